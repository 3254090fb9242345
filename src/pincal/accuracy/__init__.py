"""ISO 9283 pose accuracy and repeatability."""
