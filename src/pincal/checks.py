"""Checks of a measurement table against its robot, before anything is fitted.

Each check raises :class:`~pincal.errors.DataError` with what is wrong and how to fix it:

- :func:`check_columns`: every chain joint has a column (or is locked on purpose), and no
  column looks like a joint the URDF does not have (a typo, or another robot's data);
- :func:`check_limits`: joint values inside the URDF limits, within a small tolerance, with a
  hint when the values look like degrees given as radians (or millimetres given as metres);
- :func:`check_scale`: the measured points spread about as far as the tip does at the same
  joint values (a factor of 1000 means millimetres given as metres, or the reverse).
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Iterable, Sequence

import numpy as np

from .data import Dataset
from .errors import DataError
from .robots import Robot

LIMIT_TOLERANCE = (np.deg2rad(1.0), 1e-3)  # [rad] revolute, [m] prismatic, beyond the URDF limits
SCALE_RATIO = 10.0  # measured spread / tip spread beyond which the units are suspect
_JOINT_LIKE = re.compile(r"^(q|j|theta|joint|axis)[_ ]?\d+$|joint", re.IGNORECASE)


def check_columns(header: Sequence[str], robot: Robot, locked: Iterable[str] = ()) -> None:
    """Every chain joint has a column, and no column names a joint the URDF lacks.

    Args:
        header: the CSV's column names.
        robot: the chain (its joints must all have a column, unless in ``locked``).
        locked: chain joints the user asked to hold at their neutral value (``--lock``).

    Raises:
        DataError: a missing chain-joint column, or an unknown joint-like column.
    """
    columns = [c for c in header if c]
    known = set(robot.urdf_joints) | set(robot.joint_names)
    missing = [j for j in robot.joint_names if j not in columns and j not in set(locked)]
    unknown = [c for c in columns if c not in known and _looks_like_joint(c, known)]
    if missing:
        hints = [
            f"'{match[0]}' for {j}?"
            for j in missing
            if (match := difflib.get_close_matches(j, unknown or columns, n=1, cutoff=0.6))
        ]
        raise DataError(
            f"no column for chain joint(s) {', '.join(missing)} (the header has {', '.join(columns)})"
            + (f"; misspelt: {' '.join(hints)}" if hints else "")
            + f": name a column after each joint between the base and {robot.tip}, or pass "
            f"--lock {','.join(missing)} to hold them at their neutral value"
        )
    if unknown:
        raise DataError(
            f"column(s) {', '.join(unknown)} look like joint values but the URDF has no such joint "
            f"(chain joints: {', '.join(robot.joint_names)}): rename or remove them, or check that "
            "the data belongs to this robot"
        )


def _looks_like_joint(column: str, known: set[str]) -> bool:
    return bool(_JOINT_LIKE.search(column)) or bool(difflib.get_close_matches(column, known, n=1, cutoff=0.8))


def check_limits(robot: Robot, data: Dataset, degrees: bool = False) -> None:
    """Joint values within the URDF limits, give or take :data:`LIMIT_TOLERANCE`.

    Args:
        robot: the chain and its limits.
        data: the poses (radians and metres, as read).
        degrees: whether the file's revolute values were degrees (for the hint).

    Raises:
        DataError: the first joint whose values leave its limits, with the row and a hint.
    """
    tol = np.where(robot.prismatic, LIMIT_TOLERANCE[1], LIMIT_TOLERANCE[0])
    below = data.q < robot.lower - tol
    above = data.q > robot.upper + tol
    bad = below | above
    if not bad.any():
        return
    joint = int(np.flatnonzero(bad.any(axis=0))[0])
    col = data.q[:, joint]
    first = int(np.flatnonzero(bad[:, joint])[0])
    unit = "m" if robot.prismatic[joint] else "rad"
    lo, hi = robot.lower[joint], robot.upper[joint]
    hint = "check the column and the URDF's limits"
    if robot.prismatic[joint]:
        if np.all((col * 1e-3 >= lo - tol[joint]) & (col * 1e-3 <= hi + tol[joint])):
            hint = "the values look like millimetres: pass --units mm"
    elif (
        not degrees
        and np.abs(col).max() > 2 * np.pi + tol[joint]  # no angle in radians is that large
        and np.all((np.deg2rad(col) >= lo - tol[joint]) & (np.deg2rad(col) <= hi + tol[joint]))
    ):
        hint = "the values look like degrees given as radians: pass --degrees"
    raise DataError(
        f"data row {int(data.row_numbers[first])}, column {robot.joint_names[joint]}: "
        f"{col[first]:.6g} {unit} is outside the URDF limits [{lo:.4g}, {hi:.4g}] {unit} "
        f"({int(bad[:, joint].sum())} of {len(col)} rows are): {hint}"
    )


def small_angles(robot: Robot, data: Dataset) -> bool:
    """Whether every revolute joint value is within ±2π degrees (radians read as degrees would be)."""
    revolute = ~np.asarray(robot.prismatic, dtype=bool)
    small = np.deg2rad(2 * np.pi) + 1e-12  # [rad]: 2π read as degrees
    return bool(revolute.any() and len(data) > 2 and np.abs(data.q[:, revolute]).max() <= small)


def check_scale(robot: Robot, data: Dataset, units: str = "m", degrees: bool = False) -> None:
    """The measured points spread about as far as the nominal tip does at the same joint values.

    The instrument's registration and the measured point are unknown, but neither changes the
    spread of the points by more than a small factor; a factor of :data:`SCALE_RATIO` or more
    means the wrong unit.

    Small joint motions given with ``--degrees`` (every value within ±6.3°, a real small-motion
    experiment or radians read as degrees) are refused only when the points say which: they spread
    like the tip with the values read as radians, and not read as degrees.

    Args:
        robot: the chain.
        data: the poses and measured points [m, as read].
        units: the unit the file was read in (for the hint).
        degrees: whether the file's revolute values were degrees (for the hint).

    Raises:
        DataError: the spreads differ by more than :data:`SCALE_RATIO`.
    """
    tips = np.array([robot.frame_placement(q).translation for q in data.q])
    with np.errstate(over="ignore", invalid="ignore"):
        tip_spread = spread(tips)
        measured = spread(data.points)
    if not np.isfinite(tip_spread):
        raise DataError("the URDF puts the tip beyond any finite distance: check its joint origins")
    if not np.isfinite(measured) or measured > 1e6:  # [m]
        raise DataError(f"the measured points x,y,z are {measured:.3g} m apart or more: check their unit")
    if len(data) < 3:
        return
    ratio = measured / tip_spread if tip_spread > 0 else np.inf
    if 1.0 / SCALE_RATIO < ratio < SCALE_RATIO:
        return
    if degrees and small_angles(robot, data) and _fits_as_radians(robot, data, measured):
        hint = "the joint values look like radians given with --degrees: drop --degrees"
    elif tip_spread < 1e-3:  # [m] poses alike: the rank check says why
        return
    elif ratio >= SCALE_RATIO:
        hint = (
            "the values look like millimetres: pass --units mm"
            if units == "m" and 300 < ratio < 3000
            else "check the unit of x,y,z"
        )
    else:
        hint = (
            "the values look like metres: drop --units mm"
            if units == "mm" and 1 / 3000 < ratio < 1 / 300
            else "check the unit of x,y,z and that the points belong to this robot"
        )
    raise DataError(
        f"the measured points x,y,z spread {measured:.4g} m around their centre (read as {units}), "
        f"but the robot's tip spreads {tip_spread:.3g} m at the same joint values: {hint}"
    )


def _fits_as_radians(robot: Robot, data: Dataset, measured: float) -> bool:
    """Whether the measured points spread like the tip when the (degree) joint values are read as radians."""
    q = data.q.copy()
    revolute = ~np.asarray(robot.prismatic, dtype=bool)
    q[:, revolute] = np.rad2deg(q[:, revolute])
    tips = np.array([robot.frame_placement(qi).translation for qi in q])
    tip_spread = spread(tips)
    return bool(tip_spread > 0 and 1.0 / SCALE_RATIO < measured / tip_spread < SCALE_RATIO)


def spread(points: np.ndarray) -> float:
    """RMS distance of points from their centroid [m]."""
    return float(np.sqrt(np.mean(np.sum((points - points.mean(axis=0)) ** 2, axis=1))))
