"""Published protocols and data that tests and benchmarks reproduce.

- Zhang et al., *error modelling of serial robots with conformal geometric algebra*: a simulated
  robot whose every free modified-DH parameter is off by a random sign times U(0.1, 0.5) mm or
  U(0.5, 2) mrad (:func:`zhang_truth`), its noise and the held-out errors it reports;
- Xiong et al. 2012 (TCP calibration): the six flange poses of the paper's Table 1
  (:data:`XIONG_2012_POSES`) and the tool it prints.

(Gao et al. 2013's laser-tracker data are :func:`pincal.gao2013_data`.)
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from pincal.kinematics.mdh import make_model
from pincal.robot.robots import Robot
from pincal.simulation.truth import TrueRobot

#: Zhang et al.'s noise: position [m] and orientation [rad], 1σ per axis.
ZHANG_NOISE = (2e-5, 1.5e-4)
#: Zhang et al., held-out position error [mm] before and after: (mean, max, std).
ZHANG_POSITION_MM = {"before": (1.4980, 1.8024, 0.1995), "after": (0.1364, 0.2137, 0.0557)}
#: Zhang et al., held-out orientation error [mrad] before and after: (mean, max, std).
ZHANG_ROTATION_MRAD = {"before": (5.9, 6.6, 0.4), "after": (0.6, 0.8, 0.1)}

#: Table 1 of Xiong 2012: flange poses x, y, z [mm], a, b, c [deg]. Rows 1-4 are the TCP poses,
#: rows 4-6 the Z/X orientation rows (origin, +X move, +Z move); row 4 is shared.
XIONG_2012_POSES = (
    (1028.29, 233.29, 1432.98, -156.2, 44.8, -126.6),
    (1118.69, -231.99, 1478.85, 153.6, 19.0, 136.1),
    (1129.45, 25.0, 1564.0, -175.1, 29.4, -175.0),
    (983.98, 0.39, 1502.31, 179.8, 54.3, 180.0),
    (605.47, 0.39, 1502.31, 179.8, 54.3, 180.0),
    (983.98, 0.39, 1122.24, 179.8, 54.3, 180.0),
)
#: Xiong 2012's result as printed: the TCP [mm] and ``flange_R_tool`` (3 decimals; its columns
#: are the tool axes n, o, a in the flange frame).
XIONG_2012_TCP_MM = np.array([119.62, -0.32, 351.90])
XIONG_2012_ROTATION = np.array([[0.584, 0.0, 0.812], [0.0, 1.0, 0.0], [-0.812, 0.0, 0.584]])


def zhang_truth(robot: Robot, seed: int = 0) -> TrueRobot:
    """Zhang et al.'s simulated errors on ``robot``'s modified-DH model: every free parameter off
    by a random sign times U(0.1, 0.5) mm (lengths) or U(0.5, 2) mrad (angles); base,
    instrument and tool exact."""
    model = make_model("mdh", robot)
    rng = np.random.default_rng(seed)
    x = np.zeros(model.n_params)
    for i, (name, unit) in enumerate(zip(model.names, model.units)):
        if name in model.held or name.startswith("base."):
            continue
        size = rng.uniform(0.1e-3, 0.5e-3) if unit == "m" else rng.uniform(0.5e-3, 2e-3)
        x[i] = rng.choice([-1.0, 1.0]) * size
    return TrueRobot(model=model, x=x, instrument_T_base=pin.SE3.Identity(), tool=pin.SE3.Identity())
