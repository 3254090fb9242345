"""Measurement kinds (``--measure``): what differs between position, pose, distance and fixed-point data.

Each kind is a small class beside the models (:mod:`pincal.kinematics.models`): how many residual rows a
pose gives, whether the data needs an instrument registration, the tool's degrees of freedom,
its residual and Jacobian rows (:meth:`MeasurementKind.rows`), the words the report uses, and how
held-out rows are grouped and scored (:mod:`pincal.auto.residual`, :mod:`pincal.auto.screening`). Adding a
kind is one class here and its name in :data:`pincal.options.MEASURES`.

- ``position``: the point in the instrument frame, 3 rows per pose [m];
- ``pose``: the position (3 [m]) and ``w · log3(R_measuredᵀ R_model)`` (3), ``w`` [m/rad];
- ``distance``: ``|p_i - p_j|`` (model, base frame) minus the measured distance, one row per
  pair of poses [m]; no registration;
- ``points``: the tip (base frame) minus its fixed point, 3 rows per pose [m], then one per known
  distance between points; no registration, the points' positions are unknowns instead.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from pincal.data.dataset import Dataset
from pincal.errors import DataError
from pincal.identify.fixed_points import points_rows
from pincal.identify.rows import ProblemRows
from pincal.kinematics.chain import Frames
from pincal.kinematics.so3 import jlog3, log3


def pair_directions(points: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """Each pair's unit vector from its second measured point to its first (zero for a pose
    measured twice, whose distance has no direction)."""
    along = points[pairs[:, 0]] - points[pairs[:, 1]]
    length = np.linalg.norm(along, axis=1, keepdims=True)
    return np.divide(along, length, out=np.zeros_like(along), where=length > 0)


class MeasurementKind:
    """What one kind of measurement is: its rows, unknowns and words.

    Attributes:
        name: the ``--measure`` name.
        width: residual rows per pose (per pair of poses for ``distance``).
        by_pairs: whether the rows belong to pairs of poses rather than to one pose.
        registered: whether the data is in an instrument's frame, so that a registration
            ``instrument_T_base`` (6 unknowns) is needed.
        fixed_points: whether the fixed points' positions (3 each, [m]) are unknowns.
        tool_dof: the tool's unknowns when it is fitted: 3 (a point [m]) or 6 (a frame).
        orientation: whether the data needs the orientation columns ``qw,qx,qy,qz``.
        thing: what the tool is, in words ("measured point" or "target frame").
        error: what the summary's error column measures.
        statistic: the statistics the summary shows.
        fitted: what "before" fits besides the nominal kinematics.
        data_word: what the nominal robot misses, in words ("data" or "distances").
        misses: what misses when the fit is poor, in words.
        columns: the measured columns of a CSV of this kind (``pincal template``).
    """

    name: ClassVar[str] = ""
    width: ClassVar[int] = 3
    by_pairs: ClassVar[bool] = False
    registered: ClassVar[bool] = True
    fixed_points: ClassVar[bool] = False
    tool_dof: ClassVar[int] = 3
    orientation: ClassVar[bool] = False
    thing: ClassVar[str] = "measured point"
    error: ClassVar[str] = "position error"
    statistic: ClassVar[str] = "RMS / max"
    fitted: ClassVar[str] = "registration and tool"
    data_word: ClassVar[str] = "data"
    misses: ClassVar[str] = "the calibrated robot misses the points"
    columns: ClassVar[tuple[str, ...]] = ("x", "y", "z")

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"

    def check(self, data: Dataset) -> None:
        """Raise :class:`~pincal.errors.DataError` if ``data`` lacks what this kind needs."""
        if self.orientation and not data.has_orientation:
            raise DataError(f"measure={self.name} needs the orientation columns qw,qx,qy,qz")

    def rows(
        self, problem: ProblemRows, theta: np.ndarray, cols: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Residuals [m] of ``problem`` at θ and, if columns ``cols`` are asked for, their
        Jacobian (rows, c) (else an empty array)."""
        raise NotImplementedError

    def frames(
        self, problem: ProblemRows, theta: np.ndarray, cols: np.ndarray | None
    ) -> tuple[Frames, np.ndarray, np.ndarray]:
        """``problem``'s target frames at θ, in the instrument's axes when this kind is registered:
        the tip's alone when the unknowns ``cols`` (None: the residuals alone) hold no column of
        the model or of the effect, whose columns need every joint's frame."""
        tip_only = cols is None or not bool(np.any(cols < problem.n_model))
        return problem.target_frames(theta, in_instrument=self.registered, tip_only=tip_only)

    def n_rows(self, problem: ProblemRows) -> int:
        """How many residual rows :meth:`rows` gives on ``problem``, without computing them: ``width``
        per pose, then one per known distance between fixed points."""
        return len(problem.data) * self.width + len(problem.measurement.point_distances)

    def owners(self, problem: ProblemRows) -> np.ndarray:
        """The pose(s) each residual row belongs to (rows, k): k = 2 for pairs, else 1 (-1: none,
        as a known distance's row)."""
        return problem.row_poses()[:, None]

    def per_pose(self, rows: np.ndarray, poses: np.ndarray) -> np.ndarray:
        """Residual rows (R, M) whose poses are ``poses`` (R,) -> per pose the 3-D position error
        vectors (N, 3, M) [m] (per pair the distance errors (P, 1, M))."""
        n_rows = (len(rows) // self.width) * self.width  # a known distance's row belongs to no pose
        kept = rows[poses >= 0][:n_rows]
        return kept.reshape(-1, self.width, rows.shape[1])[:, :3, :]

    def held_out(self, predicted: np.ndarray) -> np.ndarray:
        """Held-out error sizes [m] of predicted residual rows: per pose the 3-D position error
        (per pair the distance error)."""
        return np.linalg.norm(predicted.reshape(-1, self.width)[:, :3], axis=1)

    def noise_rows(self, problem: ProblemRows, n_rows: int, noise: np.ndarray) -> np.ndarray:
        """Residual rows (n_rows, draws) [m] that ``noise`` (N, 3, draws) [m] on each measured
        point makes (a known distance's rows: exact)."""
        n, draws = len(problem.data), noise.shape[2]
        rows = np.zeros((n, self.width, draws))
        rows[:, :3, :] = noise
        extra = n_rows - n * self.width
        return np.concatenate([rows.reshape(n * self.width, draws), np.zeros((extra, draws))])


class Position(MeasurementKind):
    """A point on the tip, measured in the instrument's frame (a laser tracker, a camera)."""

    name = "position"

    def rows(
        self, problem: ProblemRows, theta: np.ndarray, cols: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Residuals ``p_model - p_measured`` (3 per pose, [m]) and their Jacobian."""
        frames, rot, pos = self.frames(problem, theta, cols)
        res = (pos - problem.data.points).reshape(-1)
        if cols is None:
            return res, np.empty((0, 0))
        return res, problem.target_jacobian(theta, cols, frames, (rot, pos)).reshape(-1, len(cols))


class Pose(MeasurementKind):
    """A frame on the tip, measured in the instrument's frame (position and orientation)."""

    name = "pose"
    width = 6
    tool_dof = 6
    orientation = True
    thing = "target frame"
    columns = ("x", "y", "z", "qw", "qx", "qy", "qz")

    def rows(
        self, problem: ProblemRows, theta: np.ndarray, cols: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Residuals: the position [m] and ``w · log3(R_measuredᵀ R_model)`` (w [m/rad]), 6 per
        pose, and their Jacobian."""
        m = problem.measurement
        frames, rot, pos = self.frames(problem, theta, cols)
        res_p = pos - problem.data.points
        err = np.transpose(problem.measured_rotations, (0, 2, 1)) @ rot
        log = log3(err)
        res = np.concatenate([res_p, m.rotation_weight * log], axis=1).reshape(-1)
        if cols is None:
            return res, np.empty((0, 0))
        # d log3(R_measᵀ R) = Jlog3 · Rᵀ · (angular velocity in the instrument's axes)
        to_log = m.rotation_weight * (jlog3(err, log) @ np.transpose(rot, (0, 2, 1)))
        return res, problem.target_jacobian(theta, cols, frames, (rot, pos), to_log).reshape(-1, len(cols))


class Distance(MeasurementKind):
    """Distances between the measured points of pairs of poses (Gao et al. 2013, eqs. 13-18)."""

    name = "distance"
    width = 1
    by_pairs = True
    registered = False
    error = "abs. distance error over pairs"
    data_word = "distances"
    misses = "the distances miss"

    def rows(
        self, problem: ProblemRows, theta: np.ndarray, cols: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Residuals ``|p_i - p_j| - d_ij`` (one per pair, [m]) and their Jacobian."""
        frames, rot, pos = self.frames(problem, theta, cols)
        i, j = problem.pairs[:, 0], problem.pairs[:, 1]
        diff = pos[i] - pos[j]
        dist = np.linalg.norm(diff, axis=1)
        res = dist - problem.measured_distances
        if cols is None:
            return res, np.empty((0, 0))
        jac_v = problem.target_jacobian(theta, cols, frames, (rot, pos))
        u = diff / np.where(dist > 0, dist, 1.0)[:, None]  # a pose paired with itself: no direction
        return res, np.einsum("pk,pkc->pc", u, jac_v[i] - jac_v[j])

    def n_rows(self, problem: ProblemRows) -> int:
        """One row per pair of poses."""
        return len(problem.pairs)

    def owners(self, problem: ProblemRows) -> np.ndarray:
        """The two poses of each pair (P, 2)."""
        return problem.pairs

    def per_pose(self, rows: np.ndarray, poses: np.ndarray) -> np.ndarray:
        """Per pair the distance errors (P, 1, M) [m]."""
        return rows[:, None, :]

    def held_out(self, predicted: np.ndarray) -> np.ndarray:
        """Per pair the size of the distance error [m]."""
        return np.abs(predicted)

    def noise_rows(self, problem: ProblemRows, n_rows: int, noise: np.ndarray) -> np.ndarray:
        """The distance rows (P, draws) [m] that ``noise`` on the measured points makes."""
        pairs = problem.pairs
        u = pair_directions(problem.data.points, pairs)
        return np.einsum("pk,pkd->pd", u, noise[pairs[:, 0]] - noise[pairs[:, 1]])


class Points(MeasurementKind):
    """The tip held at fixed points (sockets) whose positions are unknown
    (:mod:`pincal.identify.fixed_points`)."""

    name = "points"
    registered = False
    fixed_points = True
    error = "fixed points"
    statistic = "mean from the point's mean / distance error"
    fitted = "tool and points"
    misses = "the tip misses its fixed points"
    columns = ("point",)

    def rows(
        self, problem: ProblemRows, theta: np.ndarray, cols: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Residuals: the tip minus its point (3 per pose, [m]), then the known distances' misfits;
        and their Jacobian (:func:`pincal.identify.fixed_points.points_rows`)."""
        frames, rot, pos = self.frames(problem, theta, cols)
        return points_rows(problem, theta, cols, frames, (rot, pos))


#: The measurement kinds by name, in the order of :data:`pincal.options.MEASURES`.
KINDS: dict[str, MeasurementKind] = {k.name: k for k in (Position(), Pose(), Distance(), Points())}


def get_kind(name: str) -> MeasurementKind:
    """The measurement kind called ``name``.

    Raises:
        DataError: no kind has that name (the message lists the names).
    """
    try:
        return KINDS[name]
    except (KeyError, TypeError):
        raise DataError(f"unknown measure {name!r}: choose one of {', '.join(KINDS)}") from None


def check_options(
    kind: MeasurementKind, data: Dataset, pairs: object, point_distances: tuple[object, ...]
) -> None:
    """Refuse data and options that ``kind`` has no use for: fixed points without a point column,
    known point distances for another kind, named or given pose pairs for another than distances.

    Raises:
        DataError: what is wrong, and what to give instead.
    """
    if kind.fixed_points and data.labels is None:
        raise DataError("measure=points needs a point column naming the fixed point of each row")
    if point_distances and not kind.fixed_points:
        raise DataError(
            f"point_distances= is for measure=points (fixed-point data), not for {kind.name} data"
        )
    if not (isinstance(pairs, str) and pairs == "all") and not kind.by_pairs:
        named = pairs if isinstance(pairs, str) else "(an array)"
        raise DataError(f"pairs={named} is for measure=distance, not for {kind.name} data")
