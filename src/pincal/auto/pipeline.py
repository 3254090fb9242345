""":func:`calibrate`: the whole identification, from data to a :class:`~pincal.Calibration`.

The steps are those of :mod:`pincal.identify.solver`; what to fit is given (``params=[...]``,
``extension="EFFECT:JOINT"``), every identifiable parameter (``params="all"``), or chosen from
the fitted poses alone (``params="auto"``, ``extension="auto"``, see :mod:`pincal.auto.choice`).
``pincal calibrate`` calls this function with ``params="auto"``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
import pinocchio as pin

from pincal.auto.balance import balanced_fit, choose_weight
from pincal.auto.choice import ModelChoice, choose
from pincal.auto.delivery import effect_on_top, settled
from pincal.data.dataset import Dataset
from pincal.errors import DataError
from pincal.identify.calibration import Calibration
from pincal.identify.fixed_points import PointDistance
from pincal.identify.forward_selection import select_on
from pincal.identify.guard import DEFAULT_PULL, Protected, Pull, protect
from pincal.identify.identifiability import RCOND, Identifiability
from pincal.identify.kfold import cross_validate_with
from pincal.identify.measurements import ROTATION_WEIGHT
from pincal.identify.solver import Setup, assess, identifiable_set, register, screen_outliers, set_up, solve
from pincal.kinematics.effects import Extension, Payload
from pincal.kinematics.models import Model
from pincal.options import LOSSES
from pincal.robot.robots import Robot
from pincal.threads import limited

#: How geometry and an effect share the fit (see :func:`calibrate`'s ``deliver``).
DELIVERIES = ("balanced", "joint", "none")


def fit(
    setup: Setup,
    params: Sequence[str] | None,
    *,
    partial: bool = False,
    loss: str = "linear",
    f_scale: float = 1e-4,
    rcond: float = RCOND,
    nominal: np.ndarray | None = None,
    every: Identifiability | None = None,
    pull: Pull = DEFAULT_PULL,
) -> Protected:
    """Register (unless the registration-only θ ``nominal`` is given), find the identifiable set
    (``every``, when given, is the one of every parameter at ``nominal``: used for ``params``
    None), choose the pull toward the URDF and solve, and judge the fit against the nominal model
    (:func:`pincal.identify.guard.protect`)."""
    nominal = register(setup) if nominal is None else nominal
    known = every if params is None else None
    ident = identifiable_set(setup, nominal, params, partial, rcond) if known is None else known
    base, _ = solve(setup, nominal, ident.identifiable, loss, f_scale)  # at the default pull
    return protect(setup, nominal, ident, base, pull, loss, f_scale)


def parse_params(params: Sequence[str] | str | None) -> tuple[str, ...] | str | None:
    """``None`` or ``"all"`` (every identifiable parameter) -> None; ``"auto"``; or the names."""
    if params is None or (isinstance(params, str) and params == "all"):
        return None
    if isinstance(params, str):
        if params != "auto":
            raise DataError(f"params={params!r}: use 'auto', 'all' or a list of parameter names")
        return "auto"
    return tuple(params)


def parse_extension(
    robot: Robot, extension: Extension | str | None, payload: Payload | None
) -> Extension | str | None:
    """``None``/``"none"`` -> None; ``"auto"``; ``EFFECT:JOINT`` -> its :class:`Extension`."""
    if extension is None or extension == "none":
        return None
    if not isinstance(extension, str) or extension == "auto":
        return extension
    if ":" not in extension:
        raise DataError(
            f"--extend {extension!r}: write auto, none or EFFECT:JOINT (for example joint_compliance:J)"
        )
    return Extension.parse(robot, extension, payload)


def _check_choices(**given: tuple[str, tuple[str, ...]]) -> None:
    """Refuse an argument whose value is not one of its choices (``name=(value, choices)``)."""
    for name, (value, choices) in given.items():
        if value not in choices:
            raise DataError(f"unknown {name} {value!r}: choose one of {', '.join(choices)}")


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
    instrument_T_base: pin.SE3 | None = None,
    tool: pin.SE3 | np.ndarray | None = None,
    rotation_weight: float = ROTATION_WEIGHT,
    pairs: str | np.ndarray = "all",
    point_distances: tuple[PointDistance, ...] = (),
    loss: str = "linear",
    f_scale: float = 1e-4,
    rcond: float = RCOND,
    extension: Extension | str | None = None,
    params: Sequence[str] | str | None = None,
    outliers: float | None = None,
    partial: bool = False,
    payload: Payload | None = None,
    folds: int = 5,
    seed: int = 0,
    nested: bool | None = False,
    progress: Callable[[int, int, str], None] | None = None,
    deliver: str = "balanced",
    pull: Pull = DEFAULT_PULL,
) -> Calibration:
    """Identify a kinematic model from measurements.

    Args:
        robot, data, test: the chain (:func:`pincal.load_robot`), fitted and held-out poses.
        model: ``placements``, ``poe``, ``mdh``, ``offsets`` or a :class:`~pincal.kinematics.models.Model`.
        measure: ``position``, ``pose``, ``distance`` or ``points`` (default: by the columns).
        instrument_T_base, tool: the known registration, and measured point on the tip (3,) [m]
            or target frame (default: unknown, estimated).
        rotation_weight: weight of orientation residuals [m/rad] for pose data; pairs: pose
            pairs for distance data (``all``, ``gao`` (eq. 21) or an (m, 2) array);
            point_distances: known distances between fixed points, ((A, B, D [m]), ...).
        loss, f_scale, rcond: a loss and where it down-weights [m]; the rank's threshold.
        extension: an effect (:class:`~pincal.kinematics.effects.Extension` or ``EFFECT:JOINT``);
            ``"auto"``: the cause the diagnosis names (:mod:`pincal.auto.choice`); None: none.
        params: None or ``"all"`` (every identifiable one), ``"auto"`` (chosen by cross-validation
            on ``data``) or names; the others stay nominal (registration, tool always fitted).
        outliers, partial: leave out poses this many robust σ above the others
            (:mod:`pincal.identify.outliers`); fit what the data identifies when varied poses
            would identify more.
        payload, progress: a tip load, for gravity torques; ``progress(done, total, label)``.
        folds, seed: K and seed of the cross-validation of ``extension="auto"`` and ``nested``.
        nested: judge the whole call by K-fold cross-validation: True, False or None (when cheap).
        deliver: with an extension, ``balanced`` (the URDF alone stays the best URDF, the effect
            completes it: :mod:`pincal.auto.balance`), ``joint`` (fitted together) or ``none`` (joint,
            gravity on the nominal URDF: the diagnosis' inner fits).
        pull: the pull toward the URDF, and when the fit is exported (:class:`~pincal.identify.guard.Pull`).

    Raises:
        DataError, IdentifiabilityError: unusable input (names, data), too little information.
    """
    _check_choices(loss=(loss, LOSSES), deliver=(deliver, DELIVERIES))
    wanted, ext = parse_params(params), parse_extension(robot, extension, payload)
    options: dict[str, Any] = dict(instrument_T_base=instrument_T_base, tool=tool, pairs=pairs)
    options.update(rotation_weight=rotation_weight, point_distances=tuple(point_distances))
    fit_options: dict[str, Any] = dict(partial=partial, loss=loss, f_scale=f_scale, rcond=rcond)
    call = dict(options, **fit_options, params=params, extension=extension, payload=payload, deliver=deliver)
    call["pull"] = fit_options["pull"] = pull
    choosing = dict(fit=calibrate, folds=folds, seed=seed, payload=payload, progress=progress)
    setup, choice, wanted, chosen = _chosen(
        robot, data, model, measure, wanted, ext, options, fit_options, choosing
    )
    found = fit(setup, wanted, **chosen, **fit_options)
    bad, scores = screen_outliers(*found.screening, found.free, outliers or 0.0, f_scale)
    if bad.size and choice.diagnosis is not None and choice.diagnosis.candidates:
        screen = {**fit_options, "threshold": outliers or 0.0}
        bad = _outliers_for_both(setup, choice, bad, wanted, options, screen)
    if bad.size:  # leave them out and start again: the choice too is made on the poses kept
        rest = dict(test=test, folds=folds, seed=seed, nested=nested, progress=progress)
        return _without(robot, data, model, measure, bad, scores, {**call, **rest})
    if nested is not False:
        judge = _judge(robot, data, model, measure, (folds, seed, progress), {**call, "outliers": outliers})
        choice = choice.with_nested(judge, nested is True, len(data))
    return _delivered(found, setup, choice, deliver, wanted, test, options, fit_options)


def _chosen(
    robot: Robot,
    data: Dataset,
    model: str | Model,
    measure: str | None,
    wanted: Any,
    ext: Extension | str | None,
    options: dict[str, Any],
    fit_options: dict[str, Any],
    choosing: dict[str, Any],
) -> tuple[Setup, ModelChoice, Any, dict[str, Any]]:
    """The set-up to fit, what was chosen (:mod:`pincal.auto.choice`), the parameters to fit and what
    the fit may reuse (``nominal``, ``every``); ``fit_options["partial"]`` set as the choice allows."""
    given = ext if isinstance(ext, Extension) else None
    setup = set_up(robot, data, model, measure, extension=given, **options)
    nominal, every = _checked(setup, wanted, fit_options)  # for "auto": refuse what "all" refuses
    start = nominal if given is None else None
    choice = choose(setup, wanted, ext, options=options, fit_options=fit_options, start=start, **choosing)
    if wanted == "auto" or ext == "auto":
        checked = wanted == "auto"  # every parameter passed the rank check: so does any subset
        if choice.extension is not None and given is None:
            setup = set_up(robot, data, model, measure, extension=choice.extension, **options)
            nominal, checked, every = None, False, None
        fit_options["partial"], wanted = fit_options["partial"] or checked, choice.params
    return setup, choice, wanted, {"nominal": nominal, "every": every}


def _delivered(
    found: Protected,
    setup: Setup,
    choice: ModelChoice,
    deliver: str,
    wanted: Any,
    test: Dataset | None,
    options: dict[str, Any],
    fit_options: dict[str, Any],
) -> Calibration:
    """The fit ``found`` of ``setup`` (on the parameters ``wanted``) as ``deliver`` asks (see
    :func:`calibrate`)."""
    if setup.problem.extension is None or deliver == "none":
        return replace(found.assessed(test), choice=choice)
    if deliver == "joint":
        return settled(replace(found.assessed(test), choice=choice), setup.data, test)
    problem = setup.problem
    geometry = set_up(problem.model.robot, setup.data, problem.model, problem.measurement.kind, **options)
    kept = _geometric_params(geometry, choice, wanted)
    joint = found if kept == wanted else fit(setup, kept, **fit_options)  # the same parameters: reused
    return _balanced(setup, geometry, kept, joint, choice, test, fit_options)


def _balanced(
    setup: Setup,
    geometry: Setup,
    kept: tuple[str, ...] | None,
    joint: Protected,
    choice: ModelChoice,
    test: Dataset | None,
    fit_options: dict[str, Any],
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
    alone = replace(fit(geometry, kept, **fit_options).assessed(test), choice=choice)
    assert setup.problem.extension is not None
    return replace(effect_on_top(alone, setup.problem.extension, data, test), balance=balance)


def _outliers_for_both(
    setup: Setup,
    choice: ModelChoice,
    bad: np.ndarray,
    wanted: Any,
    options: dict[str, Any],
    screen: dict[str, Any],
) -> np.ndarray:
    """Of the poses ``bad`` the fit flags, those the diagnosis' best candidate cannot explain
    either: a pose that is an outlier only for the rigid model may carry a real effect (backlash,
    a nonlinear stiffness), and is kept. ``options``, ``screen``: the set-up and fit options (with
    the outlier threshold, ``threshold``)."""
    assert choice.diagnosis is not None
    best = choice.diagnosis.candidates[0].extension
    if setup.problem.extension is not None and best.label == setup.problem.extension.label:
        return bad
    problem = setup.problem
    robot, kind = problem.model.robot, problem.measurement.kind
    other = set_up(robot, problem.data, problem.model, kind, extension=best, **options)
    params = choice.params if wanted == "auto" else wanted
    fit_options = {k: v for k, v in screen.items() if k != "threshold"}
    found = fit(other, params, **{**fit_options, "partial": True})
    again, _ = screen_outliers(*found.screening, found.free, screen["threshold"], screen["f_scale"])
    return np.intersect1d(bad, again)


def _geometric_params(geometry: Setup, choice: ModelChoice, wanted: Any) -> tuple[str, ...] | None:
    """The parameters of the geometry alone: those chosen without a cause (the first round of
    ``extension="auto"``; chosen again for ``params="auto"`` with a given extension)."""
    if choice.rounds:
        return choice.rounds[0].params
    if choice.params_mode == "auto":
        return select_on(geometry).params
    return wanted if isinstance(wanted, tuple) else None


def _without(
    robot: Robot,
    data: Dataset,
    model: str | Model,
    measure: str | None,
    bad: np.ndarray,
    scores: np.ndarray,
    call: dict[str, Any],
) -> Calibration:
    """``calibrate(**call)`` again without the poses ``bad`` (scores [m]), which it records."""
    keep = np.setdiff1d(np.arange(len(data)), bad)
    again = {**call, "pairs": _kept_pairs(call["pairs"], len(data), keep), "outliers": None}
    cal = calibrate(robot, data.subset(keep), model, measure, **again)
    rows = data.row_numbers[bad]
    return replace(cal, excluded=tuple((int(r), float(s) * 1e3) for r, s in zip(rows, scores[bad])))


def _judge(
    robot: Robot,
    data: Dataset,
    model: str | Model,
    measure: str | None,
    folding: tuple[int, int, Callable[[int, int, str], None] | None],
    options: dict[str, Any],
) -> Callable[[], Any]:
    """The nested cross-validation of the whole call: ``calibrate(**options)`` without each fold
    (``folding``: K, the seed, and the progress callback told of each fold)."""
    folds, seed, progress = folding
    call = {**options, "pairs": options["pairs"] if isinstance(options["pairs"], str) else "all"}
    return lambda: cross_validate_with(
        calibrate, robot, data, model, measure, folds, seed, progress=progress, **call
    )


def _checked(
    setup: Setup, wanted: tuple[str, ...] | str | None, fit_options: dict[str, Any]
) -> tuple[np.ndarray | None, Identifiability | None]:
    """For ``params="auto"``, refuse data that ``params="all"`` refuses (unless ``partial``) and
    return the registration-only θ and the identifiable set of every parameter it found."""
    if wanted != "auto" or fit_options["partial"]:
        return None, None
    nominal = register(setup)
    return nominal, identifiable_set(setup, nominal, None, False, fit_options["rcond"])
