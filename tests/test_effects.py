"""Gravity torques with a payload: against the Jacobian-transpose of the payload's weight."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import pincal
import pincal.kinematics.chain
from pincal.kinematics.gravity import Payload, gravity_torques


@pytest.mark.parametrize("name", ["ur5", "panda", "mrres5"])
def test_payload_adds_its_weight_through_the_jacobian(get_robot, name: str) -> None:
    """τ(q; payload) - τ(q) = -J_p(q)ᵀ m g, with J_p the point Jacobian of the payload's centre."""
    robot = get_robot(name)
    payload = Payload(2.5, (0.01, -0.02, 0.08))
    q = robot.random_configurations(10, np.random.default_rng(7))
    bare = gravity_torques(robot, q)
    extra = gravity_torques(robot, q, payload) - bare
    data = robot.model.createData()
    weight = np.array([0.0, 0.0, -9.81 * payload.mass])
    for qi, got in zip(q, extra):
        pin.computeJointJacobians(robot.model, data, robot.configuration(qi))
        pin.updateFramePlacements(robot.model, data)
        tip = data.oMf[robot.tip_frame_id]
        lever = tip.rotation @ np.array(payload.com)
        jac = pin.getFrameJacobian(robot.model, data, robot.tip_frame_id, pin.LOCAL_WORLD_ALIGNED)
        point = jac[:3] - pincal.kinematics.chain.skew(lever) @ jac[3:]
        np.testing.assert_allclose(got, -(point.T @ weight), atol=1e-9)
    # The robot's own model is left as it was: without a payload, the torques are unchanged.
    np.testing.assert_array_equal(gravity_torques(robot, q), bare)


@pytest.mark.parametrize("text", ["1,2", "a,b,c,d", "-1,0,0,0", "nan,0,0,0"])
def test_payload_parse_refuses(text: str) -> None:
    """Malformed ``--payload`` values are input errors with a fix in the message."""
    with pytest.raises(pincal.DataError, match="MASS,X,Y,Z"):
        Payload.parse(text)
