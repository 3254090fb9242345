"""Error statistics of a model on a set of poses: what ``train`` and ``test`` report.

Position and pose data: the norm of each pose's 3-D position error (and, for pose data, the
angle of its orientation error). Distance data: ``|d_measured - d_model|`` over pairs of poses.
Fixed-point data: each row's distance from its point's mean tip position, and MUKCa's two
figures (:func:`pincal.identify.fixed_points.point_errors`); with several placements of a fixture, each
placement's errors (:func:`placement_errors`: a placement that disagrees with itself is named),
and rows filed under one point that sit at another (:func:`misplaced_rows`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from pincal.data.dataset import Dataset
from pincal.identify import chunked
from pincal.identify.fixed_points import placement, point_errors, point_means
from pincal.identify.measurement import Measurement
from pincal.identify.measurements import Problem
from pincal.kinematics.effects import AnyEffect
from pincal.kinematics.models import Model


@dataclass(frozen=True)
class ErrorStats:
    """Statistics of per-pose (or per-pair) errors [mm], and orientation errors [mrad] if any."""

    rms_mm: float
    mean_mm: float
    max_mm: float
    std_mm: float
    n: int
    rot_rms_mrad: float | None = None
    rot_mean_mrad: float | None = None
    rot_max_mrad: float | None = None
    rot_std_mrad: float | None = None
    point_mae_mm: float | None = None
    point_distance_error_mm: float | None = None

    @classmethod
    def of(cls, errors_m: np.ndarray, rot_errors_rad: np.ndarray | None = None) -> ErrorStats:
        """Statistics of position errors [m] and optional orientation errors [rad]."""
        e = np.asarray(errors_m, dtype=float) * 1e3
        rot: dict[str, float | None] = {}
        if rot_errors_rad is not None:
            r = np.asarray(rot_errors_rad, dtype=float) * 1e3
            rot = {
                "rot_rms_mrad": float(np.sqrt(np.mean(r**2))),
                "rot_mean_mrad": float(np.mean(r)),
                "rot_max_mrad": float(np.max(r)),
                "rot_std_mrad": float(np.std(r)),
            }
        return cls(
            rms_mm=float(np.sqrt(np.mean(e**2))),
            mean_mm=float(np.mean(e)),
            max_mm=float(np.max(e)),
            std_mm=float(np.std(e)),
            n=int(e.size),
            **rot,
        )

    @classmethod
    def of_points(cls, errors_m: np.ndarray, distance_errors_m: np.ndarray) -> ErrorStats:
        """Statistics of fixed-point errors (:func:`pincal.identify.fixed_points.point_errors`) [m]."""
        stats = cls.of(errors_m)
        off = float(np.mean(distance_errors_m)) * 1e3 if len(distance_errors_m) else None
        return replace(stats, point_mae_mm=stats.mean_mm, point_distance_error_mm=off)

    @property
    def headline_mm(self) -> float:
        """The figure a report leads with [mm]: MUKCa's mean error for fixed points, else the RMS."""
        return self.point_mae_mm if self.point_mae_mm is not None else self.rms_mm

    def to_dict(self) -> dict[str, float | int | None]:
        """JSON-ready dictionary (orientation keys only when present; for fixed-point data both
        point keys, the distance error None when no known distance applies)."""
        fixed = self.point_mae_mm is not None
        return {k: v for k, v in asdict(self).items() if v is not None or (fixed and k.startswith("point_"))}


def pose_errors(
    model: Model,
    measurement: Measurement,
    theta: np.ndarray,
    data: Dataset,
    extension: AnyEffect | None = None,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Per-pose position error norms [m] and orientation error angles [rad] (pose data); a large
    position or pose set by the blocks of :func:`pincal.identify.chunked.data_blocks` (its frames
    are never all held; the fit's problems have made those blocks already)."""
    if len(data) > chunked.BLOCK_POSES and measurement.measure.registered:
        blocks = chunked.data_blocks(data)
        parts = [pose_errors(model, measurement, theta, part, extension) for part in blocks]
        angles = [b for _, b in parts if b is not None]
        return np.concatenate([a for a, _ in parts]), np.concatenate(angles) if angles else None
    problem = Problem(model, measurement, data, extension)
    if measurement.measure.fixed_points:  # from the fitted points
        return np.linalg.norm(problem.residuals(theta)[: 3 * len(data)].reshape(-1, 3), axis=1), None
    pos, rot = problem.predict(theta)
    err = np.linalg.norm(pos - data.points, axis=1)
    if not measurement.measure.orientation:
        return err, None
    rel = np.transpose(data.rotations(), (0, 2, 1)) @ rot
    cos = np.clip((np.trace(rel, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
    return err, np.arccos(cos)


def distance_errors(
    model: Model,
    measurement: Measurement,
    theta: np.ndarray,
    data: Dataset,
    extension: AnyEffect | None = None,
) -> np.ndarray:
    """``|d_model - d_measured|`` [m] over the measurement's pairs (default: all pairs of ``data``)."""
    return np.abs(Problem(model, measurement, data, extension).residuals(theta))


def evaluate(
    model: Model,
    measurement: Measurement,
    theta: np.ndarray,
    data: Dataset,
    extension: AnyEffect | None = None,
) -> ErrorStats:
    """Error statistics of the unknowns ``theta`` on ``data``, as the report states them."""
    if measurement.measure.by_pairs:
        return ErrorStats.of(distance_errors(model, measurement, theta, data, extension))
    if measurement.measure.fixed_points:  # from each point's mean: the fitted points are not needed
        tips = Problem(model, measurement, data, extension).target_frames(theta)[2]
        return ErrorStats.of_points(*point_errors(tips, data, measurement.point_distances))
    return ErrorStats.of(*pose_errors(model, measurement, theta, data, extension))


def marker_stats(
    model: Model,
    measurement: Measurement,
    theta: np.ndarray,
    data: Dataset | None,
    extension: AnyEffect | None = None,
) -> dict[str, ErrorStats]:
    """Several markers: :func:`evaluate` of each marker's rows, by label (distance data: the pairs
    of its own points); else, or without data, empty."""
    if data is None or data.marker is None:
        return {}
    out = {}
    for k, label in enumerate(data.marker_names):
        mine = np.flatnonzero(data.marker == k)
        if mine.size > (1 if measurement.measure.by_pairs else 0):
            out[label] = evaluate(
                model, replace(measurement, pairs=None), theta, data.subset(mine), extension
            )
    return out


#: A placement is named in the summary when its rows scatter this many times the other
#: placements' median after calibration...
SCATTER_RATIO = 2.0
#: ... or when this share of its rows were left out as outliers (0-2 % on MUKCa's other placements).
LEFT_OUT_SHARE = 0.1


@dataclass(frozen=True)
class PlacementErrors:
    """One placement of a fixture in fixed-point data of several (points ``<placement>/<name>``).

    Attributes:
        name: the placement (its folder).
        rows: its rows; left_out: how many of them the outlier screen left out of the fit;
            misplaced: how many of those sit at another of its points (:func:`misplaced_rows`).
        after: errors of the calibrated model on its fitted rows [mm].
        others_mae_mm: median of the other placements' ``after.point_mae_mm`` [mm].
    """

    name: str
    rows: int
    left_out: int
    misplaced: int
    after: ErrorStats
    others_mae_mm: float

    @property
    def suspect(self) -> bool:
        """Its rows scatter far more than the other placements', or many were outliers that no
        other point explains: the fixture may have moved, or the ball slipped, while it was
        recorded."""
        mae = float(self.after.point_mae_mm or 0.0)
        unexplained = self.left_out - self.misplaced
        return mae >= SCATTER_RATIO * self.others_mae_mm or unexplained >= LEFT_OUT_SHARE * self.rows

    def to_dict(self) -> dict[str, object]:
        """JSON-ready description."""
        return {
            "name": self.name,
            "rows": self.rows,
            "left_out": self.left_out,
            "misplaced": self.misplaced,
            "point_mae_mm": self.after.point_mae_mm,
            "point_distance_error_mm": self.after.point_distance_error_mm,
            "suspect": self.suspect,
        }


def placement_errors(
    model: Model,
    measurement: Measurement,
    theta: np.ndarray,
    data: Dataset,
    extension: AnyEffect | None = None,
    left_out: tuple[int, ...] = (),
    misplaced: tuple[int, ...] = (),
) -> list[PlacementErrors]:
    """Each placement's errors on its fitted rows, for fixed-point data of several placements
    (points named ``<placement>/<name>``, as a folder of placement folders reads) in the order
    the data has them; an empty list for one placement or other data.

    Args:
        model, measurement, theta, extension: the calibrated model.
        data: the fitted data, outliers included.
        left_out: row numbers the outlier screen left out of the fit.
        misplaced: row numbers at another point than their own (:func:`misplaced_rows`).
    """
    if not measurement.measure.fixed_points or data.labels is None:
        return []
    place = np.array([placement(name) for name in data.point_names])[data.labels]
    out = np.isin(data.row_numbers, left_out)
    places = [p for p in dict.fromkeys(place.tolist()) if ((place == p) & ~out).any()]
    if len(places) < 2:
        return []
    stats = [
        evaluate(model, measurement, theta, data.subset(np.flatnonzero((place == p) & ~out)), extension)
        for p in places
    ]
    maes = np.array([float(s.point_mae_mm or 0.0) for s in stats])
    elsewhere = out & np.isin(data.row_numbers, misplaced)
    return [
        PlacementErrors(
            p,
            int((place == p).sum()),
            int(((place == p) & out).sum()),
            int(((place == p) & elsewhere).sum()),
            s,
            float(np.median(np.delete(maes, k))),
        )
        for k, (p, s) in enumerate(zip(places, stats))
    ]


#: A fixed-point row is looked at when it is this many times the median row's distance from its
#: point, and named as misplaced when another point of its placement is 3 times nearer.
MISPLACED_FACTOR = 10.0


@dataclass(frozen=True)
class Misplaced:
    """A fixed-point row whose tip is at another point of its placement than its own (a ball
    put in the other socket, or a row saved in the other socket's file).

    Attributes:
        row: its row number; point, near: the point it is filed under and the one it is at.
        off_mm, at_mm: its distance from its own point's rows and from the other's [mm]
            (each point's position: the median of its rows' tips).
    """

    row: int
    point: str
    near: str
    off_mm: float
    at_mm: float


def misplaced_rows(
    model: Model,
    measurement: Measurement,
    theta: np.ndarray,
    data: Dataset,
    extension: AnyEffect | None = None,
) -> list[Misplaced]:
    """The rows of fixed-point data that sit at another point of their placement (points named
    ``<placement>/<name>`` belong to one placement), by the calibrated model; else an empty list."""
    if not measurement.measure.fixed_points or data.labels is None:
        return []
    tips = Problem(model, measurement, data, extension).target_frames(theta)[2]
    present = np.unique(data.labels)
    centre = np.zeros((len(data.point_names), 3))
    for p in present:  # the median: robust to the rows this looks for
        centre[p] = np.median(tips[data.labels == p], axis=0)
    own = np.linalg.norm(tips - centre[data.labels], axis=1)
    place = [placement(name) for name in data.point_names]
    out = []
    for i in np.flatnonzero(own > MISPLACED_FACTOR * np.median(own)):
        label = int(data.labels[i])
        others = [int(p) for p in present if p != label and place[p] == place[label]]
        if not others:
            continue
        distance = np.linalg.norm(centre[others] - tips[i], axis=1)
        j = int(np.argmin(distance))
        if 3.0 * distance[j] < own[i]:
            names = data.point_names
            row = int(data.row_numbers[i])
            out.append(Misplaced(row, names[label], names[others[j]], own[i] * 1e3, distance[j] * 1e3))
    return out


def point_spread(
    model: Model,
    measurement: Measurement,
    theta: np.ndarray,
    data: Dataset,
    extension: AnyEffect | None = None,
) -> float:
    """The largest distance between two fixed points' mean tip positions [m] (0 for one point):
    how much of the workspace the rows of fixed-point data see."""
    if not measurement.measure.fixed_points or data.labels is None:
        raise ValueError("point_spread needs fixed-point data")
    tips = Problem(model, measurement, data, extension).target_frames(theta)[2]
    means = point_means(tips, data.labels, len(data.point_names))[np.unique(data.labels)]
    return float(np.max(np.linalg.norm(means[:, None] - means[None], axis=2)))
