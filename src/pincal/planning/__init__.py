"""Measurement poses chosen for the calibrated robot's accuracy."""
