"""The diagnosis' nonlinear stage: the finalists' fits on all poses and their cross-validations,
run as batches of independent jobs (:func:`~pincal.workers.run_jobs`) that the worker processes
share with the baseline's folds; the answers are the serial loop's, bit for bit."""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pincal.auto.screening import Screen
from pincal.identify.calibration import Calibration
from pincal.identify.kfold import CrossValidation, Fit, FoldRuns
from pincal.identify.warm import WarmStart
from pincal.kinematics.effects import AnyEffect, Extension, combined
from pincal.workers import run_jobs

#: ``quick`` diagnoses (``calibrate --extend auto``) judge by the nonlinear cross-validation only
#: the finalists whose linearised cross-validated gain reaches this (half of the diagnosis'
#: ``MIN_GAIN`` margin: the linearisation at the geometric fit is close, so one below it cannot
#: reach ``MIN_GAIN``); on data the rigid model explains, none does, and the diagnosis costs one
#: cross-validation instead of four.
QUICK_GAIN = 1.05


def worth_judging(
    top: list[tuple[Extension, Screen]], base_rms: float, p_of: Callable[[Screen], float], level: float
) -> list[tuple[Extension, Screen]]:
    """Of the best screened candidates ``top``, those a ``quick`` diagnosis judges by the
    nonlinear cross-validation: the ones that could be named, their linearised gain over
    ``base_rms`` [mm] reaching :data:`QUICK_GAIN` and their family-wise p-value (``p_of``, known
    before any nonlinear fit) under ``level``; the others' nonlinear figures could not change the
    answer."""
    return [(e, s) for e, s in top if base_rms / s.cv_rms_mm >= QUICK_GAIN and p_of(s) < level]


@dataclass(frozen=True)
class Finalists:
    """The nonlinear fits of the finalists and their cross-validations, as jobs for
    :func:`~pincal.workers.run_jobs`.

    Attributes:
        fit: the calibration.
        what: robot, data, model, measure.
        held: the effects the baseline holds (each candidate is added to them).
        options: the fit's options (warm-started at the baseline's fit).
    """

    fit: Fit
    what: tuple[Any, ...]
    held: list[Extension]
    options: dict[str, Any]

    def jobs(self, chosen: list[tuple[Extension, Screen]]) -> list[Callable[[], Calibration]]:
        """The fit on all poses of each candidate of ``chosen``, with the effects held."""
        return [functools.partial(self._full, ext) for ext, _ in chosen]

    def on_all_poses(
        self, chosen: list[tuple[Extension, Screen]], known: dict[str, Calibration]
    ) -> list[Calibration]:
        """The fit on all poses of each of ``chosen``: from ``known`` (by label), else fitted now."""
        missing = [(e, s) for e, s in chosen if e.label not in known]
        fitted = dict(zip((e.label for e, _ in missing), run_jobs(self.jobs(missing))))
        return [known[e.label] if e.label in known else fitted[e.label] for e, _ in chosen]

    def _full(self, ext: Extension) -> Calibration:
        return self.fit(*self.what, extension=self._with(ext), **self.options)

    def _with(self, ext: Extension) -> AnyEffect | None:
        """The effects held and the candidate ``ext``."""
        return combined([*self.held, ext])

    def cross_validated(
        self, fulls: list[Calibration], chosen: list[tuple[Extension, Screen]], folds: int, seed: int
    ) -> list[tuple[Extension, Screen, Calibration, CrossValidation]]:
        """Each candidate whose effects its fit on all poses ``fulls`` identifies, with its
        K-fold cross-validation (every fold of every candidate run together, each fold begun at
        its candidate's fit on all poses)."""
        n_held = sum(e.n_params for e in self.held)
        kept = [
            (ext, screen, full)
            for (ext, screen), full in zip(chosen, fulls)
            if full.identifiability.identifiable[
                full.model.n_params : full.model.n_params + ext.n_params + n_held
            ].all()
        ]
        runs = [
            FoldRuns.of(
                self.fit,
                self.what,
                folds,
                seed,
                {**self.options, "extension": self._with(ext), "start": WarmStart.of(full)},
            )
            for ext, _, full in kept
        ]
        answers = run_jobs([job for r in runs for job in r.jobs()])
        out = []
        for (ext, screen, full), r in zip(kept, runs):
            out.append((ext, screen, full, r.pooled(answers[: len(r.parts)])))
            answers = answers[len(r.parts) :]
        return out
