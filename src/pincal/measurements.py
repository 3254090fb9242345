"""Measurement models: residuals and analytic Jacobians for position, pose and distance data.

The unknowns are stacked as ``θ = [model parameters | instrument (6) | tool (3 or 6)]``:

- *instrument*: the registration ``instrument_T_base = instrument_T_base⁰ · exp(ρ)`` (a twist
  ρ, order (v, ω)), estimated unless the instrument frame is given (``--instrument-frame base``);
- *tool*: the measured point on the tip frame (3, [m]) for position and distance data, or the
  target frame ``tip_T_target = tip_T_target⁰ · exp(τ)`` (6) for pose data.

Residuals (model minus measurement):

- ``position``: the point in the instrument frame, 3 per pose [m];
- ``pose``: the position (3 [m]) and ``w · log3(R_measuredᵀ R_model)`` (3), with
  ``w = rotation_weight`` [m/rad] so that 1 mrad weighs as much as ``w`` mm;
- ``distance`` (Gao et al. 2013, eqs. 13-18): ``|p_i - p_j|`` (model, base frame) minus the
  measured distance, one per pair [m]; it needs no registration.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numpy as np
import pinocchio as pin

from .data import Dataset
from .effects import Extension
from .errors import DataError
from .kinematics import Frames, forward, joint_column, skew, tip_jacobian
from .models import Model

MEASURES = ("position", "pose", "distance")
#: Default weight of orientation residuals [m/rad]: 1 mrad counts as 0.1 mm.
ROTATION_WEIGHT = 0.1


def all_pairs(n: int) -> np.ndarray:
    """Every pair ``(i, j)``, ``i < j``, of ``n`` poses: (n(n-1)/2, 2)."""
    return np.array(list(combinations(range(n), 2)), dtype=int).reshape(-1, 2)


def gao_pairs(n: int) -> np.ndarray:
    """Gao et al. (2013) eq. 21 (0-based): (i, i+n/2), (2i, 2i-1), (4i, 4i-2), (4i-1, 4i-3).

    For the paper's 28 poses these are its 42 pairs; other ``n`` take the pairs that exist.
    """
    pairs = set()
    for i in range(1, n // 2 + 1):
        pairs.add((i, i + n // 2))
        pairs.add((2 * i - 1, 2 * i))
    for i in range(1, n // 4 + 1):
        pairs.add((4 * i - 2, 4 * i))
        pairs.add((4 * i - 3, 4 * i - 1))
    return np.array(sorted((a - 1, b - 1) for a, b in pairs if 1 <= a <= n and 1 <= b <= n and a != b))


@dataclass(frozen=True)
class Measurement:
    """What is measured and what is known about the set-up.

    Attributes:
        kind: ``position``, ``pose`` or ``distance``.
        instrument_T_base: the registration, or its initial guess when ``fit_instrument``.
        fit_instrument: whether the registration is unknown (not used by ``distance``).
        tool: ``tip_T_target`` (pose) or a point on the tip (its translation), or initial guess.
        fit_tool: whether the tool is unknown.
        rotation_weight: weight of orientation residuals [m/rad] (``pose`` only).
        pairs: (m, 2) pose pairs for ``distance`` (default: all pairs).
    """

    kind: str = "position"
    instrument_T_base: pin.SE3 = pin.SE3.Identity()
    fit_instrument: bool = True
    tool: pin.SE3 = pin.SE3.Identity()
    fit_tool: bool = True
    rotation_weight: float = ROTATION_WEIGHT
    pairs: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.kind not in MEASURES:
            raise DataError(f"unknown measure {self.kind!r}: choose one of {', '.join(MEASURES)}")

    @property
    def n_instrument(self) -> int:
        """Number of registration unknowns."""
        return 6 if self.fit_instrument and self.kind != "distance" else 0

    @property
    def n_tool(self) -> int:
        """Number of tool unknowns."""
        return 0 if not self.fit_tool else (6 if self.kind == "pose" else 3)

    def names(self) -> tuple[list[str], list[str]]:
        """Names and units of the measurement unknowns."""
        names, units = [], []
        if self.n_instrument:
            names += [f"instrument.{c}" for c in ("tx", "ty", "tz", "rx", "ry", "rz")]
            units += ["m"] * 3 + ["rad"] * 3
        if self.n_tool == 3:
            names += ["tool.x", "tool.y", "tool.z"]
            units += ["m"] * 3
        elif self.n_tool == 6:
            names += [f"tool.{c}" for c in ("tx", "ty", "tz", "rx", "ry", "rz")]
            units += ["m"] * 3 + ["rad"] * 3
        return names, units


def unpack(n_model: int, measurement: Measurement, theta: np.ndarray) -> tuple[np.ndarray, pin.SE3, pin.SE3]:
    """Split θ into model parameters, ``instrument_T_base`` and ``tip_T_target``."""
    x = theta[:n_model]
    k = n_model
    reg = measurement.instrument_T_base
    if measurement.n_instrument:
        reg = reg * pin.exp6(pin.Motion(theta[k : k + 6]))
        k += 6
    tool = measurement.tool
    if measurement.n_tool == 3:
        tool = pin.SE3(tool.rotation, theta[k : k + 3].copy())
    elif measurement.n_tool == 6:
        tool = tool * pin.exp6(pin.Motion(theta[k : k + 6]))
    return x, reg, tool


class Problem:
    """The residual function of a model, a measurement model and a dataset."""

    def __init__(
        self, model: Model, measurement: Measurement, data: Dataset, extension: Extension | None = None
    ) -> None:
        if measurement.kind == "pose" and not data.has_orientation:
            raise DataError("--measure pose needs the orientation columns qw,qx,qy,qz")
        self.model = model
        self.measurement = measurement
        self.data = data
        self.extension = extension
        names, units = measurement.names()
        ext_names = extension.names if extension else ()
        ext_units = extension.units if extension else ()
        self.names = (*model.names, *ext_names, *names)
        self.units = (*model.units, *ext_units, *units)
        self.n_model = model.n_params + len(ext_names)
        self.regressors = extension.regressors(data.q) if extension else np.empty((len(data), 0))
        self.pairs = np.empty((0, 2), dtype=int)
        self.measured_distances = np.empty(0)
        if measurement.kind == "distance":
            self.pairs = measurement.pairs if measurement.pairs is not None else all_pairs(len(data))
            self.measured_distances = np.linalg.norm(
                data.points[self.pairs[:, 0]] - data.points[self.pairs[:, 1]], axis=1
            )
        self.measured_rotations = data.rotations() if measurement.kind == "pose" else np.empty((0, 3, 3))

    @property
    def n_params(self) -> int:
        """Number of unknowns in θ."""
        return len(self.names)

    def split(self, theta: np.ndarray) -> tuple[np.ndarray, pin.SE3, pin.SE3]:
        """Model parameters, ``instrument_T_base`` and ``tip_T_target`` for the unknowns θ."""
        return unpack(self.n_model, self.measurement, theta)

    def initial_theta(self) -> np.ndarray:
        """θ for the nominal model and the measurement model's initial registration and tool."""
        theta = np.zeros(self.n_params)
        if self.measurement.n_tool == 3:
            k = self.n_model + self.measurement.n_instrument
            theta[k : k + 3] = self.measurement.tool.translation
        return theta

    def reached(self, theta: np.ndarray) -> np.ndarray:
        """The joint values the robot reaches (N, n): the commands plus the extension's error."""
        if self.extension is None:
            return self.data.q
        q = self.data.q.copy()
        q[:, self.extension.index] += self.regressors @ theta[self.model.n_params : self.n_model]
        return q

    def target_frames(self, theta: np.ndarray) -> tuple[Frames, np.ndarray, np.ndarray]:
        """Chain frames, ``base_R_target`` (N, 3, 3) and ``base_p_target`` (N, 3) [m]."""
        x, _, tool = self.split(theta)
        frames = forward(self.model.chain(x[: self.model.n_params]), self.reached(theta))
        rot = frames.tip_rotation @ tool.rotation
        pos = frames.tip_translation + frames.tip_rotation @ tool.translation
        return frames, rot, pos

    def predict(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predicted target positions (N, 3) [m] and rotations (N, 3, 3) in the instrument frame."""
        _, reg, _ = self.split(theta)
        _, rot, pos = self.target_frames(theta)
        return pos @ reg.rotation.T + reg.translation, reg.rotation @ rot

    def joint_sensitivity(self, theta: np.ndarray, joint: int) -> np.ndarray:
        """How each pose's measured point moves per unit of joint ``joint`` (N, 3), instrument frame."""
        x, reg, _ = self.split(theta)
        frames, _, pos = self.target_frames(theta)
        jac = joint_column(self.model.chain(x[: self.model.n_params]), frames, joint)
        return (jac[:, :3] + np.cross(jac[:, 3:], pos - frames.tip_translation)) @ reg.rotation.T

    def residuals(self, theta: np.ndarray) -> np.ndarray:
        """Stacked residuals [m] (see the module docstring)."""
        return self._evaluate(theta, jacobian=False)[0]

    def jacobian(self, theta: np.ndarray) -> np.ndarray:
        """Analytic Jacobian of :meth:`residuals` with respect to θ."""
        return self._evaluate(theta, jacobian=True)[1]

    def _evaluate(self, theta: np.ndarray, jacobian: bool) -> tuple[np.ndarray, np.ndarray]:
        """Residuals and, if asked, their Jacobian (else an empty array)."""
        m = self.measurement
        x, reg, tool = self.split(theta)
        frames, rot, pos = self.target_frames(theta)
        n = len(self.data)
        jac_target = np.empty((0, 6, self.n_params))
        if jacobian:
            # LOCAL_WORLD_ALIGNED Jacobian of the target frame: model columns, then tool columns.
            jt = np.zeros((n, 6, self.n_params))
            n_geo = self.model.n_params
            jt[:, :, :n_geo] = tip_jacobian(frames, self.model.twists(x[:n_geo]))
            if self.extension is not None:
                joint = self.extension.index
                column = joint_column(self.model.chain(x[:n_geo]), frames, joint)
                jt[:, :, n_geo : self.n_model] = column[:, :, None] * self.regressors[:, None, :]
            lever = pos - frames.tip_translation
            jt[:, :3, : self.n_model] += np.cross(jt[:, 3:, : self.n_model], lever[:, :, None], axis=1)
            k = self.n_model + m.n_instrument
            if m.n_tool == 3:
                jt[:, :3, k : k + 3] = frames.tip_rotation
            elif m.n_tool == 6:
                local = pin.Jexp6(pin.Motion(theta[k : k + 6]))
                jt[:, :3, k : k + 6] = rot @ local[:3]
                jt[:, 3:, k : k + 6] = rot @ local[3:]
            jac_target = jt

        if m.kind == "distance":
            i, j = self.pairs[:, 0], self.pairs[:, 1]
            diff = pos[i] - pos[j]
            dist = np.linalg.norm(diff, axis=1)
            res = dist - self.measured_distances
            if not jacobian:
                return res, np.empty((0, self.n_params))
            u = diff / np.where(dist > 0, dist, 1.0)[:, None]  # a pose paired with itself: no direction
            jac = np.einsum("pk,pkc->pc", u, jac_target[i, :3] - jac_target[j, :3])
            return res, jac

        pos_i = pos @ reg.rotation.T + reg.translation
        res_p = pos_i - self.data.points
        if m.kind == "position":
            res = res_p.reshape(-1)
        else:
            rot_i = reg.rotation @ rot
            err = np.transpose(self.measured_rotations, (0, 2, 1)) @ rot_i
            res_r = np.array([pin.log3(e) for e in err])
            res = np.concatenate([res_p, m.rotation_weight * res_r], axis=1).reshape(-1)
        if not jacobian:
            return res, np.empty((0, self.n_params))

        jac_p = reg.rotation @ jac_target[:, :3]  # (N, 3, P)
        if m.n_instrument:
            k = self.n_model
            local = pin.Jexp6(pin.Motion(theta[k : k + 6]))
            base_twist = np.concatenate([np.broadcast_to(np.eye(3), (n, 3, 3)), -skew(pos)], axis=2)
            jac_p[:, :, k : k + 6] = reg.rotation @ (base_twist @ local)
        if m.kind == "position":
            return res, jac_p.reshape(-1, self.n_params)
        jac_w = reg.rotation @ jac_target[:, 3:]  # instrument-frame rotation of the target
        if m.n_instrument:
            k = self.n_model
            jac_w[:, :, k : k + 6] = reg.rotation @ pin.Jexp6(pin.Motion(theta[k : k + 6]))[3:]
        rot_i = reg.rotation @ rot
        for p in range(n):
            jac_w[p] = pin.Jlog3(err[p]) @ rot_i[p].T @ jac_w[p]
        jac = np.concatenate([jac_p, m.rotation_weight * jac_w], axis=1)
        return res, jac.reshape(-1, self.n_params)
