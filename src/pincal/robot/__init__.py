"""Robots: URDF and xacro in, checked, the base-to-tip chain loaded into Pinocchio."""
