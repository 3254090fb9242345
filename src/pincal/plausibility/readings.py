"""Other readings of a calibration's data, for :mod:`pincal.plausibility.judge`: the mistakes a fit
cannot tell from the truth, each tried by a registration-only fit of the nominal robot.

- degrees read as radians (or the reverse);
- two of ``x,y,z`` exchanged (any mirror: the registration turns one into another);
- quaternions in x,y,z,w order under w,x,y,z names (or the reverse);
- ``--instrument-frame base`` for data that is not in the base frame; a wrong ``--tool-point``.

And :func:`model_mismatch`: whether the model reproduces the URDF at all.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from typing import Any

import numpy as np

from pincal.data.dataset import Dataset
from pincal.errors import PincalError
from pincal.identify.calibration import Calibration
from pincal.identify.evaluation import ErrorStats, evaluate
from pincal.kinematics.chain import Chain, forward
from pincal.plausibility.verdict import robot_size, score_mm

#: Another reading names the cause when the nominal robot fits it this many times better.
IMPROVEMENT = 5.0
#: ... and within this share of the robot's size (as :data:`pincal.plausibility.judge.BEFORE`).
WITHIN = 0.1
#: ... and within this share of how far the nominal tip moves over the poses so read: a reading
#: that keeps the robot nearly still (another robot's radians read as degrees) fits any data about
#: as well as a robot that does not move, which names no cause.
MOVED = 0.1


def model_mismatch(cal: Calibration, data: Dataset) -> float:
    """The largest distance [m] between the model's nominal tip (all parameters zero) and the
    URDF's, at the data's poses: zero but for rounding when the model reproduces the URDF."""
    zero = np.zeros(cal.model.n_params)
    with np.errstate(all="ignore"):
        mine = forward(cal.model.chain(zero), data.q).tip_translation
        urdf = forward(Chain.nominal(cal.robot), data.q).tip_translation
        off = np.linalg.norm(mine - urdf, axis=1).max(initial=0.0)
    return float(off) if np.isfinite(off) else float("inf")


def tip_motion(cal: Calibration, data: Dataset) -> float:
    """How far the nominal tip moves over the poses of ``data`` [m]: the RMS distance of its
    positions from their mean."""
    with np.errstate(all="ignore"):
        tips = forward(Chain.nominal(cal.robot), data.q).tip_translation
        size = float(np.sqrt(np.mean(np.sum((tips - tips.mean(axis=0)) ** 2, axis=1))))
    return size if np.isfinite(size) else 0.0


#: An other reading: cause key, fix, the data so read, and changed options of
#: :func:`pincal.identify.solver.set_up`.
Reading = tuple[str, str, Dataset, dict[str, Any]]


def other_reading(
    cal: Calibration, data: Dataset, degrees: bool, quaternion_order: str
) -> tuple[str, str, ErrorStats] | None:
    """The other reading of the data that the nominal robot fits :data:`IMPROVEMENT` times better
    than this one: its cause key, its fix and its registration-only errors; or None."""
    weight = cal.measurement.rotation_weight
    current = score_mm(cal.train_before, weight)
    found: list[tuple[float, str, str, ErrorStats, float]] = []
    for cause, fix, alt, options in _readings(cal, data, degrees, quaternion_order):
        try:
            stats, up = _registration_only(cal, alt, options)
        except (PincalError, np.linalg.LinAlgError, ValueError, FloatingPointError):
            continue
        score = score_mm(stats, weight)
        factor = current / max(score, 1e-12)
        near = score * 1e-3 <= min(WITHIN * robot_size(cal.robot), MOVED * tip_motion(cal, alt))
        if factor >= IMPROVEMENT and near:
            found.append((factor, cause, fix, stats, up))
    if not found:
        return None
    best = max(found, key=lambda f: f[0])
    swaps = [f for f in found if f[1].startswith("swapped") and f[0] > best[0] / 1.5]
    if best[1].startswith("swapped") and swaps:
        # every mirror fits as well (the registration turns one into another): an instrument with
        # its z axis up, as trackers and motion capture mostly are, names the pair; x and y otherwise
        upright = max(swaps, key=lambda f: f[4])
        best = upright if upright[4] > 0.95 else next((f for f in swaps if f[1] == "swapped_xy"), upright)
    return best[1], best[2], best[3]


def _readings(cal: Calibration, data: Dataset, degrees: bool, quaternion_order: str) -> Iterator[Reading]:
    """Other readings of the data that a common mistake would explain."""
    m, robot = cal.measurement, cal.robot
    revolute = ~np.asarray(robot.prismatic, dtype=bool)
    if revolute.any():
        q = data.q.copy()
        if degrees:
            q[:, revolute] = np.rad2deg(q[:, revolute])
            fix = "the joint values look like radians read as degrees: drop degrees=True"
            yield "radians", fix, replace(data, q=q), {}
        else:
            q[:, revolute] = np.deg2rad(q[:, revolute])
            yield "degrees", "looks like degrees read as radians: pass degrees=True", replace(data, q=q), {}
    if m.measure.registered:
        for i, j in ((0, 1), (0, 2), (1, 2)):
            a, b = "xyz"[i], "xyz"[j]
            points = data.points.copy()
            points[:, [i, j]] = points[:, [j, i]]
            fix = f"{a} and {b} look swapped (the points are mirrored): exchange the {a} and {b} columns"
            yield f"swapped_{a}{b}", fix, replace(data, points=points), {}
        if not m.fit_instrument:
            fix = "the data is not in the base frame: drop instrument_frame=base"
            yield "instrument_frame", fix, data, {"instrument_T_base": None}
        if not m.fit_tool:
            fix = "the measured point is not where tool= says: drop tool="
            yield "tool_point", fix, data, {"tool": None}
    if m.measure.orientation and data.quaternions is not None:
        quats = data.quaternions
        if quaternion_order == "xyzw":
            fix = "the quaternion looks like w,x,y,z: drop quaternion_order=xyzw"
            yield "quaternion_wxyz", fix, replace(data, quaternions=quats[:, [1, 2, 3, 0]]), {}
        else:
            fix = "quaternion looks like x,y,z,w: pass quaternion_order=xyzw"
            yield "quaternion_xyzw", fix, replace(data, quaternions=quats[:, [3, 0, 1, 2]]), {}


def _registration_only(cal: Calibration, data: Dataset, changes: dict[str, Any]) -> tuple[ErrorStats, float]:
    """Errors of the nominal robot with only the registration and tool fitted on ``data``, and the
    z component of the base's z axis in the fitted instrument's axes (1: the instrument's z is up)."""
    from pincal.identify.solver import register, set_up  # here: the solver's users import this module

    m = cal.measurement
    options: dict[str, Any] = {
        "instrument_T_base": None if m.fit_instrument else m.instrument_T_base,
        "tool": None if m.fit_tool else m.tool,
        "rotation_weight": m.rotation_weight,
        "pairs": "all" if m.pairs is None else m.pairs,
        "point_distances": m.point_distances,
        **changes,
    }
    setup = set_up(cal.robot, data, cal.model, m.kind, **options)
    theta = register(setup)
    _, reg, _ = setup.problem.split(theta)
    stats = evaluate(setup.model, setup.problem.measurement, theta, data)
    return stats, float(reg.rotation[2, 2])
