"""``pincal twists``: the chain's nominal joint twists, checked against Pinocchio."""

from __future__ import annotations

import argparse

import numpy as np
import pinocchio as pin

from pincal.cli.common import robot_options
from pincal.errors import RobotError
from pincal.robot.robots import load_robot

#: Largest disagreement of the product of exponentials with Pinocchio [m or rad] that is rounding.
TWIST_TOLERANCE = 1e-6


def run(args: argparse.Namespace) -> int:
    """Run the command; 0 on success."""
    from pincal.kinematics.twists import nominal_twists, poe_forward

    robot = load_robot(args.robot, tip=args.tip, **robot_options(args))
    tw = nominal_twists(robot)
    print(f"{robot.name}: {robot.n_joints} joints from the base to {robot.tip}; twists (ω, v [m]) at q = 0")
    for name, xi in zip(robot.joint_names, tw.twists):
        print(
            f"  {name:24s} ω = {np.array2string(xi[3:], precision=4, suppress_small=True):26s} "
            f"v = {np.array2string(xi[:3], precision=4, suppress_small=True)}"
        )
    print(f"  home: p = {np.array2string(tw.home.translation, precision=5, suppress_small=True)} m")
    rng = np.random.default_rng(0)
    worst = 0.0
    for q in robot.random_configurations(100, rng):
        err = pin.log6(robot.frame_placement(q).actInv(poe_forward(tw.twists, tw.home, q)))
        worst = max(worst, float(np.abs(err.vector).max()))
    print(f"  product of exponentials vs Pinocchio at 100 random configurations: max error {worst:.2e}")
    if not worst <= TWIST_TOLERANCE:  # NaN included
        raise RobotError(
            f"the twists disagree with Pinocchio's kinematics by {worst:.3g} "
            f"(more than {TWIST_TOLERANCE:g}): "
            "the chain is not one pincal can model; check the URDF's joint axes and origins"
        )
    return 0
