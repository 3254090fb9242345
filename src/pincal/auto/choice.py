"""What to fit, chosen from the fitted poses alone: ``params="auto"`` and ``extension="auto"``.

- **Parameters** (``params="auto"``): the forward-selection path of :mod:`pincal.auto.selection`,
  scored by linearised leave-one-out cross-validation: every identifiable parameter when fitting
  them all scores within 5 % of the path's lowest, else the shortest prefix within 1 % of it.
- **Cause** (``extension="auto"``): :func:`pincal.auto.diagnose.diagnose` on the chosen geometry,
  its own test deciding (lowest K-fold cross-validated RMS, a gain of at least 1.1 and a
  family-wise p-value under the null of the whole screen). A named cause changes which geometric
  parameters pay, so the parameters are chosen again with the cause fitted at every step and the
  diagnosis re-run on them, until it names the cause it named before (at most :data:`MAX_ROUNDS`
  rounds). Each round is a test of its own: round ``r`` names a cause at the family-wise level
  ``ALPHA / r`` (Bonferroni over the rounds). Of the rounds that named a cause, the one whose
  extended model has the lowest cross-validated RMS is kept (all are judged on the same folds).
  On Gao et al.'s arm the first round names joint 2, the second joint 3, which the third confirms
  (the full geometry names joint 3 at once).
- **Nested cross-validation** of the whole procedure (the choice re-run without each fold):
  the choice's own scores are biased low by the choosing; this estimate is not. It costs K
  choices and fits, so it runs by default only when cheap (:func:`nested_policy`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from pincal.auto.diagnosis import Diagnosis, diagnose_with, known_baseline
from pincal.auto.screen_null import ALPHA
from pincal.auto.settings import CalibrateOptions
from pincal.errors import IdentifiabilityError
from pincal.identify.calibration import Calibration
from pincal.identify.forward_selection import Selection, select_on
from pincal.identify.kfold import CrossValidation, Fit
from pincal.identify.solver import Setup, set_up
from pincal.kinematics.effects import AnyEffect, Effects

#: Rounds of selection and diagnosis for ``extension="auto"``.
MAX_ROUNDS = 3
#: Causes ``extension="auto"`` names at most, each added only where it pays on held-out poses,
#: and each on a joint of its own (:func:`pincal.auto.diagnosis.diagnose_with`).
MAX_CAUSES = 3
#: Nested cross-validation runs by default up to this many poses (it costs K selections and fits).
NESTED_MAX_POSES = 60


@dataclass(frozen=True)
class Round:
    """One round of ``extension="auto"``: the diagnosis on a geometric set.

    Attributes:
        params: the geometric parameters of the baseline (None: every identifiable one).
        with_cause: the cause fitted while those parameters were chosen (None in the first round).
        cause: the cause the diagnosis named (``EFFECT:JOINT``), or None.
        baseline_cv_rms_mm: the baseline's K-fold cross-validated RMS [mm].
        extended_cv_rms_mm: the extended model's (the baseline's when nothing is named) [mm].
        level: the family-wise level its diagnosis named a cause at (``ALPHA / r`` in round r; a
            round on the parameters of an earlier one repeats that round's test).
    """

    params: tuple[str, ...] | None
    with_cause: str | None
    cause: str | None
    baseline_cv_rms_mm: float
    extended_cv_rms_mm: float
    level: float = ALPHA

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return {
            "n_params": None if self.params is None else len(self.params),
            "params": None if self.params is None else list(self.params),
            "chosen_with": self.with_cause,
            "cause": self.cause or "none",
            "baseline_cv_rms_mm": self.baseline_cv_rms_mm,
            "extended_cv_rms_mm": self.extended_cv_rms_mm,
            "level": self.level,
        }


@dataclass(frozen=True, eq=False)
class ModelChoice:
    """What was chosen and why.

    Attributes:
        params_mode: ``auto``, ``all`` or ``given``.
        params: the chosen model parameters (None: every identifiable one).
        selection: the selection path that chose them (``params="auto"``), else None.
        extension_mode: ``auto``, ``given`` or ``none``.
        extension: the cause included, or None.
        diagnosis: the diagnosis of the round kept (``extension="auto"``), else None.
        rounds: every round of ``extension="auto"``.
        folds: K of the diagnosis' and the nested cross-validation.
        seed: the seed of their folds.
        nested: the nested cross-validation of the whole procedure, if it ran.
        nested_note: why it did not run, or how it ran.
        skipped: why ``extension="auto"``'s diagnosis did not run (too few poses for its folds).
        geometry_selection: the first round's selection, the geometry alone's (``extension="auto"``
            with ``params="auto"``): the parameters the URDF alone holds.
        more: the diagnoses that named each further cause (the second, the third), in order;
            :attr:`extension` then holds every cause.
    """

    params_mode: str
    params: tuple[str, ...] | None
    selection: Selection | None
    extension_mode: str
    extension: AnyEffect | None
    diagnosis: Diagnosis | None = field(default=None, repr=False)
    rounds: tuple[Round, ...] = ()
    folds: int = 5
    seed: int = 0
    nested: CrossValidation | None = field(default=None, repr=False)
    nested_note: str = "not asked for"
    skipped: str | None = None
    geometry_selection: Selection | None = field(default=None, repr=False)
    more: tuple[Diagnosis, ...] = field(default=(), repr=False)

    def with_nested(self, judge: Callable[[], CrossValidation], forced: bool, n_poses: int) -> ModelChoice:
        """This choice with the nested cross-validation ``judge()`` run (always when ``forced``,
        else by :func:`nested_policy`), or the reason it was not."""
        reason = None if forced else nested_policy(self, n_poses)
        if reason is not None:
            return replace(self, nested_note=reason)
        cv = judge()
        note = f"{cv.folds}-fold, the whole call re-run without each fold"
        return replace(self, nested=cv, nested_note=note)

    @property
    def left_out(self) -> tuple[str, ...]:
        """Candidate parameters of the path that were not chosen."""
        if self.selection is None or self.params is None:
            return ()
        return tuple(str(s.added) for s in self.selection.path[1:] if s.added not in self.params)

    @property
    def last_diagnosis(self) -> Diagnosis | None:
        """The diagnosis of the last cause sought (the first's when no further one was named):
        its extended fit and cross-validation hold every cause named."""
        return self.more[-1] if self.more else self.diagnosis

    @property
    def gain(self) -> float:
        """Cross-validated RMS of the geometric baseline / with every cause (1 without one)."""
        last = self.last_diagnosis
        if self.diagnosis is None or last is None or self.extension is None:
            return 1.0
        return self.diagnosis.baseline_cv_rms_mm / last.extended_cv_rms_mm

    def steps(self) -> list[tuple[str, float, float]]:
        """Each named cause with the cross-validated RMS [mm] before and after it was added."""
        if self.diagnosis is None or self.diagnosis.cause is None:
            return []
        return [
            (d.cause.extension.label, d.baseline_cv_rms_mm, d.extended_cv_rms_mm)
            for d in (self.diagnosis, *self.more)
            if d.cause is not None
        ]

    def causes(self) -> list[dict[str, Any]]:
        """Each named cause with its cross-validated RMS [mm] before and after it, JSON-ready."""
        return [
            {"cause": label, "cv_rms_mm_before": before, "cv_rms_mm_after": after}
            for label, before, after in self.steps()
        ]

    def to_dict(self) -> dict[str, Any]:
        """The report's ``choice`` object."""
        sel, diag, cv = self.selection, self.diagnosis, self.nested
        return {
            "params": self.params_mode,
            "kept": None if self.params is None else list(self.params),
            "left_out": list(self.left_out),
            "keeps_all": self.params is None,
            "selection": None if sel is None else sel.to_dict(),
            "cv_rms_mm": None
            if sel is None
            else {"chosen": sel.cv_rms_mm, "all": sel.all_cv_rms_mm, "by": "leave-one-out, linearised"},
            "extension": self.extension_mode,
            "cause": self.extension.label if self.extension else "none",
            "cause_gain": self.gain,
            "causes": self.causes(),
            "diagnosis": None if diag is None else diag.to_dict(),
            "rounds": [r.to_dict() for r in self.rounds],
            "nested": None
            if cv is None
            else {"folds": cv.folds, "before": cv.before.to_dict(), "after": cv.after.to_dict()},
            "nested_note": self.nested_note,
            "diagnosis_skipped": self.skipped,
        }


def choice_of(cal: Calibration) -> ModelChoice | None:
    """The choice a calibration records, with its type (:mod:`pincal.identify.records` says why the
    calibration types it by a protocol)."""
    choice = cal.choice
    if choice is not None and not isinstance(choice, ModelChoice):
        raise TypeError(f"a calibration's choice is a ModelChoice, not {type(choice).__name__}")
    return choice


def nested_policy(choice: ModelChoice, n_poses: int) -> str | None:
    """Why a nested cross-validation is skipped by default (None: run it)."""
    if choice.extension_mode == "auto" and choice.extension is not None:
        return "skipped: with a cause named it would re-run the diagnosis on every fold (pass nested=True)"
    if choice.params_mode != "auto":
        return "skipped: nothing was chosen"
    if n_poses < 2 * choice.folds:
        return f"skipped: fewer than {2 * choice.folds} poses for {choice.folds} folds"
    if n_poses > NESTED_MAX_POSES:
        return f"skipped: more than {NESTED_MAX_POSES} poses (pass nested=True to run it)"
    return None


Params = tuple[str, ...] | None


def _select(
    setup: Setup, wanted: tuple[str, ...] | str | None, start: np.ndarray | None = None
) -> tuple[Params, Selection | None]:
    if wanted != "auto":
        return wanted if isinstance(wanted, tuple) else None, None
    sel = select_on(setup, start=start)
    return sel.params, sel


def choose(
    setup: Setup,
    wanted: tuple[str, ...] | str | None,
    extension: AnyEffect | str | None,
    *,
    fit: Fit,
    options: CalibrateOptions,
    progress: Callable[[int, int, str], None] | None = None,
    start: np.ndarray | None = None,
) -> ModelChoice:
    """Choose the parameters (``wanted="auto"``) and the cause (``extension="auto"``).

    Args:
        setup: the problem on the poses to fit (with the extension when one is given).
        wanted: ``"auto"``, None (every parameter) or the names.
        extension: ``"auto"``, an :class:`Extension` or None.
        fit: the calibration the diagnosis fits with (:func:`pincal.calibrate`).
        options: the call's options: its set-up and fit, and the diagnosis' folds, seed and
            payload (the load on the tip, for the gravity torques of the candidates).
        progress: called as ``progress(done, total, label)`` by the diagnosis.
        start: the fit of the registration, tool and extension alone, if already known.
    """
    folds, seed = options.folds, options.seed
    params, sel = _select(setup, wanted, start)
    mode = "auto" if wanted == "auto" else "all" if wanted is None else "given"
    ext_mode = "auto" if extension == "auto" else "none" if extension is None else "given"
    base = ModelChoice(mode, params, sel, ext_mode, setup.problem.extension, folds=folds, seed=seed)
    if extension != "auto":
        return base
    robot, data, model = setup.model.robot, setup.data, setup.model
    measure = setup.problem.measurement.kind
    rounds: list[Round] = []
    kept: tuple[float, ModelChoice] | None = None
    cause: AnyEffect | None = None
    done: dict[Params, Diagnosis] = {}  # a round on the parameters of an earlier one repeats it
    for _ in range(MAX_ROUNDS):
        try:
            step = len(rounds) + 1  # round r tested at ALPHA / r: a later round is a test of its own
            diag = (
                done[params]
                if params in done
                else _diagnosis(setup, fit, options, progress, params, step=step)
            )
        except IdentifiabilityError as exc:  # a fold too small to fit: the geometry alone, said so
            if rounds:
                break
            return replace(base, skipped=f"too few poses for the diagnosis' {folds} folds ({exc})")
        done[params] = diag
        named = diag.cause.extension if diag.cause else None
        label = named.label if named else None
        with_cause = cause.label if cause else None
        cv = (diag.baseline_cv_rms_mm, diag.extended_cv_rms_mm)
        rounds.append(Round(params, with_cause, label, *cv, level=ALPHA / diag.step))
        if named is not None and (kept is None or diag.extended_cv_rms_mm < kept[0]):
            kept_choice = replace(base, params=params, selection=sel, extension=named, diagnosis=diag)
            kept = (diag.extended_cv_rms_mm, kept_choice)
        if named is None or wanted != "auto" or (cause is not None and label == cause.label):
            break
        cause = named
        params, sel = _select(set_up(robot, data, model, measure, extension=cause, **options.setup()), wanted)
    first = base.selection
    if kept is None:
        return replace(base, diagnosis=diag, rounds=tuple(rounds), geometry_selection=first)
    chosen = replace(kept[1], rounds=tuple(rounds), geometry_selection=first)
    return _more_causes(chosen, setup, fit, options, progress)


def _diagnosis(
    setup: Setup,
    fit: Fit,
    options: CalibrateOptions,
    progress: Callable[[int, int, str], None] | None,
    params: Params,
    **further: Any,
) -> Diagnosis:
    """The quick diagnosis of ``extension="auto"`` on ``setup``'s poses and the parameters
    ``params`` (``further``: the causes already held and the step, for a further cause)."""
    return diagnose_with(
        fit,
        setup.model.robot,
        setup.data,
        setup.model,  # type: ignore[arg-type]
        setup.problem.measurement.kind,
        options.folds,
        options.seed,
        payload=options.payload,
        progress=progress,
        quick=True,
        params=None if params is None else list(params),
        **further,
        **options.setup(),
        **options.fitting(),
    )


def _more_causes(
    choice: ModelChoice,
    setup: Setup,
    fit: Fit,
    options: CalibrateOptions,
    progress: Callable[[int, int, str], None] | None,
) -> ModelChoice:
    """``choice`` with the further causes that pay, each sought by a diagnosis whose baseline
    holds the causes named before it (on the parameters chosen with the first), at most
    :data:`MAX_CAUSES` in all, and the k-th tested at level ``ALPHA / k``."""
    assert choice.extension is not None and choice.diagnosis is not None
    effects, steps, previous = choice.extension, [], choice.diagnosis
    for step in range(2, MAX_CAUSES + 1):
        known = known_baseline(previous, effects)  # the previous step's cause: fitted and judged
        try:
            diag = _diagnosis(
                setup, fit, options, progress, choice.params, given=effects, step=step, baseline=known
            )
        except IdentifiabilityError:  # the folds cannot fit one more effect
            break
        if diag.cause is None:
            break
        effects = Effects((*effects.parts, diag.cause.extension))
        steps.append(diag)
        previous = diag
    return replace(choice, extension=effects, more=tuple(steps))
