"""Simulated robots, instruments and recordings for tests, the demo and the notebooks."""
