"""Identification: measurement kinds and models, the solver, what the data identify, the pull, the
guard, the Calibration.
"""
