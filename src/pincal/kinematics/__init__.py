"""Kinematics and the error models: the chain, joint twists, placements, POE, modified DH,
non-geometric effects.
"""
