"""Geometry and effect fitted together, weighted so that the URDF alone stays the best URDF.

A URDF consumer uses the geometry without the sidecar's effect; ``pincal compensate`` uses both.
A joint fit of geometry and effect is best with the sidecar but leaves a URDF that leans on it
(its geometry does not absorb what of the effect it could); the geometric fit alone is the best
URDF but leaves the effect fitted on top of it only what the geometry did not absorb. Between the
two lies a family of fits, each minimising

    |r_full(θ)|² + λ · |r_alone(θ)|²

(``r_alone``: the same geometry, registration and tool without the effect). λ = 0 is the joint
fit, λ → ∞ the geometry first and the effect on top. λ is chosen by K-fold cross-validation of
the problem linearised at the joint fit: the smallest λ of :data:`WEIGHTS` whose held-out error
of the URDF alone is no larger than the geometric fit's (λ → ∞), so that the URDF alone is
no worse than the geometry alone would be (within the cross-validation's noise), and the model
with the sidecar as good as that allows. On simulated UR5s with one effect of 0.4 mm RMS at the
tip (compliance, harmonic, scale, backlash; 60 poses, 0.05 mm noise), the URDF alone stays within
±2 % of the geometric fit on 200 held-out poses, while the model with its sidecar goes from
0.25-0.34 mm (geometry first) to 0.12-0.26 mm (joint fit: 0.10 mm, but its URDF alone 10-25 %
worse).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .folds import held_out_rows
from .measurements import Problem
from .solver import Setup, solve

#: The weights λ tried, smallest first; ``inf`` is the geometry first. Below 1 the linearised
#: cross-validation misjudges the URDF alone (on simulated UR5s it chose 0.1-0.3 for URDFs 7-9 %
#: worse alone than the geometric fit on 200 held-out poses); from 1 on, within 1.5 %.
WEIGHTS = (1.0, 3.0, 10.0, 30.0, np.inf)
#: λ standing for infinity in the linear algebra (the alone rows dominate the geometry).
LARGE = 1e8


@dataclass(frozen=True)
class Balance:
    """The weight chosen and what each weight's cross-validation gave.

    Attributes:
        weight: λ (``inf``: geometry first).
        alone_cv_rms_mm: per λ, the URDF alone's linearised cross-validated RMS [mm].
        full_cv_rms_mm: per λ, the model with its sidecar's [mm].
    """

    weight: float
    alone_cv_rms_mm: tuple[float, ...]
    full_cv_rms_mm: tuple[float, ...]

    def to_dict(self) -> dict[str, object]:
        """JSON-ready (``inf`` written as None)."""
        return {
            "weight": None if np.isinf(self.weight) else self.weight,
            "weights": [None if np.isinf(w) else w for w in WEIGHTS],
            "alone_cv_rms_mm": list(self.alone_cv_rms_mm),
            "full_cv_rms_mm": list(self.full_cv_rms_mm),
            "by": "K-fold cross-validation, linearised at the joint fit: the smallest weight whose URDF "
            "alone is no worse than the geometry alone",
        }


class Stacked:
    """The residuals of the model with its effect, and √λ times those of the same model without it."""

    def __init__(self, full: Problem, weight: float) -> None:
        self.full, self.model, self.measurement = full, full.model, full.measurement
        self.alone = Problem(full.model, full.measurement, full.data, None)
        self.effect = np.arange(full.model.n_params, full.n_model)
        self.root = float(np.sqrt(min(weight, LARGE)))
        self.names, self.units, self.n_model = full.names, full.units, full.n_model

    @property
    def n_params(self) -> int:
        """Number of unknowns (the full problem's)."""
        return self.full.n_params

    def initial_theta(self) -> np.ndarray:
        """The full problem's start."""
        return self.full.initial_theta()

    def _alone(self, theta: np.ndarray) -> np.ndarray:
        return np.delete(theta, self.effect)

    def residuals(self, theta: np.ndarray) -> np.ndarray:
        """Full residuals, then √λ times those without the effect."""
        return np.concatenate(
            [self.full.residuals(theta), self.root * self.alone.residuals(self._alone(theta))]
        )

    def jacobian(self, theta: np.ndarray, cols: np.ndarray | None = None) -> np.ndarray:
        """Their Jacobian for the unknowns ``cols`` (indices or a mask; default all)."""
        cols = np.arange(self.n_params) if cols is None else np.asarray(cols)
        cols = np.flatnonzero(cols) if cols.dtype == bool else cols
        keep = ~np.isin(cols, self.effect)
        mapped = np.array([c - np.sum(self.effect < c) for c in cols[keep]], dtype=int)
        lower = np.zeros((len(self.alone.residuals(self._alone(theta))), len(cols)))
        if mapped.size:
            lower[:, keep] = self.alone.jacobian(self._alone(theta), mapped)
        return np.vstack([self.full.jacobian(theta, cols), self.root * lower])


def _cv(
    full: np.ndarray, alone: np.ndarray, jf: np.ndarray, ja: np.ndarray, folds: list, weight: float
) -> tuple[float, float]:
    """Linearised K-fold CV of the λ-weighted fit: held-out mean squares (alone, full) [m²]."""
    root = np.sqrt(min(weight, LARGE))
    err_a, err_f = [], []
    for rows in folds:
        train = np.ones(len(full), dtype=bool)
        train[rows] = False
        lhs = np.vstack([jf[train], root * ja[train]])
        rhs = np.concatenate([full[train], root * alone[train]])
        step = -np.linalg.lstsq(lhs, rhs, rcond=1e-12)[0]
        err_f.append(full[rows] + jf[rows] @ step)
        err_a.append(alone[rows] + ja[rows] @ step)
    return float(np.mean(np.concatenate(err_a) ** 2)), float(np.mean(np.concatenate(err_f) ** 2))


def choose_weight(setup: Setup, theta: np.ndarray, free: np.ndarray, folds: int, seed: int) -> Balance:
    """λ for the joint fit ``theta`` of ``setup`` (its unknowns ``free``, a mask), by K-fold CV."""
    full_problem = setup.problem
    stacked = Stacked(full_problem, 1.0)
    cols = np.flatnonzero(free)
    n = len(full_problem.residuals(theta))
    both = stacked.jacobian(theta, cols)
    jf, ja = both[:n], both[n:]
    norms = np.where((s := np.linalg.norm(jf, axis=0) + np.linalg.norm(ja, axis=0)) > 0, s, 1.0)
    jf, ja = jf / norms, ja / norms
    r_full, r_alone = full_problem.residuals(theta), stacked.alone.residuals(stacked._alone(theta))
    groups = held_out_rows(full_problem, min(folds, len(full_problem.data)), seed)
    scores = [_cv(r_full, r_alone, jf, ja, groups, w) for w in WEIGHTS]
    reference = scores[-1][0]
    weight = next(w for w, (alone, _) in zip(WEIGHTS, scores) if alone <= reference * (1 + 1e-9))
    per = 3 if full_problem.measurement.kind != "distance" else 1
    to_mm = [np.sqrt(per * s) * 1e3 for s in (a for a, _ in scores)]
    to_mm_full = [np.sqrt(per * s) * 1e3 for s in (f for _, f in scores)]
    return Balance(weight, tuple(to_mm), tuple(to_mm_full))


def balanced_fit(setup: Setup, theta: np.ndarray, free: np.ndarray, weight: float) -> np.ndarray:
    """The λ-weighted fit from ``theta`` over the unknowns ``free``."""
    stacked = Stacked(setup.problem, weight)
    fitted, _ = solve(Setup(stacked, setup.scale, setup.tool), theta, free)  # type: ignore[arg-type]
    return fitted
