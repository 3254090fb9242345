"""The names and defaults the library and the command line accept.

This module imports nothing but the standard library, so that ``pincal --help`` and the parser
of the command line do not load NumPy, SciPy or Pinocchio. The modules that use a choice import
it from here.
"""

from __future__ import annotations

#: Parameterizations of the geometric errors (:mod:`pincal.kinematics.models`).
MODELS = ("placements", "poe", "mdh", "offsets")
#: What is measured (:mod:`pincal.identify.measurements`).
MEASURES = ("position", "pose", "distance", "points")
#: Default weight of orientation residuals [m/rad]: 1 mrad counts as 0.1 mm.
ROTATION_WEIGHT = 0.1
#: Losses of ``scipy.optimize.least_squares`` (:mod:`pincal.identify.solver`).
LOSSES = ("linear", "soft_l1", "huber", "cauchy")
#: Length units of data files -> metres.
UNITS = {"m": 1.0, "mm": 1e-3}
#: ``--quaternion-order``: what the four quaternion columns hold (w,x,y,z by their names, or x,y,z,w).
QUATERNION_ORDERS = ("wxyz", "xyzw")
#: Tool orientation methods (:mod:`pincal.tool.tcp`).
ORIENTATIONS = ("default", "z", "zx")
#: Outlier threshold: robust standard deviations above the median pose (:mod:`pincal.identify.outliers`).
THRESHOLD = 6.0
#: Bundled robots: name -> (source, path inside the source, default tip frame).
BUNDLED: dict[str, tuple[str, str, str]] = {
    "ur3": ("example-robot-data", "ur_description/urdf/ur3_robot.urdf", "tool0"),
    "ur5": ("example-robot-data", "ur_description/urdf/ur5_robot.urdf", "tool0"),
    "ur10": ("example-robot-data", "ur_description/urdf/ur10_robot.urdf", "tool0"),
    "panda": ("example-robot-data", "panda_description/urdf/panda.urdf", "panda_hand_tcp"),
    "z1": ("example-robot-data", "z1_description/urdf/z1.urdf", "link06"),
    "mrres5": ("pincal", "mrres5.urdf", "target"),
    "zu3": ("pincal", "jaka_zu3.urdf", "tool0"),
}
