"""Measurement poses chosen for the accuracy of the calibrated robot, among feasible candidates.

Candidates are random joint configurations within the limits (a ``margin`` of each range left
out) whose joint origins and measured point stay ``clearance`` above the floor (``z`` in the base
frame), and optionally within ``reach`` of the instrument; for fixed-point data, configurations
that put the ball in one of the sockets (:func:`pincal.planning.candidates.socket_candidates`). Each
candidate's rows are those the fit will see (:class:`pincal.planning.information.Information`), for
several guesses of the measured point on the tip, so that the plan does not rest on one.

The default criterion ``i`` (I-optimality) minimises what a user feels: the mean squared error of
the calibrated tip over the *task poses* (the whole feasible workspace by default, or the poses
the robot will work in), ``tr(W F⁻¹)`` with the registration and tool unknown as they are in the
fit, on the parameters the fit identifies. ``d`` (D-optimality, ``log det F``) shrinks the volume
of the parameters' confidence ellipsoid instead: it is blind to which parameters matter where the
robot works, and to the lever arm of an unknown tool. Both start from a greedy D-optimal design
and improve it by exchanges (:mod:`pincal.planning.design`), then by small feasible moves of each pose,
steps from a tenth to a hundredth of each joint's range (poses in sockets stay where they are).
``benchmarks/planning_ratio.py`` measures both against random poses (README, "Planning").

The predicted uncertainty follows from ``cov = F⁻¹``: parameter standard deviations, and the
held-out RMS over the task poses ``√(tr(W cov) + noise)``. A plan with no more independent
equations than identifiable parameters is refused; one with too few to spare once a fifth of the
poses is left out (:func:`safe_poses`) is made, with a warning.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pincal.errors import DataError
from pincal.files import atomic_write
from pincal.identify.fixed_points import PointDistance
from pincal.identify.kinds import get_kind
from pincal.kinematics.effects import Extension
from pincal.options import ROTATION_WEIGHT
from pincal.planning.candidates import candidate_poses, check_memory, perturbed, socket_candidates
from pincal.planning.design import CRITERIA, exchange, greedy, swap
from pincal.planning.equations import check_equations
from pincal.planning.information import Information, tool_hypotheses
from pincal.robot.robots import Robot
from pincal.workers import limited


@dataclass(frozen=True)
class Design:
    """A set of measurement poses and what it predicts.

    Attributes:
        q: (N, n) joint values [rad or m].
        condition_number: of the column-scaled identification Jacobian on the identifiable set.
        log_det: ``log det F`` of the whitened, scaled information matrix (larger is better).
        std: (P,) predicted standard deviation of each identifiable parameter [m or rad].
        model_rms_mm: predicted RMS model error over the task poses, from parameter uncertainty [mm].
        predicted_rms_mm: predicted held-out RMS, measurement noise included [mm].
    """

    q: np.ndarray
    condition_number: float
    log_det: float
    std: np.ndarray
    model_rms_mm: float
    predicted_rms_mm: float


@dataclass(frozen=True, eq=False)
class Plan:
    """Planned measurement poses, and random poses of the same number for comparison.

    Attributes:
        robot: the robot.
        model, measure, criterion: what the plan is for, and how it was chosen.
        names, units: the identifiable parameters (those of ``Design.std``) and their units.
        candidates: (M, n) the feasible random candidates (the first N are the random design),
            then the moves of the chosen poses tried by the refinement.
        chosen: (N,) indices of the planned poses among the candidates, in the order chosen.
        planned, random: the two designs.
        sockets: (N,) the socket of each planned pose (fixed-point data), else None.
        drawn: how many of ``candidates`` are random candidates (the rest are the refinement's
            moves); None: all of them.
        warnings: what the user should know about the plan (a thin margin of equations).
    """

    robot: Robot
    model: str
    measure: str
    criterion: str
    names: tuple[str, ...]
    units: tuple[str, ...]
    candidates: np.ndarray
    chosen: np.ndarray
    planned: Design
    random: Design
    sockets: np.ndarray | None = None
    drawn: int | None = None
    warnings: tuple[str, ...] = ()

    @property
    def q(self) -> np.ndarray:
        """The planned poses (N, n)."""
        return self.planned.q

    def summary(self) -> str:
        """Condition number and predicted uncertainties, planned against random poses."""
        rad = np.array([u == "rad" for u in self.units])
        drawn = len(self.candidates) if self.drawn is None else self.drawn
        moves = len(self.candidates) - drawn
        among = f"{drawn} candidates" + (f" (and {moves} local moves of the chosen poses)" if moves else "")
        head = f"  {'':8s} {'cond':>7s} {'log det F':>10s} {'max σ [mm]':>11s} {'max σ [mrad]':>13s}"
        lines = [
            f"{len(self.q)} poses for {self.model}/{self.measure}, {len(self.names)} identifiable "
            f"parameters, {'I' if self.criterion == 'i' else 'D'}-optimal among {among}:",
            head + f" {'held-out RMS [mm]':>18s} {'of which model':>15s}",
        ]
        for label, d in (("planned", self.planned), ("random", self.random)):
            lines.append(
                f"  {label:8s} {_condition(d.condition_number)} {d.log_det:10.1f} "
                f"{d.std[~rad].max() * 1e3:11.4f} "
                f"{d.std[rad].max() * 1e3 if rad.any() else 0.0:13.4f} {d.predicted_rms_mm:18.4f} "
                f"{d.model_rms_mm:15.4f}"
            )
        return "\n".join(lines)


def _condition(value: float) -> str:
    """A condition number in the table's 7 characters."""
    return f"{value:7.1f}" if value < 1e5 else f"{value:7.1e}"


def _design(info: Information, q: np.ndarray, labels: np.ndarray | None, weight: np.ndarray) -> Design:
    """What a design predicts, with the measured point at ``info.guess``."""
    raw, tips, _, known = info.raw(q, info.guess, labels=labels)
    flat = info.for_analysis(info.whiten(raw), tips)
    fisher = flat.T @ flat + info.prior(known)
    stacked = np.concatenate([flat, known[:, info.free] * info.scale[info.free] / info.noise])
    sv = np.linalg.svd(stacked, compute_uv=False)
    cov = np.linalg.pinv(fisher)
    model2 = float(np.trace(weight @ cov))
    noise2 = (2 if info.kind.by_pairs else 3) * info.noise**2
    return Design(
        q=q,
        condition_number=float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf"),
        log_det=float(np.linalg.slogdet(fisher)[1]),
        std=np.sqrt(np.clip(np.diag(cov), 0.0, None)) * info.scale[info.free],
        model_rms_mm=np.sqrt(model2) * 1e3,
        predicted_rms_mm=np.sqrt(model2 + noise2) * 1e3,
    )


@limited
def _quiet(done: int, total: int, stage: str) -> None:
    """No progress shown."""


def plan_poses(
    robot: Robot,
    n_poses: int,
    *,
    model: str = "placements",
    measure: str = "position",
    criterion: str = "i",
    candidates: int = 1000,
    seed: int = 0,
    tool: np.ndarray | None = None,
    tool_tolerance: float | None = None,
    task: np.ndarray | None = None,
    sockets: np.ndarray | None = None,
    point_distances: tuple[PointDistance, ...] = (),
    extension: Extension | str | None = None,
    noise: float = 3e-5,
    rot_noise: float = 1.5e-4,
    rotation_weight: float = ROTATION_WEIGHT,
    n_test: int = 200,
    margin: float = 0.05,
    clearance: float = 0.05,
    reach: float | None = None,
    instrument: np.ndarray | None = None,
    progress: Callable[[int, int, str], None] | None = None,
) -> Plan:
    """Choose ``n_poses`` measurement poses among ``candidates`` feasible ones.

    Args:
        robot: the robot.
        n_poses: poses to measure.
        model: the parameterization that will be calibrated.
        measure: ``position``, ``pose``, ``distance`` or ``points`` (fixed points: ``sockets``).
        criterion: ``i`` (the calibrated tip's mean squared error over the task poses) or ``d``
            (log det of the information), see :mod:`pincal.planning.design`.
        candidates: number of random feasible candidates.
        seed: seed of the candidates (the default task poses use ``seed + 1``).
        tool: the measured point on the tip (3,) [m], as roughly known (default: the tip's origin).
        tool_tolerance: how far the real point may be from ``tool`` [m] (default 0.01, or 0.1 from
            the tip's origin): the plan is judged on 4 points this far around the guess and
            predicted on the one that identifies most (``Information.guess``).
        task: (T, n) the poses the robot will work in [rad or m] (default: ``n_test`` random
            feasible poses, the whole workspace).
        sockets: (K, 3) where the fixed points are, roughly, in the base frame [m] (``points``).
        point_distances: known distances between the fixed points ((A, B, D [m]), ...).
        extension: a non-geometric effect identified with the geometry (``EFFECT:JOINT``).
        noise: 1σ of each measured coordinate [m]; rot_noise: of each orientation axis [rad].
        rotation_weight: weight of orientation residuals [m/rad] (pose data).
        n_test: random task poses when ``task`` is not given.
        margin, clearance, reach, instrument: the feasible set, see :func:`candidate_poses`.
        progress: called as ``progress(done, 2, stage)``: the candidates, then the choice.

    Raises:
        DataError: unknown measure or criterion, too few feasible candidates, no sockets or one out of reach.
        IdentifiabilityError: too few independent equations (:mod:`pincal.planning.equations`).
    """
    _check(robot, measure, criterion, (n_poses, candidates), sockets)
    told = progress or _quiet
    tools = _hypotheses(tool, tool_tolerance)
    where = Feasible.around(tool, margin, clearance, instrument, reach)
    cand, labels = _candidates(robot, candidates, seed, sockets, where)
    told(1, 2, f"{len(cand)} feasible candidates")
    if task is None:
        task = candidate_poses(
            robot, n_test, seed + 1, margin, 0.0, clearance, where.point, instrument, reach
        )
    ext = Extension.parse(robot, extension) if isinstance(extension, str) else extension
    info = Information(
        robot, model, measure, cand, tools, ext, noise, rot_noise, rotation_weight, labels, point_distances
    )
    warnings, drawn = check_equations(measure, n_poses, int(info.free.sum())), len(cand)  # before moves
    weights = info.task_weights(np.atleast_2d(task), tools)
    chosen = _choose(info, criterion, weights, len(cand), n_poses)
    cand, chosen = _refine(info, tools, criterion, weights, cand, chosen, where, seed)
    told(2, 2, f"{n_poses} poses chosen and refined")
    names, units = (tuple(x for x, f in zip(v, info.free) if f) for v in (info.names, info.units))
    at = (None, None) if labels is None else (labels[chosen], labels[:n_poses])
    w = weights[info.best]  # the predictions' hypothesis, whose weights are already made
    planned, random = _design(info, cand[chosen], at[0], w), _design(info, cand[:n_poses], at[1], w)
    what = (robot, model, measure, criterion, names, units, cand, np.array(chosen), planned, random)
    return Plan(*what, sockets=at[0], drawn=drawn, warnings=warnings)


def _hypotheses(tool: np.ndarray | None, tolerance: float | None) -> list[np.ndarray]:
    """The measured points a plan is judged on: the guess and points ``tolerance`` [m] around it
    (0.01 m when the tool is given, else 0.1 m from the tip's origin)."""
    return tool_hypotheses(tool, (0.01 if tool is not None else 0.1) if tolerance is None else tolerance)


def _choose(
    info: Information, criterion: str, weights: Sequence[np.ndarray], n_cand: int, n_poses: int
) -> list[int]:
    """``n_poses`` of the ``n_cand`` candidates: greedy, then exchanges (:mod:`pincal.planning.design`)."""
    rows, priors = info.candidate_rows, info.priors
    return exchange(criterion, rows, n_cand, greedy(rows, n_cand, n_poses, priors), priors, weights)


@dataclass(frozen=True)
class Feasible:
    """Where candidates may be, see :func:`pincal.planning.candidates.candidate_poses` (lengths [m])."""

    margin: float
    clearance: float
    point: np.ndarray
    instrument: np.ndarray | None
    reach: float | None

    @classmethod
    def around(
        cls,
        tool: np.ndarray | None,
        margin: float,
        clearance: float,
        instrument: np.ndarray | None,
        reach: float | None,
    ) -> Feasible:
        """The feasible set for the measured point ``tool`` (default: the tip's origin)."""
        point = np.zeros(3) if tool is None else np.asarray(tool, float)
        return cls(margin, clearance, point, instrument, reach)


#: Local refinement: the steps of the moves of each pose (fractions of each joint's range) and
#: how many moves of each pose are tried per step.
STEPS, MOVES = (0.1, 0.05, 0.025, 0.0125, 0.006), 20


def _refine(
    info: Information,
    tools: list[np.ndarray],
    criterion: str,
    weights: list[np.ndarray],
    cand: np.ndarray,
    chosen: list[int],
    feasible: Feasible,
    seed: int,
) -> tuple[np.ndarray, list[int]]:
    """The design improved by small moves of its poses: at each of :data:`STEPS`, ``MOVES``
    feasible moves of every pose become candidates (appended to ``cand`` and ``info``), and
    each pose is replaced by its best move when that lowers the loss (:func:`pincal.planning.design.swap`).
    Poses in sockets cannot move: they are ordered socket by socket (the ball is moved once)."""
    if info.labels is not None:
        return cand, [chosen[k] for k in np.argsort(info.labels[chosen], kind="stable")]
    rng = np.random.default_rng(seed + 2)
    f = feasible
    for step in STEPS:
        moved, near = perturbed(
            info.robot, cand[chosen], MOVES, step, rng, f.margin, f.clearance, f.point, f.instrument, f.reach
        )
        pools = [len(cand) + np.flatnonzero(near == n) for n in range(len(chosen))]
        info.extend(moved, tools)
        cand = np.concatenate([cand, moved])
        chosen = swap(criterion, info.candidate_rows, chosen, info.priors, pools, weights)
    return cand, chosen


def _candidates(
    robot: Robot, n: int, seed: int, sockets: np.ndarray | None, where: Feasible
) -> tuple[np.ndarray, np.ndarray | None]:
    """Feasible candidates, and the socket each is at (fixed points) or None."""
    w = where
    if sockets is not None:
        return socket_candidates(robot, sockets, n, seed, w.margin, w.clearance, w.point)
    return candidate_poses(robot, n, seed, w.margin, 0.0, w.clearance, w.point, w.instrument, w.reach), None


def _check(
    robot: Robot, measure: str, criterion: str, sizes: tuple[int, int], sockets: np.ndarray | None
) -> None:
    """Refuse what cannot be planned (``sizes``: poses and candidates), with what to do, or
    what needs more memory than the machine has."""
    n_poses, candidates = sizes
    kind = get_kind(measure)  # a DataError naming the kinds if there is none of that name
    if criterion not in CRITERIA:
        raise DataError(f"unknown criterion {criterion!r}: choose one of {', '.join(CRITERIA)}")
    if kind.fixed_points and sockets is None:
        raise DataError("planning fixed-point data needs where the sockets are: sockets=X,Y,Z;X,Y,Z")
    if not 0 < n_poses <= candidates:
        raise DataError(f"n_poses={n_poses} must be between 1 and the number of candidates ({candidates})")
    check_memory(robot, candidates, measure, n_poses)


def write_poses(path: str | Path, plan: Plan, degrees: bool = False, units: str = "m") -> None:
    """Write the planned poses as a CSV with a column per joint (radians, or degrees; prismatic
    joints in ``units``), and for fixed-point data a ``point`` column naming the socket, atomically."""
    from pincal.units import joints_to_file  # the one unit layer (issue 33)

    q = joints_to_file(plan.q, degrees, units, plan.robot.prismatic)
    sockets = [""] * len(q) if plan.sockets is None else [f",{k}" for k in plan.sockets]
    head = ",".join(plan.robot.joint_names) + ("" if plan.sockets is None else ",point")
    lines = [head] + [",".join(repr(float(v)) for v in row) + at for row, at in zip(q, sockets)]
    atomic_write(path, "\n".join(lines) + "\n")
