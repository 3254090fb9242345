"""A joint compliance read as a stiffness: its sign, its size and its plausibility.

- An elastic joint (link angle = motor angle - τ(q_link)/K, K > 0, τ the torque the motor holds
  against gravity) on a simulated UR5 (random geometric errors, unknown instrument frame and tool
  point, 0.03 mm noise, 80 poses): the identified coefficient is negative, and read as a
  stiffness it sags, recovers K within 10 % and is plausible, for a sag of 3 mrad and of 1 mrad
  at the largest load.
- The same effect with its sign flipped (the joint rising against its load) is no stiffness, nor
  is a joint that would sag by more than 20 mrad.
- ``diagnose`` writes the stiffness of a joint-compliance candidate into its JSON, without inf
  or NaN, and names it in its summary.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import pincal
import pincal.kinematics.effects
from pincal.auto.diagnose import diagnose
from pincal.kinematics.effects import Extension
from pincal.kinematics.gravity import gravity_torques
from pincal.kinematics.stiffness import PLAUSIBLE_DEFLECTION, compliance_stiffness

NOISE = 3e-5  # 1σ of each measured coordinate [m]
N_POSES = 80
JOINT = "shoulder_lift_joint"
SEED = 3
MAX_K_ERROR = 0.10  # relative error of the recovered stiffness


def elastic_data(robot: pincal.Robot, sag: float, seed: int = SEED) -> tuple[pincal.Dataset, float]:
    """Measurements of a robot whose ``JOINT`` is elastic, and its true stiffness.

    Args:
        robot: the nominal robot.
        sag: the joint's deflection at its largest gravity torque over the poses [rad]; negative
            makes the joint rise against its load (K < 0).
        seed: seed of the truth, the poses and the noise.

    Returns:
        The data (commanded motor angles, measured positions) and the true K [N·m/rad].
    """
    truth = pincal.random_truth(robot, seed)
    rng = np.random.default_rng(seed + 1)
    q_motor = robot.random_configurations(N_POSES, rng, 0.05)
    j = robot.joint_names.index(JOINT)
    k = np.abs(gravity_torques(robot, q_motor)[:, j]).max() / sag
    q_link = q_motor.copy()
    for _ in range(6):  # link = motor - τ(link)/K: a contraction, since |dτ/dq| << K
        q_link[:, j] = q_motor[:, j] - gravity_torques(robot, q_link)[:, j] / k
    points = truth.target(q_link)[0] + rng.normal(0.0, NOISE, (N_POSES, 3))
    return pincal.Dataset(robot.joint_names, q_motor, points), float(k)


def identified(robot: pincal.Robot, data: pincal.Dataset) -> pincal.kinematics.stiffness.Stiffness:
    """The compliance of ``JOINT`` identified with the geometry, read as a stiffness."""
    ext = Extension(robot, "joint_compliance", JOINT)
    cal = pincal.calibrate(robot, data, "placements", extension=ext)
    return compliance_stiffness(ext, float(cal.effect_params[0]), data.q)


@pytest.mark.parametrize("sag", [3e-3, 1e-3])
def test_an_elastic_joint_sags_with_its_stiffness(get_robot, sag: float) -> None:
    """A joint that sags under its load has c < 0, and K = -1/c is the true stiffness."""
    robot = get_robot("ur5")
    data, k_true = elastic_data(robot, sag)
    s = identified(robot, data)
    error = abs(s.stiffness - k_true) / k_true
    context = f"K = {s.stiffness:.4g}, true {k_true:.4g} N·m/rad ({error:.1%}); {s.verdict}"
    assert s.coefficient < 0, context
    assert s.sags and s.stiffness > 0, context
    assert error <= MAX_K_ERROR, context
    assert s.plausible, context
    assert s.verdict.startswith("sags under gravity"), context
    assert s.deflection == pytest.approx(abs(s.coefficient) * s.max_torque)


def test_a_joint_rising_against_its_load_is_no_stiffness(get_robot) -> None:
    """The same effect with its sign flipped: K < 0, not plausible whatever its size."""
    robot = get_robot("ur5")
    data, _ = elastic_data(robot, -3e-3)
    s = identified(robot, data)
    assert s.coefficient > 0 and s.stiffness < 0, s.verdict
    assert not s.sags and not s.plausible
    assert "implausible" in s.verdict and "rise against its load" in s.verdict


@pytest.mark.parametrize("factor", [1.5, 10.0])
def test_too_soft_is_implausible(get_robot, factor: float) -> None:
    """A sag beyond the largest plausible deflection is no stiffness, though it sags."""
    robot = get_robot("ur5")
    ext = Extension(robot, "joint_compliance", JOINT)
    q = robot.random_configurations(N_POSES, np.random.default_rng(0))
    max_torque = np.abs(ext.regressors(q)).max()
    s = compliance_stiffness(ext, -factor * PLAUSIBLE_DEFLECTION[1] / max_torque, q)
    assert s.sags and not s.plausible
    assert s.deflection > PLAUSIBLE_DEFLECTION[1]
    assert s.max_torque == pytest.approx(max_torque)
    assert "implausible" in s.verdict and "mrad" in s.verdict


def test_too_stiff_and_zero_are_implausible(get_robot) -> None:
    """Below the smallest plausible deflection, and c = 0 (K infinite, written as null)."""
    robot = get_robot("ur5")
    ext = Extension(robot, "joint_compliance", JOINT)
    q = robot.random_configurations(N_POSES, np.random.default_rng(0))
    max_torque = np.abs(ext.regressors(q)).max()
    stiff = compliance_stiffness(ext, -0.5 * PLAUSIBLE_DEFLECTION[0] / max_torque, q)
    assert stiff.sags and not stiff.plausible and "implausible" in stiff.verdict
    zero = compliance_stiffness(ext, 0.0, q)
    assert np.isinf(zero.stiffness) and not zero.plausible
    assert zero.to_dict()["K"] is None
    json.dumps(zero.to_dict(), allow_nan=False)


def test_diagnose_reports_the_stiffness(get_robot) -> None:
    """The JSON of a compliance candidate holds its stiffness and is strict JSON; the summary of
    a named compliance gives the coefficient and the verdict."""
    robot = get_robot("ur5")
    data, k_true = elastic_data(robot, 3e-3)
    ext = Extension(robot, "joint_compliance", JOINT)
    other = Extension(robot, "encoder_scale", "elbow_joint")
    d = diagnose(robot, data, "placements", folds=3, effects=[ext, other])
    doc = json.loads(json.dumps(d.to_dict(), allow_nan=False))
    by_effect = {c["effect"]: c for c in doc["candidates"]}
    stiffness = by_effect["joint_compliance"]["stiffness"]
    keys = {"coefficient", "K", "unit_K", "max_torque", "deflection", "sags", "plausible", "verdict"}
    assert set(stiffness) == keys
    assert stiffness["unit_K"] == "N·m/rad"
    assert stiffness["sags"] and stiffness["plausible"]
    assert abs(stiffness["K"] - k_true) / k_true <= MAX_K_ERROR
    assert "stiffness" not in by_effect.get("encoder_scale", {})
    assert d.cause is not None and d.cause.extension is ext, doc["summary"]
    assert doc["summary"].startswith(f"{JOINT} sags under gravity: c = -"), doc["summary"]
    assert "N·m/rad" in doc["summary"]
