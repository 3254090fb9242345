"""Fixed-point constraints: calibration without an instrument (``--measure points``).

The tip (a ball on the flange) is held by hand at a few physical points (sockets of a fixture),
many times each in different configurations, as in MUKCa (Franzese, Spahn et al. 2025). The
only knowledge is "same point" within a point's rows and, optionally, known distances between
points. The unknowns are the points' positions in the base frame (3 each, [m]) and the tip point
on the flange (3, [m]); the residual of a row is its tip position minus its point's position, so
the cost grows with the number of rows, not of pairs. A known distance ``D`` between points
``a`` and ``b`` adds one residual ``w · (|c_a - c_b| - D)``, ``w = 10 √N`` (:data:`DISTANCE_WEIGHT`:
it is worth ten times the rows together: a printed fixture is more exact than a hand-held ball,
and the pull toward the URDF must not trade micrometres of it).

Some motions of the whole set-up change no residual (*gauges*): moving the robot's base and
every point together (3 translations, 3 rotations), and, without a known distance, scaling every
length (the points, the tool and the links) about the base (base axes). :func:`gauge_directions` finds those
the fitted parameters can make; the identifiable set holds one parameter per gauge at its
nominal value, and the report names them (the scale then comes from the URDF alone).

Errors as MUKCa reports them (:func:`point_errors`): each row's distance from its point's mean
tip position, and ``|distance between two points' means - D|`` per known distance. A held-out
placement of the fixture is judged the same way: its points are the means of its own rows, the
robot model is the calibrated one.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from pincal.data.dataset import Dataset
from pincal.errors import DataError
from pincal.identify.rows import ProblemRows
from pincal.kinematics.chain import Frames
from pincal.options import UNITS

#: A known distance between two named points [m].
PointDistance = tuple[str, str, float]
#: A gauge is exact when the parameters make its motion to this relative accuracy.
GAUGE_TOLERANCE = 1e-6
#: A known distance weighs as this many times the rows together, in root-sum-square: a printed
#: fixture is more exact than a hand-held ball, and the pull toward the URDF (:mod:`pincal.identify.prior`)
#: must not trade micrometres of it for its own cost.
DISTANCE_WEIGHT = 10.0


def parse_point_distances(text: str | None, units: str = "m") -> tuple[PointDistance, ...]:
    """``A,B=D[;C,E=F...]`` (D in ``units``) -> ((A, B, D [m]), ...).

    Raises:
        DataError: a malformed item, a point paired with itself, a distance that is not > 0, or
            a pair given twice (in either order).
    """
    if text is None or not text.strip():
        return ()
    out: list[PointDistance] = []
    for item in text.replace(" ", "").split(";"):
        names, _, value = item.partition("=")
        pair = names.split(",")
        try:
            distance = float(value) * UNITS[units]
        except (ValueError, KeyError):
            distance = float("nan")
        if len(pair) != 2 or not all(pair) or not abs(distance) < 1e6:  # [m], NaN and inf fail
            raise DataError(f"point_distances={item!r}: write A,B=D (two point names, a distance in {units})")
        if pair[0] == pair[1]:
            raise DataError(f"point_distances={item!r}: a point's distance to itself is 0")
        if distance <= 0:
            raise DataError(f"point_distances={item!r}: the distance must be positive")
        twice = [d for a, b, d in out if {a, b} == set(pair)]
        if twice:
            same = "twice" if abs(twice[0] - distance) <= 1e-12 else f"twice, {twice[0] / UNITS[units]:g} and"
            raise DataError(
                f"point_distances= gives the distance between {pair[0]} and {pair[1]} {same} "
                f"{distance / UNITS[units]:g} {units}: give each pair once"
            )
        out.append((pair[0], pair[1], distance))
    return tuple(out)


def point_index(data: Dataset, points: tuple[str, ...]) -> np.ndarray | None:
    """Each row's index into ``points`` (the measurement's unknown points), or None when the data
    names a point that is not among them (or has no point column)."""
    if data.labels is None:
        return None
    where = {name: k for k, name in enumerate(points)}
    mapped = [where.get(name, -1) for name in data.point_names]
    if min(mapped, default=0) < 0:
        return None
    return np.asarray(mapped, dtype=int)[data.labels]


def check_distances(points: tuple[str, ...], distances: tuple[PointDistance, ...]) -> None:
    """Every point a known distance names is in the data.

    Raises:
        DataError: naming the unknown point and the data's points.
    """
    for a, b, _ in distances:
        for name in (a, b):
            if name not in points:
                raise DataError(
                    f"point_distances= names point {name!r}, but the data's points are only "
                    f"{', '.join(points)} (a point column's names, or the hole_<name>.csv files)"
                )


def placement(name: str) -> str:
    """The placement of the fixture a point belongs to: ``front`` for ``front/0``, ``""`` for a
    point of data of one placement."""
    return name.rpartition("/")[0]


def placed_distances(names: Sequence[str], distances: tuple[PointDistance, ...]) -> tuple[PointDistance, ...]:
    """The known distances as they hold among points ``names``: as written when both points are
    there; else, for data of several placements of a fixture (points ``<placement>/<name>``, as
    :func:`pincal.data.point_files.read_socket_folder` names them), once in every placement that has
    both; a distance between two placements' points applies to a single placement's own points
    too (a model fitted on several placements, judged on one). A distance no point matches stays
    as written (:func:`check_distances` names it)."""
    there = set(names)
    places = sorted({placement(name) for name in names if "/" in name})
    out: dict[tuple[str, str], float] = {}
    for a, b, d in distances:
        bare = (a.rpartition("/")[2], b.rpartition("/")[2])
        if a in there and b in there:
            found = [(a, b)]
        else:
            found = [(f"{p}/{bare[0]}", f"{p}/{bare[1]}") for p in places]
            found = [pair for pair in found if set(pair) <= there] or (
                [bare] if set(bare) <= there else [(a, b)]
            )
        for pair in found:
            out.setdefault(pair, d)
    return tuple((a, b, d) for (a, b), d in out.items())


def point_means(tips: np.ndarray, labels: np.ndarray, n_points: int) -> np.ndarray:
    """Mean tip position of each point's rows (n_points, 3) [m]."""
    counts = np.bincount(labels, minlength=n_points)[:, None]
    sums = np.zeros((n_points, 3))
    np.add.at(sums, labels, tips)
    return sums / np.maximum(counts, 1)


def point_errors(
    tips: np.ndarray, data: Dataset, distances: tuple[PointDistance, ...]
) -> tuple[np.ndarray, np.ndarray]:
    """MUKCa's errors: each row's distance from its point's mean tip position (N,) [m], and
    ``|distance between the means - D|`` for each known distance whose points the data has [m]."""
    if data.labels is None:
        raise DataError("fixed-point errors need a point column")
    means = point_means(tips, data.labels, len(data.point_names))
    where = {name: k for k, name in enumerate(data.point_names)}
    placed = placed_distances(data.point_names, distances)
    present = set(np.unique(data.labels).tolist())  # a subset may hold some points only
    known = [(where[a], where[b], d) for a, b, d in placed if {where.get(a), where.get(b)} <= present]
    off = [abs(float(np.linalg.norm(means[a] - means[b])) - d) for a, b, d in known]
    return np.linalg.norm(tips - means[data.labels], axis=1), np.array(off)


def gauge_directions(
    problem: ProblemRows, theta: np.ndarray, candidates: np.ndarray, scale: np.ndarray
) -> tuple[np.ndarray, tuple[str, ...]]:
    """The motions of the whole set-up that the candidate parameters can make and no residual
    sees, to first order: (P, g) directions in θ and their names.

    Args:
        problem: a fixed-point problem.
        theta: where to linearise.
        candidates: (P,) mask of the parameters that may be fitted.
        scale: (P,) natural size of each parameter (the least squares are solved in those units).
    """
    n_model, m = problem.n_model, problem.measurement
    points = slice(n_model, n_model + m.n_points)
    others = np.flatnonzero(candidates)
    others = others[(others < n_model) | (others >= points.stop)]
    frames, rot, pos = problem.target_frames(theta)
    jac = problem.target_jacobian(theta, others, frames, (rot, pos)).reshape(-1, len(others))
    js = jac * scale[others]
    centres = problem.point_positions(theta)
    fields: list[tuple[str, np.ndarray, np.ndarray]] = []
    for k, axis in enumerate("xyz"):
        e = np.eye(3)[k]
        fields.append((f"translation along {axis}", e + 0 * pos, e + 0 * centres))
    for k, axis in enumerate("xyz"):
        e = np.eye(3)[k]
        fields.append((f"rotation about {axis}", np.cross(e, pos), np.cross(e, centres)))
    if not m.point_distances:
        fields.append(("scale (no known distance between the points)", pos, centres))
    directions, names = [], []
    for name, tip_motion, point_motion in fields:
        target = tip_motion.reshape(-1)
        step = np.linalg.lstsq(js, target, rcond=None)[0]
        if np.linalg.norm(js @ step - target) > GAUGE_TOLERANCE * np.linalg.norm(target):
            continue  # the parameters cannot make this motion: the data sees it
        v = np.zeros(problem.n_params)
        v[others] = step * scale[others]
        v[points] = point_motion.reshape(-1)
        directions.append(v)
        names.append(name)
    return np.array(directions).T.reshape(problem.n_params, -1), tuple(names)


def without_gauges(jacobian: np.ndarray, gauges: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """The Jacobian with the gauge directions (P, g) made exactly blind, in scaled units."""
    if gauges.shape[1] == 0:
        return jacobian
    basis, _ = np.linalg.qr(gauges / scale[:, None])
    js = jacobian * scale
    return (js - (js @ basis) @ basis.T) / scale


def gauge_reasons(
    names: tuple[str, ...], held: np.ndarray, gauges: np.ndarray, labels: tuple[str, ...], scale: np.ndarray
) -> dict[str, str]:
    """Why a held parameter is held, for the parameter each gauge leans on most."""
    reasons: dict[str, str] = {}
    weights = np.abs(gauges / scale[:, None])
    for g, label in enumerate(labels):
        share = np.where(held, weights[:, g], 0.0)
        if share.max() <= 0:
            continue
        name = names[int(np.argmax(share))]
        hint = " (give point_distances=A,B=D): lengths keep the URDF's scale" if "scale" in label else ""
        reasons.setdefault(name, f"not identifiable from fixed points: the whole set-up's {label}{hint}")
    return reasons


def points_rows(
    problem: ProblemRows,
    theta: np.ndarray,
    cols: np.ndarray | None,
    frames: Frames,
    target: tuple[np.ndarray, np.ndarray],
) -> tuple[np.ndarray, np.ndarray]:
    """Residuals of fixed-point data [m] (rows, then known distances) and, given columns
    ``cols``, their Jacobian (else an empty array); ``target``: tip rotations and positions."""
    m, index = problem.measurement, problem.point_index
    if index is None:
        raise DataError("measure=points needs a point column naming one of the fitted points in every row")
    centres = problem.point_positions(theta)
    weight = DISTANCE_WEIGHT * np.sqrt(len(problem.data))
    where = {name: k for k, name in enumerate(m.points)}
    known = [(where[a], where[b], d) for a, b, d in m.point_distances]
    diffs = np.array([centres[a] - centres[b] for a, b, _ in known]).reshape(-1, 3)
    lengths = np.linalg.norm(diffs, axis=1)
    misfit = weight * (lengths - np.array([d for _, _, d in known]))
    res = np.concatenate([(target[1] - centres[index]).reshape(-1), misfit])
    if cols is None:
        return res, np.empty((0, 0))
    jac = problem.target_jacobian(theta, cols, frames, target)  # (N, 3, c): zero for the points
    first = problem.n_model
    at = np.flatnonzero((cols >= first) & (cols < first + m.n_points))
    point, axis = np.divmod(cols[at] - first, 3)
    for c, k, a in zip(at, point, axis):
        jac[index == k, a, c] = -1.0
    rows = np.zeros((len(known), len(cols)))
    unit = diffs / np.where(lengths > 0, lengths, 1.0)[:, None]
    for r, (a, b, _) in enumerate(known):
        rows[r, at] = weight * unit[r, axis] * ((point == a).astype(float) - (point == b))
    return res, np.vstack([jac.reshape(-1, len(cols)), rows])


def blind_jacobian(
    problem: ProblemRows, theta: np.ndarray, jacobian: np.ndarray, candidates: np.ndarray, scale: np.ndarray
) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """For fixed-point data, the Jacobian with its gauges made exactly blind, the gauges (P, g)
    and their names (:func:`gauge_directions`); other data: the Jacobian as it is, no gauges.
    Linearised, a gauge looks like a gain (shrinking everything shrinks every residual): the
    identifiable set and the parameter choice both need it gone."""
    if not problem.measurement.measure.fixed_points:
        return jacobian, np.empty((problem.n_params, 0)), ()
    gauges, names = gauge_directions(problem, theta, candidates, scale)
    return without_gauges(jacobian, gauges, scale), gauges, names
