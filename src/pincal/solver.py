"""Identification: register the nominal model, find the identifiable set, solve, report errors.

:func:`calibrate` is the whole pipeline. The solver is ``scipy.optimize.least_squares``
(Levenberg-Marquardt, or trust-region reflective with a robust loss) on the identifiable
parameters only, scaled so that 1 mm and the rotation that moves the workspace by 1 mm weigh the
same; standard deviations are ``σ² (JᵀJ)⁻¹`` on that set with ``σ²`` from the fit residual.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin
from scipy.optimize import least_squares

from .data import Dataset
from .effects import Extension
from .errors import DataError, IdentifiabilityError
from .evaluation import ErrorStats, evaluate
from .identifiability import RCOND, Identifiability, analyse, lost_parameters, parameter_scale
from .kinematics import Chain, forward
from .measurements import ROTATION_WEIGHT, Measurement, Problem, gao_pairs, unpack
from .models import Model, make_model
from .outliers import find_outliers
from .robots import Robot

LOSSES = ("linear", "soft_l1", "huber", "cauchy")


@dataclass(frozen=True, eq=False)
class Calibration:
    """What an identification found.

    Attributes:
        model: the parameterization.
        extension: the non-geometric effect identified with it, if any.
        measurement: the measurement model (its registration and tool are the initial guesses).
        names: names of all unknowns θ (model, then instrument and tool).
        units: their units (``m`` or ``rad``).
        theta: the identified unknowns.
        std: standard deviations of θ (0 for the parameters held fixed).
        nominal_theta: the nominal model with its registration and tool fitted ("before": the
            error the nominal kinematics is responsible for, FIGAROH's "registration only").
        identifiability: the identifiable set and why the rest was held.
        train_before, train_after: errors on the fitted poses.
        test_before, test_after: errors on held-out poses, or None.
        train_urdf, test_urdf: errors of the URDF exactly as it is: the nominal kinematics with the
            nominal tool (the tip frame's origin, or the tool given), only the instrument
            registered (as the papers report "before calibration").
        n_poses: number of fitted poses.
        n_evaluations: Jacobian evaluations of the solver.
        message: the solver's termination message.
        excluded: outlier poses left out of the fit, as (row number, residual [mm]) pairs.
    """

    model: Model
    extension: Extension | None
    measurement: Measurement
    names: tuple[str, ...]
    units: tuple[str, ...]
    theta: np.ndarray
    std: np.ndarray
    nominal_theta: np.ndarray
    identifiability: Identifiability
    train_before: ErrorStats
    train_after: ErrorStats
    test_before: ErrorStats | None
    test_after: ErrorStats | None
    train_urdf: ErrorStats
    test_urdf: ErrorStats | None
    urdf_measurement: Measurement
    urdf_theta: np.ndarray
    n_poses: int
    n_evaluations: int
    message: str
    excluded: tuple[tuple[int, float], ...] = ()

    @property
    def robot(self) -> Robot:
        """The calibrated robot (nominal description)."""
        return self.model.robot

    @property
    def x(self) -> np.ndarray:
        """The model parameters (first part of θ)."""
        return self.theta[: self.model.n_params]

    @property
    def effect_params(self) -> np.ndarray:
        """The extension's parameters (empty without one)."""
        n = self.extension.n_params if self.extension else 0
        return self.theta[self.model.n_params : self.model.n_params + n]

    def chain(self) -> Chain:
        """The calibrated chain from base to tip."""
        return self.model.chain(self.x)

    def problem(self, data: Dataset) -> Problem:
        """The residual function of this calibration on other data (all pairs for distances)."""
        return Problem(self.model, replace(self.measurement, pairs=None), data, self.extension)

    def split(self) -> tuple[np.ndarray, pin.SE3, pin.SE3]:
        """Model parameters, ``instrument_T_base`` and ``tip_T_target`` as identified."""
        n = self.model.n_params + (self.extension.n_params if self.extension else 0)
        x, reg, tool = unpack(n, self.measurement, self.theta)
        return x[: self.model.n_params], reg, tool

    def base_T_tip(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Calibrated tip rotations (N, 3, 3) and positions (N, 3) [m] for commanded joint values
        (N, n), the extension's joint error included."""
        q = np.atleast_2d(q)
        if self.extension is not None:
            q = q + self.extension.joint_error(q, self.effect_params)
        frames = forward(self.chain(), q)
        return frames.tip_rotation, frames.tip_translation


def _check_rank(
    problem: Problem,
    theta: np.ndarray,
    jacobian: np.ndarray,
    scale: np.ndarray,
    candidates: np.ndarray,
    rcond: float,
) -> int:
    """How many parameters varied poses identify; an error if these poses identify fewer.

    The reference is the same problem on random poses within the joint limits, measured exactly;
    ``jacobian`` is the data's, at ``theta``.

    Raises:
        IdentifiabilityError: naming the parameters the data cannot see, and the likely cause.
    """
    robot, data = problem.model.robot, problem.data
    n_ref = max(60, 2 * problem.n_params)
    q_ref = robot.random_configurations(n_ref, np.random.default_rng(0), margin=0.05)
    quats = np.tile([1.0, 0.0, 0.0, 0.0], (n_ref, 1)) if data.has_orientation else None
    blank = Dataset(data.joint_names, q_ref, np.zeros((n_ref, 3)), quats)
    meas = replace(problem.measurement, pairs=None)
    points, rotations = Problem(problem.model, meas, blank, problem.extension).predict(theta)
    exact = replace(blank, points=points, quaternions=None if quats is None else _quaternions(rotations))
    reference = Problem(problem.model, meas, exact, problem.extension)
    rank, lost = lost_parameters(jacobian, reference.jacobian(theta), problem.names, scale, candidates, rcond)
    if not lost or len(jacobian) <= rank:  # too few equations: the caller says so
        return rank
    span = np.ptp(data.q, axis=0)
    still = [j for j, s, p in zip(robot.joint_names, span, robot.prismatic) if s < (1e-4 if p else 1e-3)]
    if len(data) < 3 or len(still) == robot.n_joints:
        cause = "all the poses are alike (no joint moves)"
    elif still:
        cause = f"joint(s) {', '.join(still)} never move"
    else:
        cause = f"{len(data)} poses do not vary the joints enough"
    names = ", ".join(lost[:8]) + (f" and {len(lost) - 8} more" if len(lost) > 8 else "")
    raise IdentifiabilityError(
        f"the data cannot identify {names}, which varied poses would: {cause}. Measure poses that "
        "move every joint over its range, fit fewer parameters (--model offsets), or pass "
        "--partial to fit only what this data identifies"
    )


def _quaternions(rotations: np.ndarray) -> np.ndarray:
    """(w, x, y, z) of rotation matrices (N, 3, 3)."""
    return np.array([pin.Quaternion(r).coeffs()[[3, 0, 1, 2]] for r in rotations])


def _kabsch(src: np.ndarray, dst: np.ndarray) -> pin.SE3:
    """Rigid transform ``T`` minimising ``|T src - dst|`` (points (N, 3))."""
    cs, cd = src.mean(axis=0), dst.mean(axis=0)
    u, _, vt = np.linalg.svd((src - cs).T @ (dst - cd))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rot = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return pin.SE3(rot, cd - rot @ cs)


def _project_so3(m: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(m)
    return u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt


def initial_measurement(robot: Robot, data: Dataset, measurement: Measurement) -> Measurement:
    """Closed-form first guess of the registration and tool from the nominal model.

    Alternates a rigid registration of the nominal points (Kabsch) with a linear least-squares
    solve of the tool point, then averages the tool orientation for pose data.
    """
    frames = forward(Chain.nominal(robot), data.q)
    rot, pos = frames.tip_rotation, frames.tip_translation
    reg, tool = measurement.instrument_T_base, measurement.tool
    point = tool.translation.copy()
    fit_reg = measurement.fit_instrument
    for _ in range(8 if fit_reg and measurement.fit_tool else 1):
        if fit_reg:
            reg = _kabsch(pos + rot @ point, data.points)
        if measurement.fit_tool:
            lhs = (reg.rotation @ rot).reshape(-1, 3)
            rhs = (data.points - pos @ reg.rotation.T - reg.translation).reshape(-1)
            point = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    tool_rot = tool.rotation
    if measurement.kind == "pose" and measurement.fit_tool:
        rel = np.transpose(reg.rotation @ rot, (0, 2, 1)) @ data.rotations()
        tool_rot = _project_so3(rel.sum(axis=0))
    return replace(measurement, instrument_T_base=reg, tool=pin.SE3(tool_rot, point))


def _solve(
    problem: Problem, theta: np.ndarray, free: np.ndarray, scale: np.ndarray, loss: str, f_scale: float
):
    def fun(sub: np.ndarray) -> np.ndarray:
        full = theta.copy()
        full[free] = sub
        return problem.residuals(full)

    def jac(sub: np.ndarray) -> np.ndarray:
        full = theta.copy()
        full[free] = sub
        return problem.jacobian(full)[:, free]

    n_res = len(problem.residuals(theta))
    method = "lm" if loss == "linear" and n_res >= free.sum() else "trf"
    result = least_squares(
        fun,
        theta[free],
        jac=jac,
        method=method,
        loss=loss,
        f_scale=f_scale,
        x_scale=scale[free] * 1e-3,
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-12,
        max_nfev=200,
    )
    out = theta.copy()
    out[free] = result.x
    return out, result


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
    loss: str = "linear",
    f_scale: float = 1e-4,
    rcond: float = RCOND,
    extension: Extension | str | None = None,
    params: Sequence[str] | None = None,
    outliers: float | None = None,
    partial: bool = False,
) -> Calibration:
    """Identify a kinematic model from measurements.

    Args:
        robot: the robot and its chain (see :func:`pincal.load_robot`).
        data: the fitted poses.
        model: ``placements``, ``poe``, ``mdh``, ``offsets`` or a :class:`~pincal.models.Model`.
        measure: ``position``, ``pose`` or ``distance`` (default: ``pose`` when the data has
            orientations, else ``position``).
        test: held-out poses for the errors after calibration.
        instrument_T_base: the known registration (default: unknown, estimated).
        tool: the known measured point on the tip (3,) [m] or target frame (default: estimated).
        rotation_weight: weight of orientation residuals [m/rad] for pose data.
        pairs: pose pairs for distance data: ``all``, ``gao`` (eq. 21) or an (m, 2) array.
        loss: ``linear`` (least squares) or a robust loss of ``scipy.optimize.least_squares``.
        f_scale: residual size where a robust loss starts to down-weight [m].
        rcond: relative singular-value threshold of the identifiability rank.
        extension: a non-geometric effect identified with the geometry (an
            :class:`~pincal.effects.Extension` or ``EFFECT:JOINT``).
        params: names of the model parameters to fit (default: every one the data identifies);
            the others stay at their nominal value. The extension, registration and tool are fitted
            whatever this says.
        outliers: screen for outlier poses at this many robust standard deviations (see
            :mod:`pincal.outliers`), leave them out and refit; ``None`` keeps every pose.
        partial: fit what the data identifies even when varied poses would identify more
            (otherwise that is an error naming the parameters the data cannot see).

    Raises:
        DataError: unknown measure or loss, data that does not fit the robot.
        IdentifiabilityError: fewer equations than identifiable parameters.
    """
    if len(data) < 2:
        raise IdentifiabilityError(f"{len(data)} pose(s) to fit: a calibration needs many varied poses")
    if tuple(data.joint_names) != robot.joint_names:
        raise DataError(f"the data's joints {data.joint_names} are not the chain's {robot.joint_names}")
    if loss not in LOSSES:
        raise DataError(f"unknown loss {loss!r}: choose one of {', '.join(LOSSES)}")
    kind = measure or ("pose" if data.has_orientation else "position")
    mdl = make_model(model, robot) if isinstance(model, str) else model
    if isinstance(pairs, str):
        if pairs not in ("all", "gao"):
            raise DataError(f"unknown pairing {pairs!r}: use all or gao")
        pair_array = gao_pairs(len(data)) if pairs == "gao" else None
    else:
        pair_array = np.asarray(pairs, dtype=int)
    tool_se3 = (
        tool
        if isinstance(tool, pin.SE3)
        else pin.SE3(np.eye(3), np.zeros(3) if tool is None else np.asarray(tool, float))
    )
    measurement = Measurement(
        kind=kind,
        instrument_T_base=instrument_T_base or pin.SE3.Identity(),
        fit_instrument=instrument_T_base is None,
        tool=tool_se3,
        fit_tool=tool is None,
        rotation_weight=rotation_weight,
        pairs=pair_array,
    )
    measurement = initial_measurement(robot, data, measurement)
    ext = Extension.parse(robot, extension) if isinstance(extension, str) else extension
    problem = Problem(mdl, measurement, data, ext)
    n_model = problem.n_model
    length = max(0.05, float(np.sqrt(np.mean(np.sum((data.points - data.points.mean(0)) ** 2, axis=1)))))
    scale = parameter_scale(problem.units, length)
    if ext is not None:  # natural size of an effect: moving the joint by 1 mm at the lever arm
        rms = np.sqrt(np.mean(problem.regressors**2, axis=0))
        lever = 1.0 if robot.prismatic[ext.index] else length
        scale[mdl.n_params : n_model] = 1.0 / (lever * np.where(rms > 0, rms, 1.0))

    # "Before": the nominal model with only the registration and tool fitted.
    theta = problem.initial_theta()
    meas_free = np.arange(problem.n_params) >= n_model
    if meas_free.any():
        theta, _ = _solve(problem, theta, meas_free, scale, "linear", f_scale)
    nominal_theta = theta.copy()

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
    preference = np.ones(problem.n_params)
    preference[:n_model] = 1.0 + 0.05 * np.linspace(0.0, 1.0, n_model)
    preference[n_model:] = 2.0
    jacobian = problem.jacobian(theta)
    ident = analyse(jacobian, problem.names, scale, candidates, preference, held, rcond)
    n_res = len(jacobian)
    n_needed = (
        ident.n_identifiable if partial else _check_rank(problem, theta, jacobian, scale, candidates, rcond)
    )
    if n_res <= n_needed:
        per_pose = max(1, n_res // max(1, len(data)))
        raise IdentifiabilityError(
            f"{len(data)} poses give {n_res} equations for {n_needed} identifiable "
            f"parameters: measure at least {n_needed // per_pose + 2} poses"
        )
    theta, result = _solve(problem, theta, ident.identifiable, scale, loss, f_scale)
    if outliers:

        def robust(start: np.ndarray, how: str, size: float) -> np.ndarray:
            return _solve(problem, start, ident.identifiable, scale, how, size)[0]

        bad, scores = find_outliers(problem, theta, robust, outliers)
        if bad.size:
            keep = np.setdiff1d(np.arange(len(data)), bad)
            kept_pairs: str | np.ndarray = pairs
            if not isinstance(pairs, str):
                index = np.full(len(data), -1)
                index[keep] = np.arange(len(keep))
                mapped = index[np.asarray(pairs, dtype=int)]
                kept_pairs = mapped[(mapped >= 0).all(axis=1)]
            cal = calibrate(
                robot,
                data.subset(keep),
                mdl,
                measure,
                test=test,
                instrument_T_base=instrument_T_base,
                tool=tool,
                rotation_weight=rotation_weight,
                pairs=kept_pairs,
                loss=loss,
                f_scale=f_scale,
                rcond=rcond,
                extension=ext,
                params=params,
                partial=partial,
            )
            rows = data.row_numbers[bad]
            return replace(cal, excluded=tuple((int(r), float(s) * 1e3) for r, s in zip(rows, scores[bad])))

    # The URDF as it is: nominal tool, only the registration fitted.
    urdf_meas = replace(measurement, tool=tool_se3, fit_tool=False)
    urdf_problem = Problem(mdl, urdf_meas, data, ext)
    urdf_theta = urdf_problem.initial_theta()
    if urdf_meas.n_instrument:
        urdf_theta[n_model:] = theta[n_model : n_model + 6]
        urdf_free = np.arange(urdf_problem.n_params) >= n_model
        urdf_theta, _ = _solve(
            urdf_problem, urdf_theta, urdf_free, scale[: urdf_problem.n_params], "linear", f_scale
        )

    std = np.zeros(problem.n_params)
    free = ident.identifiable
    jac = problem.jacobian(theta)[:, free] * scale[free]
    dof = n_res - int(free.sum())
    sigma2 = float(np.sum(problem.residuals(theta) ** 2)) / dof
    cov = np.linalg.pinv(jac.T @ jac) * sigma2
    std[free] = np.sqrt(np.clip(np.diag(cov), 0.0, None)) * scale[free]

    test_meas = replace(measurement, pairs=None)

    def stats(meas: Measurement, th: np.ndarray, on: Dataset) -> ErrorStats:
        return evaluate(mdl, meas, th, on, ext)

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
        test_before=None if test is None else stats(test_meas, nominal_theta, test),
        test_after=None if test is None else stats(test_meas, theta, test),
        train_urdf=stats(urdf_meas, urdf_theta, data),
        urdf_measurement=urdf_meas,
        urdf_theta=urdf_theta,
        test_urdf=None if test is None else stats(replace(urdf_meas, pairs=None), urdf_theta, test),
        n_poses=len(data),
        n_evaluations=int(result.njev or result.nfev),
        message=str(result.message),
    )
