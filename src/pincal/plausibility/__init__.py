"""Plausibility: whether a calibration is what a rigid arm can be, and the likely mistake."""
