"""What a model fitted on every placement at once still leaves on MUKCa's socket data.

The one-to-many protocol (:mod:`mukca`) judges a calibration on placements it never saw; its
held-out error cannot fall below what any model leaves on the rows it *was* fitted to. This
fits, per robot, the URDF's geometry (every joint placement, the ball, each placement's sockets,
the 50 mm distance; a negligible pull, no screening) on every placement at once: the rigid floor,
as the mean absolute error of each row from its socket [mm]. It then adds, linearised at that
fit, joint-space error models on **every** joint at once (which :func:`pincal.calibrate` fits one
joint at a time) and a tilt of the base proportional to the arm's overturning moment (a mobile
base on its suspension), each refitted together with the whole geometry, and prints what each
leaves. Everything here is fitted *and* judged on the same rows: a floor, not a prediction.

When no smooth function of the joint angles (nor of the arm's weight) lowers the floor, the rows'
scatter about their sockets is not a model error a calibration can remove: it is the
instrument's (the ball's seating by hand, the gearboxes' play), and it bounds what any
calibration, pincal's or MUKCa's, can reach on a held-out placement.

Usage::

    python benchmarks/mukca_floor.py DATASETS_DIR [--more FOLDER]

``--more``: a folder of further robots laid out as ``DATASETS_DIR/mukca/data`` (for example the
other robots of MUKCa's repository), named ``panda_*``, ``kuka_*`` or ``dinova_*``.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pinocchio as pin
from mukca import DISTANCE, URDFS

import pincal
from pincal.data.dataset import Dataset
from pincal.data.point_files import read_socket_folder
from pincal.identify.measurements import Problem
from pincal.kinematics.gravity import gravity_torques

#: Joint-space error models: each maps (q, gravity torques) to regressors (N, n) per joint.
Basis = Callable[[np.ndarray, np.ndarray], list[np.ndarray]]
MODELS: dict[str, Basis] = {
    "harmonics 1 (sin q, cos q)": lambda q, tau: [np.sin(q), np.cos(q)],
    "harmonics 1-2": lambda q, tau: [np.sin(q), np.cos(q), np.sin(2 * q), np.cos(2 * q)],
    "compliance (gravity torque)": lambda q, tau: [tau],
    "backlash (sign of the gravity torque)": lambda q, tau: [np.sign(tau)],
    "all of the above, and harmonic 3": lambda q, tau: [
        tau,
        np.sign(tau),
        *(f(h * q) for h in (1, 2, 3) for f in (np.sin, np.cos)),
    ],
}


class Floor:
    """The rigid fit on every placement of one robot, linearised: residuals [m] and Jacobians."""

    def __init__(self, robot: pincal.Robot, data: Dataset) -> None:
        pull = pincal.Pull(1e-3, force_fit=True)
        cal = pincal.calibrate(robot, data, params="all", outliers=None, point_distances=DISTANCE, pull=pull)
        problem = Problem(cal.model, cal.measurement, data, cal.extension)
        self.robot, self.q = robot, data.q
        self.residuals = problem.residuals(cal.theta)
        self.geometry = problem.jacobian(cal.theta)  # every unknown: geometry, ball, sockets
        sens = [problem.joint_sensitivity(cal.theta, j) for j in range(data.q.shape[1])]
        self.joints = np.stack(sens, axis=2)  # (N, 3, n) [m/rad]
        self.tips = problem.target_frames(cal.theta)[2]  # (N, 3) [m]

    def mae_mm(self, extra: list[np.ndarray]) -> float:
        """The rows' mean distance from their sockets [mm] with columns ``extra`` (each (N, 3))
        fitted together with every unknown of the rigid fit (one Gauss-Newton step)."""
        n_rows = len(self.q)
        cols = np.zeros((len(self.residuals), len(extra)))
        if extra:
            cols[: 3 * n_rows] = np.stack([c.reshape(-1) for c in extra], axis=1)
        stacked = np.hstack([cols, self.geometry])
        step = np.linalg.lstsq(stacked, -self.residuals, rcond=1e-10)[0]
        left = (self.residuals + stacked @ step)[: 3 * n_rows].reshape(-1, 3)
        return float(np.mean(np.linalg.norm(left, axis=1))) * 1e3

    def joint_columns(self, basis: Basis) -> list[np.ndarray]:
        """A joint-value error ``c · b(q)`` on every joint, for each regressor ``b`` of ``basis``."""
        tau = gravity_torques(self.robot, self.q)
        n = self.q.shape[1]
        return [self.joints[:, :, j] * b[:, j : j + 1] for b in basis(self.q, tau) for j in range(n)]

    def tilt_columns(self) -> list[np.ndarray]:
        """A small rotation of the base about x, y and z, proportional to the arm's weight moment
        about x and y (its mass times its centre of mass' horizontal position)."""
        model = self.robot.model
        data = model.createData()
        mass = sum(inertia.mass for inertia in model.inertias)
        centres = [pin.centerOfMass(model, data, self.robot.configuration(q)) for q in self.q]
        moment = mass * np.array(centres)[:, :2]  # [kg·m]
        return [np.cross(axis, self.tips) * moment[:, k : k + 1] for axis in np.eye(3) for k in range(2)]


def robot_rows(root: Path, robot_dir: Path) -> tuple[str, list[str]]:
    """One robot's table rows: the rigid floor, then each model on top of it [mm]."""
    urdf = root / "urdf" / URDFS[robot_dir.name.split("_")[0]]
    robot = pincal.load_robot(urdf, tip="ball_link")
    floor = Floor(robot, read_socket_folder(robot_dir, robot.joint_names))
    rigid = floor.mae_mm([])
    cells = [f"{floor.mae_mm(floor.joint_columns(basis)):.3f}" for basis in MODELS.values()]
    massless = sum(inertia.mass for inertia in robot.model.inertias) <= 0.0
    cells.append("- (no masses in the URDF)" if massless else f"{floor.mae_mm(floor.tilt_columns()):.3f}")
    return robot_dir.name, [f"{rigid:.3f}", *cells]


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("datasets", type=Path, help="the shared datasets folder (holding mukca/)")
    parser.add_argument("--more", type=Path, help="a folder of further robots (MUKCa's layout)")
    args = parser.parse_args()
    root = args.datasets / "mukca"
    folders = sorted((root / "data").iterdir())
    folders += sorted(args.more.iterdir()) if args.more is not None else []
    heads = ["rigid", *MODELS, "base tilt (weight moment)"]
    print("every placement fitted at once: rows' mean distance from their socket [mm], fitted and judged on")
    print("the same rows; each joint-space model on every joint at once, with the whole geometry\n")
    print("| robot | " + " | ".join(heads) + " |")
    print("|---" * (len(heads) + 1) + "|")
    for robot_dir in folders:
        name, cells = robot_rows(root, robot_dir)
        print(f"| {name} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
