"""Property tests of the models' chains and of every analytic Jacobian.

- Every model at zero parameters is the URDF: its chain equals Pinocchio's forward kinematics
  (1e-10 m, 1e-10 rad) for every bundled robot; ``placements`` with random parameters equals a
  Pinocchio model whose joint placements were edited the same way (an independent path).
- The tip Jacobian of every model, and the residual Jacobian of every model x measure
  (``position``, ``pose``, ``distance``) with a random registration and tool, match central
  finite differences (relative error <= 1e-6).
- The joint-angle columns: :func:`pincal.kinematics.chain.joint_jacobian` equals Pinocchio's frame Jacobian
  (LOCAL_WORLD_ALIGNED) within 1e-10, and the derivative of the ``position`` residual with respect
  to the joint values equals Pinocchio's frame Jacobian mapped into the instrument frame,
  ``R_I (J_v - [R_tip p]x J_ω)``, within 1e-10.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest
from finite_differences import tip_jacobian_fd

import pincal
import pincal.identify.measurement
import pincal.kinematics.mdh
from pincal.kinematics.turns import skew

ROBOTS = ("ur5", "ur10", "panda", "z1", "mrres5", "zu3")
JACOBIAN_ROBOTS = ("ur5", "panda")
MEASURES = ("position", "pose", "distance")
TOL = 1e-10  # [m], [rad], and Jacobian entries [m/rad] compared analytic to analytic
FD_RTOL = 1e-6  # max |J - J_fd| / max |J|
FD_STEP = 1e-6


def rotation_errors(r_ref: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Angles [rad] of ``r_refᵀ r`` for stacks of rotations (N, 3, 3)."""
    return np.array([np.linalg.norm(pin.log3(a.T @ b)) for a, b in zip(r_ref, r)])


def pinocchio_tips(robot: pincal.Robot, configurations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tip rotations (N, 3, 3) and translations (N, 3) by Pinocchio."""
    placements = [robot.frame_placement(q) for q in configurations]
    return np.array([m.rotation for m in placements]), np.array([m.translation for m in placements])


def relative_error(jac: np.ndarray, jac_fd: np.ndarray) -> float:
    """``max |J - J_fd| / max |J|``."""
    scale = np.max(np.abs(jac))
    assert scale > 0.0
    return float(np.max(np.abs(jac - jac_fd)) / scale)


# --- chains at zero and with random parameters ---------------------------------------------------


@pytest.mark.parametrize("kind", pincal.MODELS)
@pytest.mark.parametrize("name", ROBOTS)
def test_model_at_zero_is_pinocchio(get_robot, name: str, kind: str) -> None:
    robot = get_robot(name)
    model = pincal.kinematics.mdh.make_model(kind, robot)
    configurations = robot.random_configurations(30, np.random.default_rng(7))
    frames = pincal.kinematics.chain.forward(model.chain(np.zeros(model.n_params)), configurations)
    rot_ref, pos_ref = pinocchio_tips(robot, configurations)
    assert np.max(np.linalg.norm(frames.tip_translation - pos_ref, axis=1)) <= TOL
    assert np.max(rotation_errors(rot_ref, frames.tip_rotation)) <= TOL


@pytest.mark.parametrize("name", ROBOTS)
def test_placements_equal_edited_pinocchio_model(get_robot, name: str) -> None:
    """``C_j = C⁰_j exp(δ_j)`` is Pinocchio's ``jointPlacements[j] * exp6(δ_j)``."""
    robot = get_robot(name)
    model = pincal.kinematics.mdh.make_model("placements", robot)
    rng = np.random.default_rng(11)
    x = rng.normal(0.0, 0.05, model.n_params)
    edited = pin.Model(robot.model)
    for j in range(1, edited.njoints):
        delta = x[6 * (j - 1) : 6 * j]
        edited.jointPlacements[j] = edited.jointPlacements[j] * pin.exp6(pin.Motion(delta))
    data = edited.createData()
    configurations = robot.random_configurations(30, rng)
    frames = pincal.kinematics.chain.forward(model.chain(x), configurations)
    for i, q in enumerate(configurations):
        pin.framesForwardKinematics(edited, data, robot.configuration(q))
        ref = data.oMf[robot.tip_frame_id]
        assert np.linalg.norm(frames.tip_translation[i] - ref.translation) <= TOL
        assert np.linalg.norm(pin.log3(ref.rotation.T @ frames.tip_rotation[i])) <= TOL
    # The edit is not a no-op: the nominal robot is far from the edited one.
    nominal = robot.frame_placement(configurations[0]).translation
    assert np.linalg.norm(frames.tip_translation[0] - nominal) > 1e-3


# --- finite differences of the tip and of the residuals ------------------------------------------


@pytest.mark.parametrize("kind", pincal.MODELS)
@pytest.mark.parametrize("name", JACOBIAN_ROBOTS)
def test_tip_jacobian_matches_finite_differences(get_robot, name: str, kind: str) -> None:
    robot = get_robot(name)
    model = pincal.kinematics.mdh.make_model(kind, robot)
    rng = np.random.default_rng(3)
    x = rng.normal(0.0, 0.01, model.n_params)
    configurations = robot.random_configurations(8, rng)
    frames = pincal.kinematics.chain.forward(model.chain(x), configurations)
    jac = pincal.kinematics.chain.tip_jacobian(frames, model.twists(x))
    assert jac.shape == (8, 6, model.n_params)
    jac_fd = tip_jacobian_fd(model, x, configurations, step=FD_STEP)
    assert relative_error(jac, jac_fd) <= FD_RTOL


def make_problem(
    robot: pincal.Robot, kind: str, measure: str, seed: int
) -> tuple[pincal.identify.measurements.Problem, np.ndarray]:
    """A problem with a random registration and tool on 8 random poses, and a random θ near it.

    The measurements are the model's own predictions at θ, slightly perturbed, so that the
    orientation residuals stay far from log3's singularity at π.
    """
    rng = np.random.default_rng(seed)
    pin.seed(seed)  # SE3.Random draws from Eigen's generator
    model = pincal.kinematics.mdh.make_model(kind, robot)
    measurement = pincal.identify.measurement.Measurement(
        measure, instrument_T_base=pin.SE3.Random(), tool=pin.SE3.Random()
    )
    configurations = robot.random_configurations(8, rng)
    placeholder = pincal.Dataset(
        robot.joint_names, configurations, np.zeros((8, 3)), np.tile([1.0, 0.0, 0.0, 0.0], (8, 1))
    )
    draft = pincal.identify.measurements.Problem(model, measurement, placeholder)
    theta = draft.initial_theta() + rng.normal(0.0, 0.01, draft.n_params)
    points, rotations = draft.predict(theta)
    points = points + rng.normal(0.0, 1e-3, points.shape)
    quaternions = np.empty((8, 4))
    for i, r in enumerate(rotations):
        qt = pin.Quaternion(pin.exp3(rng.normal(0.0, 0.02, 3)) @ r)
        quaternions[i] = (qt.w, qt.x, qt.y, qt.z)
    data = pincal.Dataset(robot.joint_names, configurations, points, quaternions)
    return pincal.identify.measurements.Problem(model, measurement, data), theta


@pytest.mark.parametrize("measure", MEASURES)
@pytest.mark.parametrize("kind", pincal.MODELS)
@pytest.mark.parametrize("name", JACOBIAN_ROBOTS)
def test_problem_jacobian_matches_finite_differences(get_robot, name: str, kind: str, measure: str) -> None:
    problem, theta = make_problem(get_robot(name), kind, measure, seed=5)
    jac = problem.jacobian(theta)
    n_residuals = {"position": 3 * 8, "pose": 6 * 8, "distance": 8 * 7 // 2}[measure]
    assert jac.shape == (n_residuals, problem.n_params)
    jac_fd = np.empty_like(jac)
    for c in range(problem.n_params):
        step = np.zeros(problem.n_params)
        step[c] = FD_STEP
        jac_fd[:, c] = (problem.residuals(theta + step) - problem.residuals(theta - step)) / (2 * FD_STEP)
    assert relative_error(jac, jac_fd) <= FD_RTOL


# --- joint-angle columns against Pinocchio -------------------------------------------------------


@pytest.mark.parametrize("name", ROBOTS)
def test_joint_jacobian_equals_pinocchio_frame_jacobian(get_robot, name: str) -> None:
    robot = get_robot(name)
    chain = pincal.kinematics.chain.Chain.nominal(robot)
    configurations = robot.random_configurations(20, np.random.default_rng(17))
    jac = pincal.kinematics.chain.joint_jacobian(
        chain, pincal.kinematics.chain.forward(chain, configurations)
    )
    assert jac.shape == (20, 6, robot.n_joints)
    for i, q in enumerate(configurations):
        np.testing.assert_allclose(jac[i], robot.frame_jacobian(q), rtol=0.0, atol=TOL)


def pinocchio_position_jacobian(
    robot: pincal.Robot, q: np.ndarray, reg: pin.SE3, point: np.ndarray
) -> np.ndarray:
    """d(instrument_p_target)/dq (3, n) from Pinocchio: ``R_I (J_v - [R_tip p]x J_ω)``.

    The target is the point ``p`` on the tip; its velocity is the tip origin's plus
    ``ω x (R_tip p)`` (LOCAL_WORLD_ALIGNED, base axes), rotated into the instrument frame by
    ``R_I``.
    """
    jac = robot.frame_jacobian(q)
    lever = robot.frame_placement(q).rotation @ point
    return reg.rotation @ (jac[:3] - skew(lever) @ jac[3:])


@pytest.mark.parametrize("name", ROBOTS)
def test_position_residual_joint_derivative_equals_pinocchio(get_robot, name: str) -> None:
    """The joint-value derivative of the ``position`` residual, three ways.

    pincal's analytic one is the ``offsets`` model's column at zero offsets (the robot reaches
    ``q + o``, so ∂r/∂o_j = ∂r/∂q_j); it must equal Pinocchio's frame Jacobian mapped into the
    instrument frame within 1e-10, and central differences of the residuals in ``data.q``.
    """
    robot = get_robot(name)
    rng = np.random.default_rng(23)
    n, n_poses = robot.n_joints, 6
    reg = pin.SE3(pin.exp3(rng.normal(size=3)), rng.normal(size=3))
    point = rng.normal(0.0, 0.1, 3)
    measurement = pincal.identify.measurement.Measurement(
        "position", instrument_T_base=reg, fit_instrument=False, tool=pin.SE3(np.eye(3), point)
    )
    configurations = robot.random_configurations(n_poses, rng)
    data = pincal.Dataset(robot.joint_names, configurations, rng.normal(size=(n_poses, 3)))
    problem = pincal.identify.measurements.Problem(
        pincal.kinematics.mdh.make_model("offsets", robot), measurement, data
    )
    theta = problem.initial_theta()
    assert np.allclose(theta[n:], point) and not np.any(theta[:n])

    analytic = problem.jacobian(theta)[:, :n].reshape(n_poses, 3, n)
    expected = np.array([pinocchio_position_jacobian(robot, q, reg, point) for q in configurations])
    np.testing.assert_allclose(analytic, expected, rtol=0.0, atol=TOL)

    by_q = np.empty_like(expected)
    for j in range(n):
        q_plus, q_minus = configurations.copy(), configurations.copy()
        q_plus[:, j] += FD_STEP
        q_minus[:, j] -= FD_STEP
        plus = pincal.identify.measurements.Problem(
            problem.model, measurement, replace(data, q=q_plus)
        ).residuals(theta)
        minus = pincal.identify.measurements.Problem(
            problem.model, measurement, replace(data, q=q_minus)
        ).residuals(theta)
        by_q[:, :, j] = ((plus - minus) / (2 * FD_STEP)).reshape(n_poses, 3)
    assert relative_error(expected, by_q) <= FD_RTOL


def test_one_frame_for_every_point_is_that_frame_repeated() -> None:
    """The registration's columns (one frame, every point): the columns of that frame repeated for
    each point, velocity and angular velocity, to rounding."""
    from pincal.kinematics.chain import twist_columns

    rng = np.random.default_rng(8)
    frame = pin.SE3.Random()
    points, zeta = rng.normal(size=(40, 3)), rng.normal(size=(6, 5))
    one = twist_columns(frame.rotation, frame.translation, zeta, points)
    rot, pos = np.tile(frame.rotation, (40, 1, 1)), np.tile(frame.translation, (40, 1))
    each = twist_columns(rot, pos, zeta, points)
    for got, want in zip(one, each, strict=True):
        assert got is not None and want is not None and got.shape == want.shape == (40, 3, 5)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-13)
    v_by_hand = rot @ zeta[:3] + np.cross(rot @ zeta[3:], (points - pos)[:, :, None], axis=1)
    np.testing.assert_allclose(one[0], v_by_hand, rtol=0, atol=1e-13)
