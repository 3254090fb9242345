"""Identification in named steps: set up, register, choose, solve, screen outliers, assess.

:func:`pincal.calibrate` runs them; every other path calls it or the same steps:

1. :func:`set_up`: the residual function (:class:`~pincal.identify.measurements.Problem`) with a
   closed-form first guess of the registration and tool, and each unknown's natural size;
2. :func:`register`: the nominal model with only the registration and tool fitted ("before");
3. :func:`identifiable_set`: the parameters the data identifies (and those held, with why);
4. :func:`solve`: Levenberg-Marquardt (or trust-region reflective with a robust loss) on that
   set, 1 mm and the rotation that moves the workspace by 1 mm weighing the same, each
   correction held near the URDF (``Setup.prior_weight``, :mod:`pincal.identify.prior`);
5. :func:`screen_outliers`: poses far outside the others' residuals (see :mod:`pincal.identify.outliers`);
6. :func:`assess`: standard deviations (:mod:`pincal.identify.uncertainty`), the errors before
   and after on the fitted and held-out poses; a fit stopped at :data:`MAX_EVALUATIONS` flagged.

``params="auto"`` and ``extension="auto"`` are chosen by :func:`pincal.auto.choice.choose` between
steps 2 and 4, on the poses being fitted only.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import pinocchio as pin

from pincal.data.dataset import Dataset
from pincal.data.pairs import chosen_pairs
from pincal.errors import DataError, IdentifiabilityError
from pincal.identify import chunked
from pincal.identify.calibration import Calibration
from pincal.identify.evaluation import evaluate, marker_stats
from pincal.identify.fixed_points import PointDistance, blind_jacobian, gauge_reasons, placed_distances
from pincal.identify.identifiability import RCOND, Identifiability, analyse, check_rank, natural_scale
from pincal.identify.kinds import check_options, get_kind
from pincal.identify.lm import OptimizeResult, levenberg_marquardt, soft_l1_roots
from pincal.identify.measurement import Measurement, held_markers, marker_setup
from pincal.identify.measurements import Problem
from pincal.identify.outliers import find_outliers
from pincal.identify.registration import initial_measurement
from pincal.identify.registrations import REGISTRATIONS
from pincal.identify.uncertainty import RowSums, posterior_std
from pincal.kinematics.effects import AnyEffect
from pincal.kinematics.mdh import make_model
from pincal.kinematics.models import Model
from pincal.options import ROTATION_WEIGHT
from pincal.robot.robots import Robot

#: Keyword arguments of :func:`calibrate` that describe the measurement set-up (see :func:`set_up`).
SETUP_KEYS = ("instrument_T_base", "tool", "rotation_weight", "pairs", "point_distances")

#: Weight of the rows that hold each geometric correction near the URDF, per natural unit (metres,
#: or the rotation that moves the workspace by 1 m): 0.1 m of correction weighs as one residual of
#: 0.15 mm. Where data can hardly tell corrections apart (the last joint's placement against a ball
#: on its axis), it keeps the fit from wandering decimetres and radians away for micrometres.
PRIOR_WEIGHT = 1.5e-3

#: Most evaluations of the residuals in one fit; a fit stopped there is flagged
#: (:attr:`pincal.identify.calibration.Calibration.converged`).
MAX_EVALUATIONS = 200


@dataclass(frozen=True, eq=False)
class Setup:
    """A calibration problem before anything is fitted.

    Attributes:
        problem: the residual function (model, measurement model with its first-guess
            registration and tool, data, extension).
        scale: natural size of each unknown (1 for metres, 1/length for radians, an effect's
            size that moves the tip by 1 mm at the workspace's length).
        tool: the tool as given (the tip frame's origin when unknown): the "URDF as is" tool.
        prior_weight: the pull toward the URDF (:data:`PRIOR_WEIGHT`, or :mod:`pincal.identify.prior`'s).
    """

    problem: Problem
    scale: np.ndarray
    tool: pin.SE3
    prior_weight: float = PRIOR_WEIGHT
    _last: dict[str, Any] = field(default_factory=dict, init=False, repr=False)

    def linearised(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residuals and Jacobian at ``theta``; the last pair is kept, as the registration-only
        point is asked for by the rank check, the selection and the fit in turn."""
        key = theta.tobytes()
        if self._last.get("key") != key:
            self._last.update(key=key, value=(self.problem.residuals(theta), self.problem.jacobian(theta)))
        return self._last["value"]

    @property
    def model(self) -> Model:
        """The parameterization."""
        return self.problem.model

    @property
    def data(self) -> Dataset:
        """The fitted poses."""
        return self.problem.data


def set_up(
    robot: Robot,
    data: Dataset,
    model: str | Model = "placements",
    measure: str | None = None,
    *,
    instrument_T_base: pin.SE3 | None = None,
    tool: pin.SE3 | np.ndarray | dict[str, np.ndarray] | None = None,
    rotation_weight: float = ROTATION_WEIGHT,
    pairs: str | np.ndarray = "all",
    point_distances: tuple[PointDistance, ...] = (),
    extension: AnyEffect | None = None,
) -> Setup:
    """The problem to solve, with a closed-form first guess of the registration and tool.

    Arguments as :func:`calibrate`.
    """
    if len(data) < 2:
        raise IdentifiabilityError(f"{len(data)} pose(s) to fit: a calibration needs many varied poses")
    if tuple(data.joint_names) != robot.joint_names:
        raise DataError(f"the data's joints {data.joint_names} are not the chain's {robot.joint_names}")
    mdl = make_model(model, robot) if isinstance(model, str) else model
    one_point = (
        tool is None or isinstance(tool, pin.SE3) or (not isinstance(tool, dict) and np.size(tool) == 3)
    )
    tool_se3 = (
        tool
        if isinstance(tool, pin.SE3)
        else pin.SE3(np.eye(3), np.zeros(3) if tool is None or not one_point else np.asarray(tool, float))
    )
    kind = measure or data.measured
    check_options(get_kind(kind), data, pairs, point_distances)
    measurement = Measurement(
        kind=kind,
        instrument_T_base=instrument_T_base or pin.SE3.Identity(),
        fit_instrument=instrument_T_base is None,
        tool=tool_se3,
        fit_tool=tool is None,
        rotation_weight=rotation_weight,
        pairs=chosen_pairs(pairs, len(data)),
        points=data.point_names if get_kind(kind).fixed_points else (),
        point_distances=placed_distances(data.point_names, tuple(point_distances)),
        **marker_setup(data, tool, robot),
    )
    problem = Problem(mdl, initial_measurement(robot, data, measurement), data, extension)
    return Setup(problem, natural_scale(problem), tool_se3)


def solve(
    setup: Setup, theta: np.ndarray, free: np.ndarray, loss: str = "linear", f_scale: float = 1e-4
) -> tuple[np.ndarray, OptimizeResult]:
    """Least squares over the unknowns ``free`` (mask) from ``theta``, held by ``setup.prior_weight`` rows.

    Args:
        setup: the problem.
        theta: the start; the unknowns not free keep their value.
        free: (P,) mask of the unknowns to fit.
        loss: ``linear`` or a robust loss of ``scipy.optimize.least_squares``.
        f_scale: residual size where a robust loss starts to down-weight [m].
    """
    problem = setup.problem
    nominal = problem.initial_theta()
    geometric = np.flatnonzero(free[: problem.model.n_params])  # the first free unknowns
    prior = setup.prior_weight / setup.scale[geometric]  # [1 or m/rad]

    def full(sub: np.ndarray) -> np.ndarray:
        out = theta.copy()
        out[free] = sub
        return out

    def residuals(sub: np.ndarray) -> np.ndarray:
        held = prior * (sub[: len(geometric)] - nominal[geometric])
        return np.concatenate([problem.residuals(full(sub)), held])

    def jacobian(sub: np.ndarray) -> np.ndarray:
        held = np.eye(len(geometric), len(sub)) * prior[:, None]
        return np.vstack([problem.jacobian(full(sub), free), held])

    x_scale = setup.scale[free] * 1e-3
    enough = problem.n_rows() >= free.sum()
    if loss == "linear" and enough:
        big = chunked.lm_triangle(problem, full, free, x_scale, (prior, nominal[geometric]))  # issue 33
        result = levenberg_marquardt(
            residuals, jacobian, theta[free], x_scale, max_nfev=MAX_EVALUATIONS, triangle=big
        )
    elif loss == "soft_l1" and enough:  # the outlier screen's refit
        rooted, rooted_jacobian = soft_l1_roots(residuals, jacobian, f_scale)
        big = chunked.lm_triangle(problem, full, free, x_scale, (prior, nominal[geometric]), f_scale)
        result = levenberg_marquardt(
            rooted, rooted_jacobian, theta[free], x_scale, max_nfev=MAX_EVALUATIONS, triangle=big
        )
    else:  # another robust loss: SciPy's trust-region reflective, imported only then (start-up)
        from scipy.optimize import least_squares

        tight = dict.fromkeys(("xtol", "ftol", "gtol"), 1e-12)
        options = dict(loss=loss, f_scale=f_scale, x_scale=x_scale, max_nfev=MAX_EVALUATIONS, **tight)
        result = least_squares(residuals, theta[free], jac=jacobian, method="trf", **options)
    return full(result.x), result


def register(setup: Setup, with_extension: bool = False) -> np.ndarray:
    """θ of the nominal model with only the registration and tool fitted (and the extension,
    when ``with_extension``): the "before" of a report and the start of every fit; solved once
    per set of poses and set-up (:mod:`pincal.identify.registrations`)."""
    problem = setup.problem
    theta = problem.initial_theta()
    first = problem.model.n_params if with_extension else problem.n_model
    free = np.arange(problem.n_params) >= first
    if free.any() and not with_extension:  # the same for every fit on these poses: solved once
        return REGISTRATIONS.solved(problem, setup.scale, "nominal", lambda: solve(setup, theta, free)[0])
    if free.any():
        theta, _ = solve(setup, theta, free)
    return theta


def identifiable_set(
    setup: Setup,
    theta: np.ndarray,
    params: Sequence[str] | None = None,
    partial: bool = False,
    rcond: float = RCOND,
) -> Identifiability:
    """The unknowns to fit: the chosen model parameters (default: all) that the data identifies,
    with the extension, registration and tool.

    Raises:
        DataError: unknown parameter names.
        IdentifiabilityError: the data cannot identify what varied poses would (unless
            ``partial``), or gives fewer equations than unknowns.
    """
    setup = chunked.sampled(setup)  # issue 33: many poses, a random subset of them (pincal.identify.chunked)
    problem, mdl = setup.problem, setup.model
    held = dict(mdl.held)
    if params is not None:
        unknown = sorted(set(params) - set(mdl.names))
        if unknown:
            raise DataError(
                f"unknown parameters {', '.join(unknown)}: "
                f"the {mdl.kind} model's are named like {', '.join(mdl.names[:3])}"
            )
        chosen = set(params)
        held.update({name: "not selected" for name in mdl.names if name not in chosen and name not in held})
    candidates = np.array([name not in held for name in problem.names])
    n_model = problem.n_model
    preference = np.ones(problem.n_params)
    preference[:n_model] = 1.0 + 0.05 * np.linspace(0.0, 1.0, n_model)
    preference[n_model:] = 2.0
    jacobian = setup.linearised(theta)[1]
    jacobian, gauges, blind = blind_jacobian(problem, theta, jacobian, candidates, setup.scale)
    ident = analyse(jacobian, problem.names, setup.scale, candidates, preference, held, rcond)
    if blind:
        why = gauge_reasons(problem.names, candidates & ~ident.identifiable, gauges, blind, setup.scale)
        ident = replace(ident, reasons={**ident.reasons, **why}, gauges=blind)
    n_res, n_poses = len(jacobian), len(setup.data)
    n_needed = ident.n_identifiable
    if not partial and not problem.measurement.measure.fixed_points:  # its rank is the gauges'
        n_needed = check_rank(problem, theta, jacobian, setup.scale, candidates, rcond)
    if n_res <= n_needed:
        per_pose = max(1, n_res // max(1, n_poses))
        least = n_needed // per_pose + 2
        said = f"{n_poses} poses give {n_res} equations for {n_needed} identifiable parameters"
        raise IdentifiabilityError(f"{said}: measure at least {least} poses", least)
    return ident


def screen_outliers(
    setup: Setup, theta: np.ndarray, free: np.ndarray, threshold: float, f_scale: float = 1e-4
) -> tuple[np.ndarray, np.ndarray]:
    """Outlier poses of a fit (indices, worst first) and every pose's score [m]."""

    def robust(start: np.ndarray, how: str, size: float) -> np.ndarray:
        return solve(chunked.sampled(setup), start, free, how, size)[0]  # issue 33: many poses, a subset

    return find_outliers(setup.problem, theta, robust, threshold)


def assess(
    setup: Setup,
    theta: np.ndarray,
    nominal_theta: np.ndarray,
    ident: Identifiability,
    result: OptimizeResult,
    test: Dataset | None = None,
    sums: RowSums | None = None,
) -> Calibration:
    """The calibration record: standard deviations and the errors before and after.

    Args:
        setup: the problem.
        theta: the fit.
        nominal_theta: the registration-only fit ("before").
        ident: the identifiable set the fit used.
        result: the solver's result (evaluations, message).
        test: held-out poses, if any.
        sums: the rows' sums the standard deviations read (:func:`pincal.identify.uncertainty.posterior_std`),
            when already made.
    """
    problem, mdl, ext, data = setup.problem, setup.model, setup.problem.extension, setup.data
    n_model, measurement = problem.n_model, problem.measurement
    # The URDF as it is: nominal tool, only the registration fitted.
    urdf_meas = held_markers(measurement, setup.tool)
    urdf_problem = Problem(mdl, urdf_meas, data, ext)
    urdf_theta = urdf_problem.initial_theta()
    if urdf_meas.n_instrument:
        urdf_theta[n_model:] = theta[n_model : n_model + 6]
        urdf_setup = Setup(urdf_problem, setup.scale[: urdf_problem.n_params], setup.tool)
        free = np.arange(urdf_problem.n_params) >= n_model
        start = urdf_theta
        urdf_theta = REGISTRATIONS.solved(  # as the nominal's: the same on these poses for every fit
            urdf_problem, urdf_setup.scale, "urdf", lambda: solve(urdf_setup, start, free)[0]
        )

    std = posterior_std(setup.problem, setup.scale, setup.prior_weight, theta, ident.identifiable, sums)

    def stats(meas: Measurement, th: np.ndarray, on: Dataset | None) -> Any:
        return None if on is None else evaluate(mdl, meas, th, on, ext)

    held_out = replace(measurement, pairs=None)
    return Calibration(
        model=mdl,
        extension=ext,
        measurement=measurement,
        names=problem.names,
        units=problem.units,
        theta=theta,
        std=std,
        nominal_theta=nominal_theta,
        identifiability=ident,
        train_before=stats(measurement, nominal_theta, data),
        train_after=stats(measurement, theta, data),
        test_before=stats(held_out, nominal_theta, test),
        test_after=stats(held_out, theta, test),
        train_urdf=stats(urdf_meas, urdf_theta, data),
        test_urdf=stats(replace(urdf_meas, pairs=None), urdf_theta, test),
        urdf_measurement=urdf_meas,
        urdf_theta=urdf_theta,
        n_poses=data.n_poses,
        n_evaluations=int(result.njev or result.nfev),
        message=str(result.message),
        converged=bool(result.get("success", True)),
        train_markers=marker_stats(mdl, measurement, theta, data, ext),
        test_markers=marker_stats(mdl, held_out, theta, test, ext),
    )
