"""The first guess of what the measurement set-up is: instrument registration and tool.

:func:`initial_measurement` finds, in closed form from the nominal kinematics, the pose of the
instrument in the robot's base frame (``instrument_T_base``, Kabsch) and the measured point or
target frame on the tip (linear least squares), so that the nonlinear solve starts close.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin

from pincal.data.dataset import Dataset
from pincal.identify.chunked import sample_poses
from pincal.identify.measurement import Measurement
from pincal.kinematics.chain import Chain, forward
from pincal.robot.robots import Robot


def quaternions(rotations: np.ndarray) -> np.ndarray:
    """(w, x, y, z) of rotation matrices (N, 3, 3)."""
    return np.array([pin.Quaternion(r).coeffs()[[3, 0, 1, 2]] for r in rotations])


def kabsch(src: np.ndarray, dst: np.ndarray) -> pin.SE3:
    """Rigid transform ``T`` minimising ``|T src - dst|`` (points (N, 3) [m])."""
    cs, cd = src.mean(axis=0), dst.mean(axis=0)
    u, _, vt = np.linalg.svd((src - cs).T @ (dst - cd))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rot = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return pin.SE3(rot, cd - rot @ cs)


def project_so3(m: np.ndarray) -> np.ndarray:
    """The rotation nearest to a 3x3 matrix."""
    u, _, vt = np.linalg.svd(m)
    return u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt


def initial_measurement(robot: Robot, data: Dataset, measurement: Measurement) -> Measurement:
    """Closed-form first guess of the registration and tool from the nominal model.

    Alternates a rigid registration of the nominal points (Kabsch) with a linear least-squares
    solve of the tool point, then averages the tool orientation for pose data.
    """
    if measurement.measure.fixed_points:  # no instrument; the points start at their rows' means
        return measurement
    data = sample_poses(data)  # a first guess: a random subset of many poses will do (issue 33)
    tips = np.asarray(measurement.marker_tips, dtype=int)[data.marker] if measurement.marker_tips else None
    frames = forward(Chain.nominal(robot), data.q, tips)
    rot, pos = frames.tip_rotation, frames.tip_translation
    if measurement.markers:
        return _initial_markers(data, rot, pos, measurement)
    reg, tool = measurement.instrument_T_base, measurement.tool
    point = tool.translation.copy()
    fit_reg = measurement.fit_instrument
    for _ in range(8 if fit_reg and measurement.fit_tool else 1):
        if fit_reg:
            reg = kabsch(pos + rot @ point, data.points)
        if measurement.fit_tool:
            lhs = (reg.rotation @ rot).reshape(-1, 3)
            rhs = (data.points - pos @ reg.rotation.T - reg.translation).reshape(-1)
            point = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    tool_rot = tool.rotation
    if measurement.measure.orientation and measurement.fit_tool:
        rel = np.transpose(reg.rotation @ rot, (0, 2, 1)) @ data.rotations()
        tool_rot = project_so3(rel.sum(axis=0))
    return replace(measurement, instrument_T_base=reg, tool=pin.SE3(tool_rot, point))


def _initial_markers(
    data: Dataset, rot: np.ndarray, pos: np.ndarray, measurement: Measurement
) -> Measurement:
    """:func:`initial_measurement` of several markers: the registration (Kabsch) alternating with
    each marker's point (linear least squares over its rows)."""
    assert data.marker is not None
    reg, points = measurement.instrument_T_base, measurement.points_on_tip()
    fit_reg = measurement.fit_instrument
    for _ in range(8 if fit_reg and measurement.fit_tool else 1):
        if fit_reg:
            reg = kabsch(pos + np.einsum("nij,nj->ni", rot, points[data.marker]), data.points)
        if measurement.fit_tool:
            for k in range(len(points)):
                mine = data.marker == k
                lhs = (reg.rotation @ rot[mine]).reshape(-1, 3)
                rhs = (data.points[mine] - pos[mine] @ reg.rotation.T - reg.translation).reshape(-1)
                points[k] = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    return replace(measurement, instrument_T_base=reg, marker_points=points)
