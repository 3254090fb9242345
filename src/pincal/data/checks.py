"""Checks of a measurement table against its robot, before anything is fitted.

Each check raises :class:`~pincal.errors.DataError` with what is wrong and how to fix it:

- :func:`check_columns`: every chain joint has a column (or is locked on purpose), and no
  column looks like a joint the URDF does not have (a typo, or another robot's data);
- :func:`check_limits`: joint values inside the URDF limits, within a small tolerance, with a
  hint when the values look like degrees given as radians (or millimetres given as metres);
- :func:`check_scale`: the measured points spread about as far as the tip does at the same
  joint values (a factor of 1000 means millimetres given as metres, or the reverse; a tip that
  spreads as far with the angles in the other unit means degrees read as radians, or the reverse);

The checks of the columns alone, while a file is read (all four quaternion columns or none, a
locked joint's column still), are :mod:`pincal.data.csv_table`'s.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Iterable, Sequence

import numpy as np

from pincal.data.csv_table import misspelt
from pincal.data.dataset import Dataset
from pincal.errors import DataError
from pincal.robot.robots import Robot

LIMIT_TOLERANCE = (np.deg2rad(1.0), 1e-3)  # [rad] revolute, [m] prismatic, beyond the URDF limits
#: Beyond the tolerance but within this [rad, m], a joint value is kept with a warning (a URDF's
#: limits are often a controller's soft limits, which a measured pose can pass).
LIMIT_SLACK = (np.deg2rad(3.0), 3e-3)
#: A revolute joint past its limits in this share of the rows or more is kept with a warning
#: however far (within a turn): its URDF limits are too tight, as MUKCa's Gen3 lite joint_6.
SYSTEMATIC = 0.1
#: A revolute joint past its limits in two rows or more, none by more than this [rad], is kept
#: with a warning too: one mistyped value is a lone row, limits a little too tight show again
#: (MUKCa's Gen3 lite: joint_6 3.3 deg past in 2 of 37 rows of one placement).
REPEATED_SLACK = np.deg2rad(10.0)
MAX_SPREAD = 1e6  # [m]: measured points farther apart than this are a wrong unit or a bad cell
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
        hints = misspelt(missing, unknown or columns)
        raise DataError(
            f"no column for chain joint(s) {', '.join(missing)} (the header has {', '.join(columns)})"
            + hints
            + f": name a column after each joint between the base and {robot.tip}, or pass "
            f"locked={','.join(missing)} to hold them at their neutral value"
        )
    if unknown:
        raise DataError(
            f"column(s) {', '.join(unknown)} look like joint values but the URDF has no such joint "
            f"(chain joints: {', '.join(robot.joint_names)}): rename or remove them, or check that "
            "the data belongs to this robot"
        )


def _looks_like_joint(column: str, known: set[str]) -> bool:
    return bool(_JOINT_LIKE.search(column)) or bool(difflib.get_close_matches(column, known, n=1, cutoff=0.8))


def check_limits(robot: Robot, data: Dataset, degrees: bool = False) -> int:
    """Joint values within the URDF limits, give or take :data:`LIMIT_TOLERANCE`; up to
    :data:`LIMIT_SLACK` beyond, or a revolute joint past them in :data:`SYSTEMATIC` of the rows
    (within a turn) or in two rows or more by up to :data:`REPEATED_SLACK`, is kept and counted
    for a warning.

    Args:
        robot: the chain and its limits.
        data: the poses (radians and metres, as read).
        degrees: whether the file's revolute values were degrees (for the hint).

    Returns:
        How many joint values are beyond the limits and kept (worth a warning).

    Raises:
        DataError: the first joint whose values leave its limits, with the row and a hint.
    """
    tol = np.where(robot.prismatic, LIMIT_TOLERANCE[1], LIMIT_TOLERANCE[0])
    slack = np.where(robot.prismatic, LIMIT_SLACK[1], LIMIT_SLACK[0])
    beyond = (data.q < robot.lower - tol) | (data.q > robot.upper + tol)
    bad = (data.q < robot.lower - slack) | (data.q > robot.upper + slack)
    turn = ~np.asarray(robot.prismatic) & (np.abs(data.q) <= 2 * np.pi).all(axis=0)
    excess = np.maximum(robot.lower - data.q, data.q - robot.upper).max(axis=0)  # [rad, m]
    repeated = (beyond.sum(axis=0) >= 2) & (excess <= REPEATED_SLACK)
    systematic = turn & ((beyond.mean(axis=0) >= SYSTEMATIC) | repeated)
    bad &= ~systematic
    if not bad.any():
        return int(beyond.sum())
    joint = int(np.flatnonzero(bad.any(axis=0))[0])
    col = data.q[:, joint]
    first = int(np.flatnonzero(bad[:, joint])[0])
    unit = "m" if robot.prismatic[joint] else "rad"
    lo, hi = robot.lower[joint], robot.upper[joint]
    hint = _unit_hint(robot, data, degrees, tol, bad) or "check the column and the URDF's limits"
    raise DataError(
        f"data row {int(data.row_numbers[first])}, column {robot.joint_names[joint]}: "
        f"{col[first]:.6g} {unit} is outside the URDF limits [{lo:.4g}, {hi:.4g}] {unit} "
        f"({int(bad[:, joint].sum())} of {len(col)} rows are): {hint}"
    )


def _unit_hint(robot: Robot, data: Dataset, degrees: bool, tol: np.ndarray, bad: np.ndarray) -> str | None:
    """What unit would put the first joint outside its limits inside them, if one does."""
    joint = int(np.flatnonzero(bad.any(axis=0))[0])
    col, lo, hi = data.q[:, joint], robot.lower[joint] - tol[joint], robot.upper[joint] + tol[joint]
    if robot.prismatic[joint]:
        inside = np.all((col * 1e-3 >= lo) & (col * 1e-3 <= hi))
        return "the values look like millimetres: pass units=mm" if inside else None
    too_large = np.abs(col).max() > 2 * np.pi + tol[joint]  # no angle in radians is that large
    if not degrees and too_large and np.all((np.deg2rad(col) >= lo) & (np.deg2rad(col) <= hi)):
        return "the values look like degrees given as radians: pass degrees=True"
    return None


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
        degrees: whether the revolute joint values were read as degrees (for the hint).

    Raises:
        DataError: the spreads differ by more than :data:`SCALE_RATIO`.
    """
    bounded_spread(data.points, "measured points x,y,z")  # every point: a bound, not a statistic
    data = _sample(data)  # the spreads are statistics: a million poses need not all be moved
    tips = np.array([robot.frame_placement(q).translation for q in data.q])
    with np.errstate(over="ignore", invalid="ignore"):
        tip_spread = spread(tips)
    if not np.isfinite(tip_spread):
        raise DataError("the URDF puts the tip beyond any finite distance: check its joint origins")
    measured = spread(data.points)
    if len(data) < 3:
        return
    ratio = measured / tip_spread if tip_spread > 0 else np.inf
    if 1.0 / SCALE_RATIO < ratio < SCALE_RATIO:
        return
    other = _other_angle_unit(robot, data, degrees)
    angles = None if other is None else spread(other)
    if other is not None and angles and 1.0 / 3.0 < measured / angles < 3.0 and follows(other, data.points):
        hint = (
            "the joint values look like radians read as degrees: drop degrees=True"
            if degrees
            else "the joint values look like degrees read as radians: pass degrees=True"
        )
    elif tip_spread < 1e-3:  # [m] poses alike: the rank check says why
        return
    elif ratio >= SCALE_RATIO:
        hint = (
            "the values look like millimetres: pass units=mm"
            if units == "m" and 300 < ratio < 3000
            else "check the unit of x,y,z"
        )
    else:
        hint = (
            "the values look like metres: drop units=mm"
            if units == "mm" and 1 / 3000 < ratio < 1 / 300
            else "check the unit of x,y,z and that the points belong to this robot"
        )
    raise DataError(
        f"the measured points x,y,z spread {measured:.4g} m around their centre (read as {units}), "
        f"but the robot's tip spreads {tip_spread:.3g} m at the same joint values: {hint}"
    )


#: Poses the unit check moves the robot to (a random subset of larger data) and the largest RMS
#: distance, as a share of the points' spread, of the points from the tip positions rigidly
#: aligned on them, for the tip to "follow" the points (the unknown tool point adds some).
CHECK_POSES, FOLLOW = 5000, 0.5


def _sample(data: Dataset) -> Dataset:
    if len(data) <= CHECK_POSES:
        return data
    return data.subset(np.sort(np.random.default_rng(0).choice(len(data), CHECK_POSES, replace=False)))


def follows(tips: np.ndarray, points: np.ndarray) -> bool:
    """Whether measured ``points`` (N, 3) are the tip positions ``tips`` (N, 3) seen by an
    instrument (a rigid motion, Kabsch), up to :data:`FOLLOW` of their spread: data in degrees for
    another robot spreads alike, but does not follow the tip (issue 33: its hint was --degrees)."""
    tip_c, pts_c = tips - tips.mean(axis=0), points - points.mean(axis=0)
    u, _, vt = np.linalg.svd(tip_c.T @ pts_c)
    flip = np.diag([1.0, 1.0, float(np.sign(np.linalg.det(vt.T @ u.T)) or 1.0)])
    residual = pts_c - tip_c @ (vt.T @ flip @ u.T).T
    return bool(spread(residual) <= FOLLOW * spread(points))


def _other_angle_unit(robot: Robot, data: Dataset, degrees: bool) -> np.ndarray | None:
    """The tip's positions (N, 3) [m] with the revolute joint values read in the other angle unit
    (None without a revolute joint, or when they are not finite or do not spread)."""
    revolute = ~np.asarray(robot.prismatic, dtype=bool)
    if not revolute.any():
        return None
    q = data.q.copy()
    q[:, revolute] = np.rad2deg(q[:, revolute]) if degrees else np.deg2rad(q[:, revolute])
    tips = np.array([robot.frame_placement(row).translation for row in q])
    with np.errstate(over="ignore", invalid="ignore"):
        size = spread(tips)
    return tips if np.isfinite(size) and size > 0 else None


def spread(points: np.ndarray) -> float:
    """RMS distance of points from their centroid [m]."""
    return float(np.sqrt(np.mean(np.sum((points - points.mean(axis=0)) ** 2, axis=1))))


def bounded_spread(points: np.ndarray, what: str) -> float:
    """:func:`spread` of measured points (N, 3) [m], refused when no instrument measures it.

    Raises:
        DataError: the spread is not finite or above :data:`MAX_SPREAD`, naming ``what``.
    """
    with np.errstate(over="ignore", invalid="ignore"):
        measured = spread(points)
    if not np.isfinite(measured) or measured > MAX_SPREAD:
        raise DataError(f"the {what} are {measured:.3g} m apart or more: check their unit")
    return measured
