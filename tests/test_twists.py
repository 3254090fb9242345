"""Property tests of the nominal POE twists and of Gao's closed-form twist Jacobian.

Checks, against Pinocchio as the independent reference:

- the product of exponentials built from :func:`pincal.kinematics.twists.nominal_twists` reproduces
Pinocchio's
  forward kinematics of the tip frame at seeded random configurations (1e-10 m, 1e-10 rad);
- every revolute twist is a unit screw of zero pitch (|ω| = 1, ω·v = 0), and equals the column of
  Pinocchio's WORLD frame Jacobian at q = 0;
- the bundled ``mrres5`` matches the published table of Gao et al. (2013): its twists, its home
  point, and the paper's nominal coordinates of the 28 measured poses;
- :func:`pincal.kinematics.twists.gao_k` (order (ω, v)) equals :func:`pincal.kinematics.twists.left_jacobian`
(order (v, ω)) once
  both sides are reordered, and ``left_jacobian`` is the true left Jacobian of ``exp6`` (central
  finite differences).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import pincal

ROBOTS = ("ur5", "ur10", "panda", "z1", "mrres5", "zu3")
N_CONFIGURATIONS = 100
FK_TOL = 1e-10  # [m] and [rad]

#: Reorders a 6-vector between Pinocchio's (v, ω) and Gao's (ω, v); its own inverse.
P = np.block([[np.zeros((3, 3)), np.eye(3)], [np.eye(3), np.zeros((3, 3))]])


def rotation_error(r_ref: np.ndarray, r: np.ndarray) -> float:
    """Angle [rad] of ``r_refᵀ r``."""
    return float(np.linalg.norm(pin.log3(r_ref.T @ r)))


@pytest.mark.parametrize("name", ROBOTS)
def test_poe_forward_equals_pinocchio(get_robot, name: str) -> None:
    robot = get_robot(name)
    tw = pincal.kinematics.twists.nominal_twists(robot)
    configurations = robot.random_configurations(N_CONFIGURATIONS, np.random.default_rng(2024))
    assert configurations.shape == (N_CONFIGURATIONS, robot.n_joints)
    for q in configurations:
        poe = pincal.kinematics.twists.poe_forward(tw.twists, tw.home, q)
        ref = robot.frame_placement(q)
        assert np.linalg.norm(poe.translation - ref.translation) <= FK_TOL
        assert rotation_error(ref.rotation, poe.rotation) <= FK_TOL


@pytest.mark.parametrize("name", ROBOTS)
def test_home_is_pinocchio_at_zero(get_robot, name: str) -> None:
    robot = get_robot(name)
    tw = pincal.kinematics.twists.nominal_twists(robot)
    ref = robot.frame_placement(np.zeros(robot.n_joints))
    assert np.linalg.norm(tw.home.translation - ref.translation) <= FK_TOL
    assert rotation_error(ref.rotation, tw.home.rotation) <= FK_TOL


@pytest.mark.parametrize("name", ROBOTS)
def test_revolute_twists_are_unit_zero_pitch_screws(get_robot, name: str) -> None:
    robot = get_robot(name)
    twists = pincal.kinematics.twists.nominal_twists(robot).twists
    assert twists.shape == (robot.n_joints, 6)
    n_revolute = 0
    for xi, prismatic in zip(twists, robot.prismatic):
        v, w = xi[:3], xi[3:]
        if prismatic:
            assert np.linalg.norm(w) == 0.0
            assert abs(np.linalg.norm(v) - 1.0) <= 1e-12
            continue
        n_revolute += 1
        assert abs(np.linalg.norm(w) - 1.0) <= 1e-12
        assert abs(w @ v) <= 1e-12
    assert n_revolute > 0


@pytest.mark.parametrize("name", ROBOTS)
def test_twists_are_pinocchio_world_jacobian_at_zero(get_robot, name: str) -> None:
    """At q = 0, ξ_j is column j of Pinocchio's WORLD Jacobian (an independent derivation)."""
    robot = get_robot(name)
    twists = pincal.kinematics.twists.nominal_twists(robot).twists
    data = robot.model.createData()
    q0 = robot.configuration(np.zeros(robot.n_joints))
    pin.computeJointJacobians(robot.model, data, q0)
    pin.updateFramePlacements(robot.model, data)
    jac = pin.getFrameJacobian(robot.model, data, robot.tip_frame_id, pin.ReferenceFrame.WORLD)
    np.testing.assert_allclose(twists, jac.T, rtol=0.0, atol=FK_TOL)


# Gao et al. (2013), Table 1 (mm): ω_j and v_j of the MRRES arm's joints, and the home point p_E0.
GAO_OMEGA = np.array([[0, 0, 1], [-1, 0, 0], [1, 0, 0], [0, 0, 1], [1, 0, 0]], dtype=float)
GAO_V_MM = np.array([[0, 0, 0], [0, -301.5, 0], [0, 481.5, 0], [0, 0, 0], [0, 804.5, 0]])
GAO_HOME_MM = np.array([-5.0, 0.0, 1011.5])


def test_mrres5_twists_match_gao_table(get_robot) -> None:
    robot = get_robot("mrres5")
    tw = pincal.kinematics.twists.nominal_twists(robot)
    np.testing.assert_allclose(tw.twists[:, 3:], GAO_OMEGA, rtol=0.0, atol=FK_TOL)
    np.testing.assert_allclose(tw.twists[:, :3], GAO_V_MM * 1e-3, rtol=0.0, atol=FK_TOL)
    np.testing.assert_allclose(tw.home.translation, GAO_HOME_MM * 1e-3, rtol=0.0, atol=FK_TOL)


def test_mrres5_reproduces_gao_nominal_coordinates(get_robot) -> None:
    robot = get_robot("mrres5")
    data, nominal = pincal.gao2013_data()
    assert nominal.shape == (28, 3)
    assert len(data) == 28
    assert data.joint_names == robot.joint_names
    tips = pincal.kinematics.chain.forward(
        pincal.kinematics.chain.Chain.nominal(robot), data.q
    ).tip_translation
    error_mm = np.linalg.norm(tips - nominal, axis=1) * 1e3
    assert np.all(error_mm <= 1e-3), error_mm.max()


def random_eta(rng: np.random.Generator, size: float) -> np.ndarray:
    """A twist (v, ω) with |ω| = size [rad] and a translation part of comparable size [m]."""
    w = rng.normal(size=3)
    v = rng.normal(size=3)
    return np.concatenate([size * v / np.linalg.norm(v), size * w / np.linalg.norm(w)])


SIZES = (1e-8, 0.1, 1.0, 3.0)


@pytest.mark.parametrize("size", SIZES)
@pytest.mark.parametrize("seed", range(5))
def test_gao_k_equals_left_jacobian(size: float, seed: int) -> None:
    eta = random_eta(np.random.default_rng(seed), size)  # Pinocchio order (v, ω)
    k_gao = pincal.kinematics.twists.gao_k(P @ eta)  # Gao's order (ω, v)
    k_pin = pincal.kinematics.twists.left_jacobian(eta)
    assert k_gao.shape == k_pin.shape == (6, 6)
    np.testing.assert_allclose(P @ k_gao @ P, k_pin, rtol=0.0, atol=1e-10)


@pytest.mark.parametrize("size", SIZES)
@pytest.mark.parametrize("seed", range(3))
def test_left_jacobian_by_finite_differences(size: float, seed: int) -> None:
    """``exp6(η + h d) · exp6(η)⁻¹ ≈ exp6(h K d)``: K by central differences of log6."""
    rng = np.random.default_rng(100 + seed)
    eta = random_eta(rng, size)
    k = pincal.kinematics.twists.left_jacobian(eta)
    h = 1e-6
    base_inv = pin.exp6(pin.Motion(eta)).inverse()
    k_fd = np.empty((6, 6))
    for c in range(6):
        d = np.zeros(6)
        d[c] = 1.0
        plus = pin.log6(pin.exp6(pin.Motion(eta + h * d)) * base_inv).vector
        minus = pin.log6(pin.exp6(pin.Motion(eta - h * d)) * base_inv).vector
        k_fd[:, c] = (plus - minus) / (2 * h)
    assert np.max(np.abs(k - k_fd)) / np.max(np.abs(k)) <= 1e-6
    # Not trivially the identity for finite rotations.
    if size >= 0.1:
        assert np.max(np.abs(k - np.eye(6))) > 1e-3
