"""Diagnosis: what the rigid model still gets wrong, its physical cause, and the gain on new poses.

1. Baseline: the geometric model (identifiable set only), judged by K-fold cross-validation.
2. Candidates: every effect of :mod:`pincal.kinematics.effects` on every joint, each identified together
   with the geometry and judged by the same folds: first all of them on the problem linearised
   at the geometric fit (:mod:`pincal.auto.screening`, no nonlinear solve), then the
   :data:`FINALISTS` best by the nonlinear calibration and cross-validation.
3. Selection: the finalist with the lowest cross-validated RMS wins only if
   (a) it beats the baseline's cross-validated RMS by :data:`MIN_GAIN`, and
   (b) its linearised gain is one pure noise rarely reaches as the best of every candidate:
   its family-wise p-value under the null of the whole screen (:mod:`pincal.auto.screen_null`)
   is under ``α / step`` (α = 0.01, ``step`` the causes sought so far). Otherwise the answer is
   ``none``: a false cause is worse than no cause.

The fit is given (:func:`diagnose_with`): :func:`pincal.auto.diagnose.diagnose` fits with
:func:`pincal.calibrate`, and the pipeline's ``extension="auto"``, above this module, with its own.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pincal.auto.finalists import Finalists, worth_judging
from pincal.auto.screen_null import ALPHA, draws_for, p_values, screen_null
from pincal.auto.screening import Linearised
from pincal.data.dataset import Dataset
from pincal.identify.calibration import Calibration
from pincal.identify.kfold import Fit, FoldRuns
from pincal.identify.warm import WarmStart
from pincal.kinematics.effects import AnyEffect, Extension, candidates
from pincal.kinematics.gravity import Payload, massless
from pincal.kinematics.stiffness import Stiffness, compliance_stiffness, implausible
from pincal.robot.robots import Robot
from pincal.workers import limited, run_jobs

#: The winner must beat the baseline's cross-validated RMS by at least this factor.
MIN_GAIN = 1.1
#: Candidates judged by the nonlinear cross-validation after the linearised screen.
FINALISTS = 3


@dataclass(frozen=True)
class Candidate:
    """One effect on one joint, as judged.

    Attributes:
        extension: the effect.
        cv_rms_mm: cross-validated RMS [mm] (linearised for a candidate only screened).
        p_value: family-wise p-value of its linearised gain under the null of the whole screen
            (:mod:`pincal.auto.screen_null`; 1 when no null could be drawn).
        calibration: the extended fit on all poses (None for a candidate only screened).
        q: the data's commanded configurations (N, n), to read a compliance as a stiffness.
        screened_params: the effect's parameters of the linearised fit, when only screened.
    """

    extension: Extension
    cv_rms_mm: float
    p_value: float
    calibration: Calibration | None = field(repr=False)
    q: np.ndarray | None = field(default=None, repr=False, compare=False)
    screened_params: np.ndarray | None = field(default=None, repr=False, compare=False)

    @property
    def screened(self) -> bool:
        """Judged on the linearised problem only (:mod:`pincal.auto.screening`)."""
        return self.calibration is None

    @property
    def params(self) -> np.ndarray:
        """The effect's parameters (in the extension's units)."""
        if self.calibration is not None:  # the effects already held come first
            return self.calibration.effect_params[-self.extension.n_params :]
        return np.zeros(self.extension.n_params) if self.screened_params is None else self.screened_params

    def stiffness(self, q: np.ndarray | None = None) -> Stiffness | None:
        """A ``joint_compliance`` coefficient read as a stiffness over ``q`` (default: the
        candidate's own), or None for other effects or without configurations."""
        q = self.q if q is None else q
        if self.extension.effect != "joint_compliance" or q is None:
            return None
        return compliance_stiffness(self.extension, float(self.params[0]), q)

    @property
    def implausible(self) -> str | None:
        """Why its identified value cannot be the named effect (None: plausible, or no ``q``)."""
        return None if self.q is None else implausible(self.extension, self.params, self.q)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (with a ``stiffness`` for a joint compliance, given ``q``)."""
        ext = self.extension
        stiffness = self.stiffness()
        extra: dict[str, Any] = {"stiffness": stiffness.to_dict()} if stiffness is not None else {}
        extra["implausible"] = self.implausible
        return {
            "effect": ext.effect,
            "joint": ext.joint,
            "harmonic": ext.harmonic if ext.effect == "gear_harmonic" else None,
            "cv_rms_mm": self.cv_rms_mm,
            "p_value": self.p_value,
            "judged": "linearised" if self.screened else "nonlinear",
            "parameters": {
                n: {"value": float(v), "unit": u} for n, v, u in zip(ext.names, self.params, ext.units)
            },
            **extra,
        }


@dataclass(frozen=True)
class Diagnosis:
    """The answer of :func:`pincal.auto.diagnose.diagnose`.

    Attributes:
        baseline: the geometric model's fit on all poses.
        baseline_cv_rms_mm: its cross-validated RMS [mm].
        cause: the named cause, or None.
        candidates: every candidate, best first.
        folds: number of folds.
        q: the data's commanded configurations (N, n), to read a compliance as a stiffness.
        rejected: candidates that paid on held-out poses but whose identified value is
            implausible for the effect named (:func:`pincal.kinematics.stiffness.implausible`), best first.
        given: the effects the baseline already held (a cause sought after others), or None.
        step: the causes sought so far, this one included (the test's level is ``ALPHA / step``).
        null_draws: draws of noise through the screen (0: none drawn).
        baseline_by: how ``baseline_cv_rms_mm`` was cross-validated: ``nonlinear`` (refits), or
            ``linearised`` when no candidate's p-value, known before any refit, could name one.
    """

    baseline: Calibration = field(repr=False)
    baseline_cv_rms_mm: float
    cause: Candidate | None
    candidates: tuple[Candidate, ...]
    folds: int
    q: np.ndarray | None = field(default=None, repr=False, compare=False)
    rejected: tuple[Candidate, ...] = ()
    given: AnyEffect | None = field(default=None, repr=False)
    step: int = 1
    null_draws: int = 0
    baseline_by: str = "nonlinear"

    @property
    def extended(self) -> Calibration:
        """The fit on all poses with the named cause (the baseline's when there is none)."""
        named = self.cause.calibration if self.cause else None
        return self.baseline if named is None else named

    @property
    def extended_cv_rms_mm(self) -> float:
        """Cross-validated RMS of the extended model (the baseline's when there is no cause)."""
        return self.cause.cv_rms_mm if self.cause else self.baseline_cv_rms_mm

    @property
    def gain(self) -> float:
        """Baseline / extended cross-validated RMS."""
        return self.baseline_cv_rms_mm / self.extended_cv_rms_mm

    @property
    def untried(self) -> str | None:
        """What could not be tried and how to try it, or None."""
        loaded = any(c.extension.effect in ("joint_compliance", "backlash") for c in self.candidates)
        if loaded or not massless(self.baseline.model.robot):
            return None
        return "compliance and backlash not tried: the URDF has no masses (lend them with inertias=URDF)"

    def summary(self) -> str:
        """One line a person can act on."""
        untried = self.untried
        return self._named() + (f"; {untried}" if untried else "")

    def _named(self) -> str:
        """What the diagnosis names, with its gain."""
        b, a = self.baseline_cv_rms_mm, self.extended_cv_rms_mm
        if self.cause is None:
            rejected = "".join(f"; {c.extension.label} rejected: {c.implausible}" for c in self.rejected)
            if self.rejected:
                said = f"no plausible listed effect pays on held-out poses: cross-validated RMS {b:.3f} mm"
                return said + rejected
            best = (
                f"best candidate {self.candidates[0].extension.label}, not significant"
                if self.candidates
                else "no effect the data can tell from the geometry"
            )
            by = " (linearised)" if self.baseline_by == "linearised" else ""
            return f"no listed effect pays on held-out poses: cross-validated RMS {b:.3f} mm{by} ({best})"
        ext, p = self.cause.extension, self.cause.params
        unit = ext.units[0]
        if ext.effect == "joint_compliance":
            what = self._compliance(self.cause, unit)
        elif ext.effect == "gear_harmonic":
            amplitude = float(np.linalg.norm(p)) * 1e3
            what = (
                f"{ext.joint} has a transmission error at {ext.harmonic}x its angle: "
                f"amplitude {amplitude:.3g} m{unit}"
            )
        elif ext.effect == "encoder_scale":
            what = (
                f"{ext.joint} angle is scaled by {1 + p[0]:.6f} "
                f"(encoder or gear ratio off by {p[0] * 1e6:.0f} ppm)"
            )
        else:
            what = (
                f"{ext.joint} has {2 * abs(p[0]) * 1e3:.3g} m{unit} of play "
                "between the two directions of its gravity load"
            )
        return f"{what}; held-out RMS {b:.3f} → {a:.3f} mm ({b / a:.1f}x, {self.folds}-fold CV)"

    def _compliance(self, cause: Candidate, unit: str) -> str:
        """A named compliance: its coefficient and what it means as a stiffness."""
        joint, c = cause.extension.joint, float(cause.params[0])
        stiffness = cause.stiffness(self.q)
        if stiffness is None:
            return f"{joint}: error proportional to its gravity torque, c = {c:.3g} {unit}"
        if stiffness.plausible:  # "sags under gravity: K = ..."
            head, _, tail = stiffness.verdict.partition(": ")
            return f"{joint} {head}: c = {c:.3g} {unit}, {tail}"
        return f"{joint}: error proportional to its gravity torque, c = {c:.3g} {unit}; {stiffness.verdict}"

    def to_dict(self) -> dict[str, Any]:
        """The JSON of ``contracts.md``."""
        cause = self.cause.extension if self.cause else None
        return {
            "baseline": {
                "model": self.baseline.model.kind,
                "cv_rms_mm": self.baseline_cv_rms_mm,
                "by": self.baseline_by,
            },
            "cause": {
                "effect": cause.effect if cause else "none",
                "joint": cause.joint if cause else None,
                "harmonic": cause.harmonic if cause and cause.effect == "gear_harmonic" else None,
            },
            "extended": {"cv_rms_mm": self.extended_cv_rms_mm},
            "gain": self.gain,
            "summary": self.summary(),
            "folds": self.folds,
            "selection": f"lowest cross-validated RMS, if gain >= {MIN_GAIN} and its family-wise p < {ALPHA} "
            f"/ {self.step} under the null of the screen of {len(self.candidates)} candidates"
            f" ({self.null_draws} draws of noise)",
            "candidates": [c.to_dict() for c in self.candidates],
            "rejected": [
                {"effect": c.extension.effect, "joint": c.extension.joint, "why": c.implausible}
                for c in self.rejected
            ],
        }


def known_baseline(previous: Diagnosis, given: AnyEffect) -> Candidate | None:
    """The baseline of the diagnosis that seeks a cause beyond ``given``, when the ``previous``
    diagnosis (on the same poses, parameters and options) already fitted and cross-validated it:
    its named cause, if that is ``given`` (fitted ``partial``: the rank check a baseline's own
    fit makes is made by the calibration's final fit, on these parameters and every cause)."""
    cause = previous.cause
    if cause is None or cause.calibration is None or cause.calibration.extension is None:
        return None
    return cause if cause.calibration.extension.label == given.label else None


def _pool(listed: list[Extension], held: tuple[Extension, ...]) -> list[Extension]:
    """The candidates of ``listed`` on a joint no effect of ``held`` is on: one cause a joint.
    Listed effects stacked on one joint (harmonics 1 and 2, a scale) make a flexible curve of its
    angle, which absorbs effects outside the list (sin 3q on a Panda's joint 4, a cubic
    stiffness) and would call them explained (``benchmarks/verdict_audit.py``)."""
    taken = {e.joint for e in held}
    return [e for e in listed if e.joint not in taken]


@limited
def diagnose_with(
    fit: Fit,
    robot: Robot,
    data: Dataset,
    model: str = "placements",
    measure: str | None = None,
    folds: int = 5,
    seed: int = 0,
    effects: list[Extension] | None = None,
    payload: Payload | None = None,
    progress: Callable[[int, int, str], None] | None = None,
    quick: bool = False,
    given: AnyEffect | None = None,
    step: int = 1,
    baseline: Candidate | None = None,
    **options: Any,
) -> Diagnosis:
    """:func:`pincal.auto.diagnose.diagnose` (its arguments and answer) with the calibration ``fit``,
    called as ``fit(robot, data, model, measure, **options)``; with ``given``, the baseline holds
    those effects and each candidate is added to them (the ``step``-th cause sought: tested at
    level ``ALPHA / step``); ``baseline``: the baseline's fit and
    cross-validated RMS when already known (:func:`known_baseline`), not fitted again."""
    options = {k: v for k, v in options.items() if k != "extension"}
    options["deliver"] = "none"  # a cause is named by the joint fit of geometry and effect
    held = given.parts if given is not None else ()
    pool = _pool(candidates(robot, payload) if effects is None else effects, held)
    what = (robot, data, model, measure)
    base_runs = None
    if baseline is None or baseline.calibration is None:
        base = fit(robot, data, model, measure, extension=given, **options)  # first: the data may fall short
        options["start"] = WarmStart.of(base)  # the folds and the candidates begin at the baseline's fit
        base_runs = FoldRuns.of(fit, what, folds, seed, {**options, "extension": given})
        base_rms = float("nan")
    else:
        base, base_rms = baseline.calibration, baseline.cv_rms_mm
        options["start"] = WarmStart.of(base)
    lin = Linearised(base, data, folds, seed, pool)  # every candidate's columns in one pass
    total = len(pool) + min(FINALISTS, len(pool))
    baseline_screen, each = lin.screen_all(pool)
    # an effect the data cannot tell from the geometry is no candidate
    screens = [(ext, screen) for ext, screen in zip(pool, each) if screen.identifiable]
    if progress is not None:
        progress(len(pool), total, "linearised screen")
    screens.sort(key=lambda item: item[1].cv_rms_mm)
    null = screen_null(lin, [ext for ext, _ in screens], draws_for(step), seed)
    lin_rms = baseline_screen.cv_rms_mm  # the baseline's, linearised
    p_of = p_values(lin_rms, null)
    options["partial"] = True
    top = screens[: min(FINALISTS, len(screens))]
    fits = Finalists(fit, what, [*held], options)
    level = ALPHA / step
    likely = worth_judging(top, lin_rms, p_of, level) if quick else top  # started early
    can_name = not quick or any(p_of(s) < level for _, s in top) or not lin.folds_fit()  # else no refit
    base_jobs = [] if base_runs is None or not can_name else base_runs.jobs()
    full_jobs = fits.jobs(likely)  # on all poses with one more unknown: the longest, so first
    first = run_jobs([*full_jobs, *base_jobs])  # the baseline's folds beside the fits
    if base_runs is not None:
        base_rms = base_runs.pooled(first[len(full_jobs) :]).after.rms_mm if base_jobs else lin_rms
    finals = worth_judging(top, base_rms, p_of, level) if quick else top
    fulls = fits.on_all_poses(finals, dict(zip((e.label for e, _ in likely), first[: len(full_jobs)])))
    for k, (ext, _) in enumerate(finals):
        if progress is not None:
            progress(len(pool) + k + 1, total, f"{ext.label} (nonlinear)")
    judged_cv = fits.cross_validated(fulls, finals, folds, seed)
    finalists = [
        Candidate(ext, cv.after.rms_mm, p_of(screen), full, data.q) for ext, screen, full, cv in judged_cv
    ]
    finalists.sort(key=lambda c: c.cv_rms_mm)
    others = [(ext, s) for ext, s in screens if all(ext is not e for e, _ in finals)]
    screened = [Candidate(ext, s.cv_rms_mm, p_of(s), None, data.q, s.params) for ext, s in others]
    paying = [c for c in finalists if base_rms / c.cv_rms_mm >= MIN_GAIN and c.p_value < level]
    rejected = tuple(c for c in paying if c.implausible is not None)
    cause = next((c for c in paying if c.implausible is None), None)
    draws = 0 if null is None else null.draws
    judged = tuple(finalists + screened)
    by = "linearised" if base_runs is not None and not base_jobs else "nonlinear"
    return Diagnosis(base, base_rms, cause, judged, folds, data.q, rejected, given, step, draws, by)
