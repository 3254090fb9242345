"""Which model parameters to fit: forward selection scored by cross-validation on the fitted poses.

With few poses, fitting every identifiable parameter fits the noise and the effects no rigid model
holds, and predicts new poses worse than a smaller model. :func:`select_parameters` starts from
the registration and tool alone (and any extension) and adds, one at a time, the model parameter
that gives the lowest cross-validated RMS, until no candidate adds rank. The chosen set is the
shortest prefix of that path whose cross-validated RMS is within ``min_gain`` (relative) of the
path's minimum: the minimum itself, unless a smaller model is as good. Only the data it is given
is used.

Every candidate is scored in closed form on the problem linearised at the registration-only fit.
With ``H`` the hat matrix of the current columns and ``e`` the fit's residual, the residual of
a group of rows ``g`` predicted by a fit on the other rows is ``(I - H_gg)⁻¹ e_g`` (the PRESS
identity); adding one column ``u`` (orthonormalised against the current ones) changes ``H`` by
``u uᵀ`` and ``e`` by ``-u uᵀe``, so a step costs a few small solves per group and candidate. A
group is one pose (leave-one-out, the default) or one of K folds; for distance data it holds the
rows of every pair with a pose in the group, as in :func:`pincal.cross_validate`.

:func:`cross_validate_selection` judges the whole procedure (selection, then the nonlinear fit of
the chosen set) by K-fold cross-validation, the selection re-run on each fold's fitted poses:
the cross-validated RMS of the chosen step is biased low by the choice itself, this is not.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .crossval import fold_indices, held_out_errors
from .data import Dataset
from .evaluation import ErrorStats
from .identifiability import RCOND, parameter_scale
from .measurements import all_pairs
from .robots import Robot
from .solver import calibrate

#: Take the shortest prefix of the path within this fraction of its lowest cross-validated RMS.
MIN_GAIN = 0.01


@dataclass(frozen=True)
class SelectionStep:
    """One step of the forward selection.

    Attributes:
        added: the parameter added at this step (None for the start: registration and tool only).
        cv_rms_mm: cross-validated RMS after the step [mm] (pose data: rotations weighted by the
            rotation weight [m/rad]; distance data: over pairs).
        fit_rms_mm: RMS on the fitted poses after the step [mm], same units.
    """

    added: str | None
    cv_rms_mm: float
    fit_rms_mm: float


@dataclass(frozen=True)
class Selection:
    """The parameters chosen and the path that chose them.

    Attributes:
        model: the parameterization the names belong to.
        chosen: the chosen parameters, in the order they were added (pass as ``params=`` to
            :func:`pincal.calibrate`).
        path: every step until no candidate adds rank; ``path[len(chosen)]`` is the chosen one.
        folds: K of the cross-validation, or None for leave-one-out.
        min_gain: the parsimony margin.
    """

    model: str
    chosen: tuple[str, ...]
    path: tuple[SelectionStep, ...]
    folds: int | None
    min_gain: float

    @property
    def cv_rms_mm(self) -> float:
        """Cross-validated RMS of the chosen step [mm] (linearised)."""
        return self.path[len(self.chosen)].cv_rms_mm

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return {
            "model": self.model,
            "chosen": list(self.chosen),
            "cv_rms_mm": self.cv_rms_mm,
            "folds": self.folds or "leave-one-out",
            "min_gain": self.min_gain,
            "path": [
                {"added": s.added, "cv_rms_mm": s.cv_rms_mm, "fit_rms_mm": s.fit_rms_mm} for s in self.path
            ],
        }


def _groups(kind: str, n_poses: int, n_rows: int, folds: int | None, seed: int) -> list[np.ndarray]:
    """Residual rows of each held-out group (a pose, or a fold of poses)."""
    held = [np.array([i]) for i in range(n_poses)] if folds is None else fold_indices(n_poses, folds, seed)
    if kind == "distance":
        pairs = all_pairs(n_poses)
        return [np.flatnonzero(np.isin(pairs, h).any(axis=1)) for h in held]
    per_pose = n_rows // n_poses
    return [(h[:, None] * per_pose + np.arange(per_pose)).reshape(-1) for h in held]


def _scores(
    q: np.ndarray, res: np.ndarray, u: np.ndarray, groups: list[np.ndarray]
) -> tuple[np.ndarray, np.ndarray]:
    """Cross-validated and in-sample sums of squares [m²] when each column of ``u`` (orthonormal to
    ``q``, or zero) is added to the basis ``q``; the residual ``res`` is already orthogonal to ``q``."""
    e = res[:, None] - u * (u.T @ res)  # (m, C) residual after each addition
    sse = np.zeros(u.shape[1])
    by_size: dict[int, list[np.ndarray]] = {}
    for g in groups:
        by_size.setdefault(len(g), []).append(g)
    for size, same in by_size.items():
        rows = np.array(same)  # (G, s)
        qg, ug, eg = q[rows], u[rows].transpose(0, 2, 1), e[rows].transpose(0, 2, 1)  # (G,s,r) (G,C,s)
        hat = (qg @ qg.transpose(0, 2, 1))[:, None] + ug[..., :, None] * ug[..., None, :]
        try:
            loo = np.linalg.solve(np.eye(size) - hat, eg[..., None])[..., 0]
        except np.linalg.LinAlgError:  # a group alone determines a column: nothing predicts it
            loo = (np.linalg.pinv(np.eye(size) - hat, rcond=1e-12) @ eg[..., None])[..., 0]
            loo[np.linalg.matrix_rank(np.eye(size) - hat) < size] = np.inf
        sse += np.sum(loo**2, axis=(0, 2))
    return sse, np.sum(e**2, axis=0)


def select_parameters(
    robot: Robot,
    data: Dataset,
    model: str = "placements",
    measure: str | None = None,
    *,
    folds: int | None = None,
    seed: int = 0,
    min_gain: float = MIN_GAIN,
    max_params: int | None = None,
    **options: Any,
) -> Selection:
    """Forward selection of the model parameters by cross-validation on ``data`` alone.

    Args:
        robot: the robot.
        data: the poses to fit (the only data looked at).
        model: the parameterization whose parameters are candidates.
        measure: ``position``, ``pose`` or ``distance`` (default as :func:`pincal.calibrate`).
        folds: K of the cross-validation, or None for leave-one-out over poses.
        seed: seed of the folds (K-fold only).
        min_gain: choose the shortest prefix of the path whose cross-validated RMS is within this
            fraction of the path's lowest.
        max_params: end the path after this many parameters.
        **options: passed to :func:`pincal.calibrate` (registration, tool, extension, ...);
            ``params`` is the selection's own.
    """
    options = {k: v for k, v in options.items() if k != "params"}
    start = calibrate(robot, data, model, measure, params=[], **options)
    problem = start.problem(data)
    kind = start.measurement.kind
    res = problem.residuals(start.theta)
    length = max(0.05, float(np.sqrt(np.mean(np.sum((data.points - data.points.mean(0)) ** 2, axis=1)))))
    jac = problem.jacobian(start.theta) * parameter_scale(problem.units, length)
    n_geo = start.model.n_params
    tol = RCOND * float(np.max(np.linalg.norm(jac, axis=0)))

    fixed = jac[:, n_geo:]  # extension, registration and tool: always fitted
    left, sv, _ = np.linalg.svd(fixed, full_matrices=False)
    q = left[:, sv > tol]
    res = res - q @ (q.T @ res)
    groups = _groups(kind, len(data), len(res), folds, seed)
    n_units = float(sum(len(g) for g in groups)) if kind == "distance" else float(len(data))
    n_fit_units = float(len(res)) if kind == "distance" else float(len(data))

    def rms(sse: np.ndarray, units: float) -> np.ndarray:
        return np.sqrt(sse / units) * 1e3

    cv0, fit0 = _scores(q, res, np.zeros((len(res), 1)), groups)
    path = [SelectionStep(None, float(rms(cv0, n_units)[0]), float(rms(fit0, n_fit_units)[0]))]
    candidates = [k for k in range(n_geo) if problem.names[k] not in start.model.held]
    while candidates and (max_params is None or len(path) <= max_params):
        cols = jac[:, candidates]
        for _ in range(2):  # Gram-Schmidt twice keeps the basis orthonormal
            cols = cols - q @ (q.T @ cols)
        norms = np.linalg.norm(cols, axis=0)
        valid = norms > tol
        if not valid.any():
            break
        u = np.where(valid, cols / np.where(valid, norms, 1.0), 0.0)
        sse, fit = _scores(q, res, u, groups)
        cv = np.where(valid, rms(sse, n_units), np.inf)
        best = int(np.argmin(cv))
        if not np.isfinite(cv[best]):
            break
        name = problem.names[candidates[best]]
        path.append(SelectionStep(name, float(cv[best]), float(rms(fit[best : best + 1], n_fit_units)[0])))
        q = np.column_stack([q, u[:, best]])
        res = res - u[:, best] * (u[:, best] @ res)
        candidates = [c for k, c in enumerate(candidates) if k != best and valid[k]]
    scores = np.array([step.cv_rms_mm for step in path])
    stop = int(np.flatnonzero(scores <= (1.0 + min_gain) * scores.min())[0])
    chosen = tuple(str(step.added) for step in path[1 : stop + 1])
    return Selection(start.model.kind, chosen, tuple(path), folds, min_gain)


@dataclass(frozen=True)
class SelectionCrossValidation:
    """Held-out errors of the whole procedure: selection and fit on K-1 folds, judged on the last.

    Attributes:
        folds: number of folds.
        before: nominal kinematics with registration and tool fitted on the other folds.
        after: the selected model fitted on the other folds.
        chosen: the parameters each fold's selection chose.
    """

    folds: int
    before: ErrorStats
    after: ErrorStats
    chosen: tuple[tuple[str, ...], ...]


def cross_validate_selection(
    robot: Robot,
    data: Dataset,
    model: str = "placements",
    measure: str | None = None,
    folds: int = 5,
    seed: int = 0,
    *,
    selection_folds: int | None = None,
    min_gain: float = MIN_GAIN,
    **options: Any,
) -> SelectionCrossValidation:
    """K-fold cross-validation of :func:`select_parameters` followed by :func:`pincal.calibrate`.

    Args:
        robot: the robot.
        data: all poses.
        model: the parameterization.
        measure: the measurement (default as :func:`pincal.calibrate`).
        folds: K of the outer cross-validation (``len(data)`` for leave-one-out).
        seed: seed of the outer partition.
        selection_folds: K of the selection's own cross-validation (None: leave-one-out).
        min_gain: the selection's parsimony margin.
        **options: passed to both; each fold's fit takes ``partial=True``, as in
            :func:`pincal.cross_validate`.
    """
    before: list[np.ndarray] = []
    after: list[np.ndarray] = []
    chosen = []
    for held in fold_indices(len(data), folds, seed):
        fit = data.subset(np.setdiff1d(np.arange(len(data)), held))
        sel = select_parameters(
            robot, fit, model, measure, folds=selection_folds, seed=seed, min_gain=min_gain, **options
        )
        fold_options = {**options, "params": list(sel.chosen), "partial": True}
        cal = calibrate(robot, fit, model, measure, **fold_options)
        _, b, a = held_out_errors(cal, data, held)
        before.append(b)
        after.append(a)
        chosen.append(sel.chosen)
    return SelectionCrossValidation(
        folds, ErrorStats.of(np.concatenate(before)), ErrorStats.of(np.concatenate(after)), tuple(chosen)
    )
