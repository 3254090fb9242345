"""Closed-form screening of candidate effects on the problem linearised at the geometric fit.

A candidate effect adds one or two columns ``E`` to the geometric fit's Jacobian ``J`` (its
identifiable model, registration and tool columns, at the fit θ̂, where the residuals are ``r``).
Near θ̂ the problem is linear, ``r(θ̂ + δ) ≈ r + [J E] δ``, so a K-fold cross-validation needs no
nonlinear solve: each fold's fit is the least-squares ``δ`` of the other folds' rows, and its
held-out error is ``r + [J E] δ`` on the fold's rows. ``J``'s part of the normal equations is
formed once per fold and shared by every candidate; a candidate adds ``Jᵀ E`` and ``Eᵀ E``.

:func:`pincal.auto.diagnose.diagnose` ranks the candidates by this linearised cross-validated RMS and
runs the nonlinear calibration and cross-validation only for the few best. The folds, the
held-out errors (a pose's 3-D position error; for distance data every pair with a held-out pose)
and the F-test's residual sums are those of the nonlinear path.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from pincal.data.dataset import Dataset
from pincal.identify.calibration import Calibration
from pincal.identify.folds import pose_folds
from pincal.identify.identifiability import RCOND
from pincal.identify.measurements import Problem
from pincal.kinematics.effects import AnyEffect, combined


@dataclass(frozen=True)
class Screen:
    """A candidate judged on the linearised problem.

    Attributes:
        cv_rms_mm: linearised K-fold cross-validated RMS [mm].
        rss: residual sum of squares of the linearised fit on all rows [m²].
        params: the effect's parameters of that fit (in the extension's units).
        identifiable: whether the data tells the effect from the geometry.
    """

    cv_rms_mm: float
    rss: float
    params: np.ndarray
    identifiable: bool


class Linearised:
    """The geometric fit's residuals and Jacobian, split by folds, ready for extra columns."""

    def __init__(self, base: Calibration, data: Dataset, folds: int, seed: int) -> None:
        self.base, self.data = base, data
        problem = base.problem(data)
        self.kind = base.measurement.measure
        self.residuals = problem.residuals(base.theta)
        self.free = np.flatnonzero(base.identifiability.identifiable)
        jac = problem.jacobian(base.theta, self.free)
        self.norms = np.where((n := np.linalg.norm(jac, axis=0)) > 0, n, 1.0)
        self.jac = jac / self.norms  # unit columns: the normal equations stay well scaled
        pose_of_row = self.kind.owners(problem)
        self.folds: list[tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]] = []
        for held in pose_folds(data, folds, seed):
            in_held = np.isin(pose_of_row, held)
            test = np.asarray(in_held.any(axis=1))
            train = ~test
            j_train = self.jac[train]
            normal = (j_train.T @ j_train, j_train.T @ self.residuals[train])
            self.folds.append((train, test, normal))
        self.gram = (self.jac.T @ self.jac, self.jac.T @ self.residuals)

    def extra_columns(self, extension: AnyEffect) -> np.ndarray:
        """The effect's Jacobian columns at θ̂ (its parameters zero), after the effects the base
        fit already holds."""
        base = self.base
        n_model = base.model.n_params + (base.extension.n_params if base.extension is not None else 0)
        held = base.extension.parts if base.extension is not None else ()
        both = combined([*held, *extension.parts])
        problem = Problem(base.model, replace(base.measurement, pairs=None), self.data, both)
        theta = np.concatenate([base.theta[:n_model], np.zeros(extension.n_params), base.theta[n_model:]])
        return problem.jacobian(theta, np.arange(n_model, n_model + extension.n_params))

    def _held_out(self, test: np.ndarray, predicted: np.ndarray) -> np.ndarray:
        """Held-out errors [m]: per pose the 3-D position error, per pair the distance error."""
        return self.kind.held_out(predicted)

    def screen(self, extension: AnyEffect | None = None) -> Screen:
        """The linearised cross-validation and all-row fit, with ``extension``'s columns or none."""
        extra = np.empty((len(self.residuals), 0)) if extension is None else self.extra_columns(extension)
        e_norms = np.where((n := np.linalg.norm(extra, axis=0)) > 0, n, 1.0)
        extra = extra / e_norms
        n_base = self.jac.shape[1]

        def fit(
            jac: np.ndarray, ext: np.ndarray, res: np.ndarray, gram: tuple[np.ndarray, np.ndarray]
        ) -> np.ndarray:
            """The least-squares step of ``res + [jac ext] δ`` (``gram``: ``jacᵀ jac``, ``jacᵀ res``)."""
            je = jac.T @ ext
            lhs = np.block([[gram[0], je], [je.T, ext.T @ ext]])
            return -np.linalg.lstsq(lhs, np.concatenate([gram[1], ext.T @ res]), rcond=1e-12)[0]

        def predict(rows: np.ndarray, step: np.ndarray) -> np.ndarray:
            return self.residuals[rows] + self.jac[rows] @ step[:n_base] + extra[rows] @ step[n_base:]

        errors = []
        for train, test, gram in self.folds:
            step = fit(self.jac[train], extra[train], self.residuals[train], gram)
            errors.append(self._held_out(test, predict(test, step)))
        pooled = np.concatenate(errors)
        every = np.arange(len(self.residuals))
        step = fit(self.jac, extra, self.residuals, self.gram)
        rss = float(np.sum(predict(every, step) ** 2))
        jj, je, ee = self.gram[0], self.jac.T @ extra, extra.T @ extra
        # what of the effect's columns the geometry cannot absorb (Schur complement, unit columns)
        schur = ee - je.T @ np.linalg.lstsq(jj, je, rcond=1e-12)[0] if extra.shape[1] else np.ones((1, 1))
        identifiable = bool(np.sqrt(max(float(np.linalg.eigvalsh(schur).min()), 0.0)) > RCOND)
        params = step[n_base:] / e_norms
        return Screen(float(np.sqrt(np.mean(pooled**2))) * 1e3, rss, params, identifiable)
