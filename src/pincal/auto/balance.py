"""Geometry and effect fitted together, weighted so that the URDF alone stays the best URDF.

A URDF consumer uses the geometry without the sidecar's effect; ``pincal compensate`` uses both.
A joint fit of geometry and effect is best with the sidecar but leaves a URDF that leans on it
(its geometry does not absorb what of the effect it could); the geometric fit alone is the best
URDF but leaves the effect fitted on top of it only what the geometry did not absorb. Between the
two lies a family of fits, each minimising over the geometry, registration and tool

    |r_full(θ)|² + λ · |r_alone(θ)|²

(``r_alone``: the same geometry, registration and tool without the effect), the effect held at
its joint fit's value (its physical value: a stiffness, an amplitude, as the diagnosis reads
it). λ = 0 is the joint fit, λ → ∞ the geometry first and the effect fitted on top. λ is
chosen by K-fold cross-validation of the problem linearised at the joint fit: among the λ of
:data:`WEIGHTS` whose held-out error of the URDF alone is no larger than the geometric
fit's (λ → ∞), so that the URDF alone is no worse than the geometry alone would be (within the
cross-validation's noise), that of them whose model with the sidecar cross-validates best. On
simulated UR5s with one effect of 0.4 mm RMS at the tip (compliance, harmonic, scale, backlash; 60 poses,
0.05 mm noise), the URDF alone stays within ±5 % of the geometric fit on 200 held-out poses,
while the model with its sidecar goes from 0.25-0.34 mm (geometry first) to 0.14-0.29 mm (joint
fit: 0.10 mm, but its URDF alone 8-21 % worse). On Gao et al.'s arm (20 of its 28 poses fitted)
a held compliance double-counts what the geometry took of it, and λ = ∞ is chosen.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from pincal.identify.folds import held_out_rows
from pincal.identify.measurements import Problem
from pincal.identify.records import Balance
from pincal.identify.solver import Setup, solve

#: The weights λ tried, smallest first; ``inf`` is the geometry first. Below 1 the linearised
#: cross-validation misjudges the URDF alone (on simulated UR5s it chose 0.1-0.3 for URDFs 7-9 %
#: worse alone than the geometric fit on 200 held-out poses); from 1 on, within 1.5 %.
WEIGHTS = (1.0, 3.0, 10.0, 30.0, np.inf)
#: λ standing for infinity in the linear algebra (the alone rows dominate the geometry).
LARGE = 1e8


class Stacked:
    """The residuals of the model with its effect, and √λ times those of the same model without it."""

    def __init__(self, full: Problem, weight: float) -> None:
        self.full, self.model, self.measurement = full, full.model, full.measurement
        self.alone = Problem(full.model, full.measurement, full.data, None)
        self.effect = np.arange(full.model.n_params, full.n_model)
        self.root = float(np.sqrt(min(weight, LARGE)))
        self.names, self.units, self.n_model = full.names, full.units, full.n_model
        self.data = full.data
        self.blockwise = (
            False  # solved whole (pincal.identify.chunked): its rows are the full problem's twice
        )

    @property
    def n_params(self) -> int:
        """Number of unknowns (the full problem's)."""
        return self.full.n_params

    def initial_theta(self) -> np.ndarray:
        """The full problem's start."""
        return self.full.initial_theta()

    def _alone(self, theta: np.ndarray) -> np.ndarray:
        return np.delete(theta, self.effect)

    def n_rows(self) -> int:
        """How many residual rows: the full problem's twice."""
        return 2 * self.full.n_rows()

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


class Delivered:
    """The delivered fit linearised at θ, for K-fold cross-validation of any residual vectors.

    Unknowns ``free`` (a mask); the effect's are those between the model's and the measurement's.
    How each fold refits, by the weight λ:

    - 0 (a joint fit): geometry, registration, tool and effect on the rows with the effect;
    - finite: geometry, registration and tool on those rows and √λ × the rows without the effect,
      the effect held at its value in θ (the joint fit's: its physical value);
    - ∞ (geometry first): geometry, registration and tool on the rows without the effect, then the
      effect on top of them.
    """

    def __init__(self, problem: Problem, theta: np.ndarray, free: np.ndarray, weight: float) -> None:
        stacked = Stacked(problem, 1.0)
        effect = np.zeros(problem.n_params, dtype=bool)
        effect[stacked.effect] = True
        n = problem.n_rows()
        both = (
            stacked.jacobian(theta, np.flatnonzero(free & ~effect))
            if (free & ~effect).any()
            else np.zeros((2 * n, 0))
        )
        self.jf, self.ja = _unit(both[:n]), _unit(both[n:])
        cols = np.flatnonzero(free & effect)
        self.effect = _unit(problem.jacobian(theta, cols)) if cols.size else np.zeros((n, 0))
        self.full, self.alone = problem.residuals(theta), stacked.alone.residuals(stacked._alone(theta))
        self.weight = weight
        if weight == 0.0 and self.effect.shape[1]:
            self.jf = np.hstack([self.jf, self.effect])
            self.ja = np.hstack([self.ja, np.zeros_like(self.effect)])

    def errors(self, test: np.ndarray, full: np.ndarray, alone: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Held-out rows ``test`` (mask) of the residual columns ``full`` and ``alone`` (rows, M),
        after the fit of the other rows: (with the effect, without it) [m]."""
        train = ~test
        if np.isinf(self.weight):
            step = np.linalg.lstsq(self.ja[train], alone[train], rcond=1e-12)[0]
            after = full - self.jf @ step
            on_top = np.linalg.lstsq(self.effect[train], after[train], rcond=1e-12)[0]
            return after[test] - self.effect[test] @ on_top, alone[test] - self.ja[test] @ step
        root = np.sqrt(self.weight)
        lhs = np.vstack([self.jf[train], root * self.ja[train]])
        step = np.linalg.lstsq(lhs, np.concatenate([full[train], root * alone[train]]), rcond=1e-12)[0]
        return full[test] - self.jf[test] @ step, alone[test] - self.ja[test] @ step


def _unit(jac: np.ndarray) -> np.ndarray:
    """Columns scaled to unit norm (the least squares stay well conditioned)."""
    return jac / np.where((n := np.linalg.norm(jac, axis=0)) > 0, n, 1.0)


def choose_weight(setup: Setup, theta: np.ndarray, free: np.ndarray, folds: int, seed: int) -> Balance:
    """λ for the joint fit ``theta`` of ``setup`` (its unknowns ``free``, a mask), by K-fold CV."""
    problem = setup.problem
    groups = held_out_rows(problem, min(folds, len(problem.data)), seed)
    tests = []
    for rows in groups:
        test = np.zeros(problem.n_rows(), dtype=bool)
        test[rows] = True
        tests.append(test)
    per = 1 if problem.measurement.measure.by_pairs else 3
    alone_mm, full_mm = [], []
    for weight in WEIGHTS:
        fit = Delivered(problem, theta, free, weight)
        pairs = [fit.errors(t, fit.full[:, None], fit.alone[:, None]) for t in tests]
        full_mm.append(float(np.sqrt(per * np.mean(np.concatenate([f for f, _ in pairs]) ** 2))) * 1e3)
        alone_mm.append(float(np.sqrt(per * np.mean(np.concatenate([a for _, a in pairs]) ** 2))) * 1e3)
    reference = alone_mm[-1]
    allowed = [k for k, alone in enumerate(alone_mm) if alone <= reference * (1 + 1e-9)]  # ∞ always is
    weight = WEIGHTS[min(allowed, key=lambda k: full_mm[k])]
    return Balance(weight, WEIGHTS, tuple(alone_mm), tuple(full_mm))


def balanced_fit(setup: Setup, theta: np.ndarray, free: np.ndarray, weight: float) -> np.ndarray:
    """The λ-weighted fit from ``theta`` over the unknowns ``free`` but the effect's, held."""
    stacked = Stacked(setup.problem, weight)
    geometry = free.copy()
    geometry[stacked.effect] = False
    fitted, _ = solve(replace(setup, problem=stacked), theta, geometry)  # type: ignore[arg-type]
    return fitted
