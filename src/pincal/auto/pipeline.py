""":func:`calibrate`: the whole identification, from data to a :class:`~pincal.Calibration`.

The steps are those of :mod:`pincal.identify.solver`; what to fit is given (``params=[...]``,
``extension="EFFECT:JOINT"``), every identifiable parameter (``params="all"``), or chosen from
the fitted poses alone (``params="auto"``, ``extension="auto"``, see :mod:`pincal.auto.choice`).
``pincal calibrate`` calls this function with ``params="auto"``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from pincal.auto.balance import balanced_fit, choose_weight
from pincal.auto.choice import ModelChoice, choose
from pincal.auto.delivery import effect_on_top, settled
from pincal.auto.fitting import Based, first_fit, fit, sample_fit
from pincal.auto.settings import CalibrateOptions
from pincal.data.dataset import Dataset
from pincal.identify import chunked
from pincal.identify.calibration import Calibration
from pincal.identify.forward_selection import select_on
from pincal.identify.guard import Protected
from pincal.identify.identifiability import Identifiability
from pincal.identify.kfold import cross_validate_with
from pincal.identify.solver import Setup, assess, identifiable_set, register, screen_outliers, set_up
from pincal.identify.warm import WarmStart
from pincal.kinematics.effects import AnyEffect, Effects, Extension
from pincal.kinematics.models import Model
from pincal.plausibility.judge import judge_calibration
from pincal.robot.robots import Robot
from pincal.workers import limited, run_jobs


def _kept_pairs(pairs: str | np.ndarray, n: int, keep: np.ndarray) -> str | np.ndarray:
    """Pose pairs among the kept poses, renumbered (named pairings are rebuilt from the poses)."""
    if isinstance(pairs, str):
        return pairs
    index = np.full(n, -1)
    index[keep] = np.arange(len(keep))
    mapped = index[np.asarray(pairs, dtype=int)]
    return mapped[(mapped >= 0).all(axis=1)]


@limited
def calibrate(
    robot: Robot,
    data: Dataset,
    model: str | Model = "placements",
    measure: str | None = None,
    *,
    test: Dataset | None = None,
    options: CalibrateOptions | None = None,
    progress: Callable[[int, int, str], None] | None = None,
    **changes: Any,
) -> Calibration:
    """Identify a kinematic model from measurements, and judge whether it can describe a real arm.

    Args:
        robot, data, test: the chain (:func:`pincal.load_robot`), fitted and held-out poses.
        model: ``placements``, ``poe``, ``mdh``, ``offsets`` or a :class:`~pincal.kinematics.models.Model`.
        measure: ``position``, ``pose``, ``distance`` or ``points`` (default: by the columns).
        options: every other choice (:class:`~pincal.auto.settings.CalibrateOptions`: the set-up,
            the fit, what to fit and how it is chosen, what is delivered).
        progress: called as ``progress(done, total, label)`` by the diagnosis and the nested
            cross-validation.
        **changes: any field of :class:`~pincal.auto.settings.CalibrateOptions` by name
            (``params="auto"``, ``extension="auto"``, ``loss="huber"``...), replacing it.

    Returns:
        The calibration, its ``plausibility`` the verdict of
        :func:`pincal.plausibility.judge.judge_calibration` (``pincal calibrate`` refuses an
        implausible one, and so do the writers unless ``accept_implausible=True``).

    Raises:
        DataError, IdentifiabilityError: unusable input (names, data), too little information.
    """
    asked = CalibrateOptions.of(options, changes)
    cal = _calibrated(robot, data, (model, measure), asked, test, progress)
    return replace(cal, plausibility=judge_calibration(cal, data, loss=asked.loss))


@limited
def calibrate_unjudged(robot: Robot, data: Dataset, *what: Any, **options: Any) -> Calibration:
    """:func:`calibrate` without its plausibility verdict, called as it is (``model``, ``measure``,
    then keywords): what the calls inside a calibration (the diagnosis' and the
    cross-validations' folds) fit with."""
    test, progress = options.pop("test", None), options.pop("progress", None)
    model = options.pop("model", what[0] if what else "placements")
    measure = options.pop("measure", what[1] if len(what) > 1 else None)
    asked = CalibrateOptions.of(options.pop("options", None), options)
    return _calibrated(robot, data, (model, measure), asked, test, progress)


def _calibrated(
    robot: Robot,
    data: Dataset,
    what: tuple[str | Model, str | None],
    asked: CalibrateOptions,
    test: Dataset | None,
    progress: Callable[[int, int, str], None] | None,
) -> Calibration:
    """The calibration ``asked`` of ``what`` (model and measure) on ``data``, unjudged."""
    wanted, ext = asked.wanted(), asked.effect(robot)
    setup, choice, wanted, chosen, opts = _chosen(robot, data, what, wanted, ext, asked, progress)
    kwargs = {**chosen, **opts.fitting(), "start": opts.start}
    urdf = _urdf_alone(setup, choice, opts)
    sample = sample_fit(setup, wanted, kwargs) if opts.outliers else None  # large data: screened first
    found: Based | Protected | None = None
    if sample is None:
        found, alone = _fits(setup, wanted, kwargs, urdf)
        if isinstance(found, Based) and found.screening is None:  # screened at the chosen pull
            found = found.protected()
        screening, free, base = found.screening, found.free, found.base
    else:
        screening, free, base = (setup, sample.base), sample.free, sample.base
    assert screening is not None
    bad, scores = _screened(setup, choice, screening, free, wanted, opts)
    if bad.size:  # leave them out and start again: the choice too is made on the poses kept
        start = asked.start or WarmStart.at(setup.problem, base)  # nearly the same poses
        chunked.release(setup.problem)
        return _without(robot, data, what, bad, scores, replace(asked, start=start), test, progress)
    if found is None:  # every pose's fit begins at the subset's (the same minimum, in fewer steps)
        kwargs["start"] = opts.start or WarmStart.at(setup.problem, base)
        found, alone = _fits(setup, wanted, kwargs, urdf)
    if isinstance(found, Based):
        found = found.protected()
    if asked.nested is not False:
        judge = _judge(robot, data, what, asked, progress)
        choice = choice.with_nested(judge, asked.nested is True, len(data))
    return _delivered(found, setup, choice, wanted, test, opts, alone)


#: The complete delivery's URDF fit: to run (:func:`_urdf_alone`), and run, with its choice.
UrdfJob = tuple[Callable[[], Protected], ModelChoice]
Alone = tuple[Protected, ModelChoice]


def _fits(
    setup: Setup, wanted: Any, kwargs: dict[str, Any], urdf: UrdfJob | None
) -> tuple[Based | Protected, Alone | None]:
    """The fit of ``setup`` (before its pull is chosen, when it runs alone: the outliers are
    screened first when they can be) and the complete delivery's URDF fit and choice, run beside it."""
    if urdf is None:
        return first_fit(setup, wanted, **kwargs), None
    found, fitted = run_jobs([functools.partial(fit, setup, wanted, **kwargs), urdf[0]])
    return found, (fitted, urdf[1])


def _urdf_alone(setup: Setup, choice: ModelChoice, opts: CalibrateOptions) -> UrdfJob | None:
    """The fit of the geometry alone that a complete delivery writes as the URDF (run beside the
    full model's fit) and the choice it records, or None when the delivery has no such fit."""
    if setup.problem.extension is None or opts.deliver != "complete":
        return None
    geometry, geometric = _geometry(setup, choice, opts)
    return functools.partial(fit, geometry, geometric.params, **opts.fitting()), geometric


def _geometry(setup: Setup, choice: ModelChoice, opts: CalibrateOptions) -> tuple[Setup, ModelChoice]:
    """The set-up of ``setup``'s geometry without its effects, and the choice of its parameters
    (:func:`_geometric_choice`)."""
    problem = setup.problem
    kind = problem.measurement.kind
    geometry = set_up(problem.model.robot, setup.data, problem.model, kind, **opts.setup())
    return geometry, _geometric_choice(geometry, choice)


def _chosen(
    robot: Robot,
    data: Dataset,
    what: tuple[str | Model, str | None],
    wanted: Any,
    ext: AnyEffect | str | None,
    opts: CalibrateOptions,
    progress: Callable[[int, int, str], None] | None,
) -> tuple[Setup, ModelChoice, Any, dict[str, Any], CalibrateOptions]:
    """The set-up to fit (``what``: model and measure), what was chosen (:mod:`pincal.auto.choice`),
    the parameters to fit, what the fit may reuse (``nominal``, ``every``) and the options it fits
    with (``partial`` set as the choice allows)."""
    (model, measure), given = what, ext if isinstance(ext, (Extension, Effects)) else None
    setup = set_up(robot, data, model, measure, extension=given, **opts.setup())
    nominal, every = _checked(setup, wanted, opts)  # for "auto": refuse what "all" refuses
    start = nominal if given is None else None
    choice = choose(setup, wanted, ext, fit=calibrate_unjudged, options=opts, progress=progress, start=start)
    if wanted == "auto" or ext == "auto":
        checked = wanted == "auto"  # every parameter passed the rank check: so does any subset
        if choice.extension is not None and given is None:
            setup = set_up(robot, data, model, measure, extension=choice.extension, **opts.setup())
            nominal, checked, every = None, False, None
        opts, wanted = replace(opts, partial=opts.partial or checked), choice.params
        if choice.selection is not None:  # the guard's null repeats the selection
            opts = replace(opts, pull=replace(opts.pull, selected=True))
    last = choice.last_diagnosis
    if opts.start is None and last is not None:  # the diagnosis fitted the chosen model
        opts = replace(opts, start=WarmStart.of(last.extended))
    return setup, choice, wanted, {"nominal": nominal, "every": every}, opts


def _delivered(
    found: Protected,
    setup: Setup,
    choice: ModelChoice,
    wanted: Any,
    test: Dataset | None,
    opts: CalibrateOptions,
    alone: Alone | None = None,
) -> Calibration:
    """The fit ``found`` of ``setup`` (on the parameters ``wanted``) as ``opts.deliver`` asks (see
    :class:`~pincal.auto.settings.CalibrateOptions`); ``alone``: the complete delivery's fit of
    the geometry alone and its choice (:func:`_urdf_alone`)."""
    if setup.problem.extension is None or opts.deliver == "none":
        return replace(found.assessed(test), choice=choice)
    if opts.deliver == "joint":
        return settled(replace(found.assessed(test), choice=choice), setup.data, test)
    if opts.deliver == "complete":  # the URDF: the geometry alone; the sidecar: the full model
        assert alone is not None, "the complete delivery's URDF is fitted beside the full model"
        fitted, geometric = alone
        full = settled(replace(found.assessed(test), choice=choice), setup.data, test)
        return replace(full, urdf_fit=replace(fitted.assessed(test), choice=geometric))
    geometry, geometric = _geometry(setup, choice, opts)
    kept = geometric.params
    joint = found if kept == wanted else fit(setup, kept, **opts.fitting())  # the same parameters: reused
    return _balanced(setup, geometry, kept, joint, geometric, test, opts)


def _balanced(
    setup: Setup,
    geometry: Setup,
    kept: tuple[str, ...] | None,
    joint: Protected,
    choice: ModelChoice,
    test: Dataset | None,
    opts: CalibrateOptions,
) -> Calibration:
    """Geometry and effect weighted so that the URDF alone stays the best URDF
    (:mod:`pincal.auto.balance`), from their joint fit ``joint`` on the parameters chosen for the
    geometry alone (``kept``): at the weight's limit the URDF is the geometric fit, and the
    effect is fitted on top of it."""
    data, folds, seed = setup.data, choice.folds, choice.seed
    if not joint.guard.kept_fit:  # the nominal geometry is exported: no effect to balance
        return replace(joint.assessed(test), choice=choice)
    theta, ident = joint.theta, joint.identifiability
    balance = choose_weight(setup, theta, ident.identifiable, folds, seed)
    if np.isfinite(balance.weight):
        theta = balanced_fit(joint.setup, theta, ident.identifiable, balance.weight)
        cal = assess(joint.setup, theta, joint.nominal, ident, joint.result, test)
        cal = replace(cal, choice=choice, prior=joint.prior, guard=joint.guard)
        return replace(settled(cal, data, test), balance=balance)
    alone = replace(fit(geometry, kept, **opts.fitting()).assessed(test), choice=choice)
    assert setup.problem.extension is not None
    return replace(effect_on_top(alone, setup.problem.extension, data, test), balance=balance)


def _screened(
    setup: Setup,
    choice: ModelChoice,
    screening: tuple[Setup, np.ndarray],
    free: np.ndarray,
    wanted: Any,
    opts: CalibrateOptions,
) -> tuple[np.ndarray, np.ndarray]:
    """The outlier poses of the fit ``screening`` (its problem and θ, the unknowns ``free``), and
    every pose's score [m] (:func:`pincal.identify.solver.screen_outliers`)."""
    bad, scores = screen_outliers(*screening, free, opts.outliers or 0.0, opts.f_scale)
    if bad.size and choice.diagnosis is not None and choice.diagnosis.candidates:
        bad = _outliers_for_both(setup, choice, bad, wanted, opts)
    return bad, scores


def _outliers_for_both(
    setup: Setup, choice: ModelChoice, bad: np.ndarray, wanted: Any, opts: CalibrateOptions
) -> np.ndarray:
    """Of the poses ``bad`` the fit flags, those the diagnosis' best candidate cannot explain
    either: a pose that is an outlier only for the rigid model may carry a real effect (backlash,
    a nonlinear stiffness), and is kept."""
    assert choice.diagnosis is not None
    best = choice.diagnosis.candidates[0].extension
    if setup.problem.extension is not None and best.label == setup.problem.extension.label:
        return bad
    problem = setup.problem
    robot, kind = problem.model.robot, problem.measurement.kind
    other = set_up(robot, problem.data, problem.model, kind, extension=best, **opts.setup())
    params = choice.params if wanted == "auto" else wanted
    found = first_fit(other, params, **{**opts.fitting(), "partial": True})
    again, _ = screen_outliers(*found.screened_on(), found.free, opts.outliers or 0.0, opts.f_scale)
    return np.intersect1d(bad, again)


def _geometric_choice(geometry: Setup, choice: ModelChoice) -> ModelChoice:
    """The choice with the parameters of the geometry alone, which the balanced delivery fits
    and the report names: those chosen without a cause (the first round of ``extension="auto"``;
    chosen again for ``params="auto"`` with a given extension); given ones as given."""
    if choice.params_mode != "auto":
        return choice
    if choice.rounds:
        return replace(choice, params=choice.rounds[0].params, selection=choice.geometry_selection)
    sel = select_on(geometry)
    return replace(choice, params=sel.params, selection=sel)


def _without(
    robot: Robot,
    data: Dataset,
    what: tuple[str | Model, str | None],
    bad: np.ndarray,
    scores: np.ndarray,
    asked: CalibrateOptions,
    test: Dataset | None,
    progress: Callable[[int, int, str], None] | None,
) -> Calibration:
    """The call ``asked`` again without the poses ``bad`` (scores [m]), which it records."""
    keep = np.setdiff1d(np.arange(len(data)), bad)
    again = replace(asked, pairs=_kept_pairs(asked.pairs, len(data), keep), outliers=None)
    cal = _calibrated(robot, data.subset(keep), what, again, test, progress)
    rows = data.row_numbers[bad]
    return replace(cal, excluded=tuple((int(r), float(s) * 1e3) for r, s in zip(rows, scores[bad])))


def _judge(
    robot: Robot,
    data: Dataset,
    what: tuple[str | Model, str | None],
    asked: CalibrateOptions,
    progress: Callable[[int, int, str], None] | None,
) -> Callable[[], Any]:
    """The nested cross-validation of the whole call ``asked``, re-run without each fold (each
    inner call with the default folds and seed, and no nested cross-validation of its own)."""
    pairs = asked.pairs if isinstance(asked.pairs, str) else "all"
    deliver = "joint" if asked.deliver == "complete" else asked.deliver  # the full model: the same fit
    inner = replace(asked, pairs=pairs, nested=False, deliver=deliver).keywords()
    del inner["folds"], inner["seed"]  # the folds of the whole call; inside it, the defaults
    model, measure = what
    return lambda: cross_validate_with(
        calibrate_unjudged, robot, data, model, measure, asked.folds, asked.seed, progress=progress, **inner
    )


def _checked(
    setup: Setup, wanted: tuple[str, ...] | str | None, opts: CalibrateOptions
) -> tuple[np.ndarray | None, Identifiability | None]:
    """For ``params="auto"``, refuse data that ``params="all"`` refuses (unless ``partial``) and
    return the registration-only θ and the identifiable set of every parameter it found."""
    if wanted != "auto" or opts.partial:
        return None, None
    nominal = register(setup)
    return nominal, identifiable_set(setup, nominal, None, False, opts.rcond)
