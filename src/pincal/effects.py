"""Non-geometric effects: what a rigid model cannot explain, as joint-angle errors.

Each effect makes joint ``j`` reach ``q_j + Σ_k p_k r_k(q)`` when commanded ``q``, with
regressors ``r_k`` that depend on the commanded configuration and parameters ``p_k`` identified
together with the geometry:

- ``joint_compliance``: ``c · τ_j(q)``, the gravity torque the joint carries
  (``pin.computeGeneralizedGravity`` with the URDF's inertias and an optional payload on the tip,
  gravity along -z of the base) [rad/(N·m)];
- ``gear_harmonic``: ``a · sin(h q_j) + b · cos(h q_j)`` for ``h`` = 1 or 2 [rad];
- ``encoder_scale``: ``s · (q_j - q_mid)`` (a gear-ratio or encoder scale error), about the middle
  of the joint's range (0 for unlimited joints), since a constant part is a zero offset [rad/rad];
- ``backlash``: ``b · sign(τ_j(q))``, the flank of the gear play gravity pushes the joint to [rad].

For a prismatic joint the same hold in metres and newtons.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .errors import DataError
from .robots import Robot

EFFECTS = ("joint_compliance", "gear_harmonic", "encoder_scale", "backlash")
_SHORT = {"joint_compliance": "compliance", "encoder_scale": "scale", "backlash": "backlash"}


@dataclass(frozen=True)
class Payload:
    """A load carried by the tip: mass [kg] and centre of mass in the tip frame [m]."""

    mass: float
    com: tuple[float, float, float]

    @classmethod
    def parse(cls, text: str) -> Payload:
        """From ``MASS,X,Y,Z`` (kg, then metres in the tip frame)."""
        try:
            values = [float(v) for v in text.split(",")]
        except ValueError:
            values = []
        if len(values) != 4 or not np.all(np.isfinite(values)) or values[0] < 0:
            raise DataError(f"--payload {text!r}: write MASS,X,Y,Z (kg, then m in the tip frame)")
        return cls(values[0], (values[1], values[2], values[3]))


def gravity_torques(robot: Robot, q: np.ndarray, payload: Payload | None = None) -> np.ndarray:
    """Gravity torque each chain joint carries [N·m or N] at configurations ``q`` (N, n), from the
    URDF's inertias and an optional payload on the tip."""
    model = robot.model
    if payload is not None and payload.mass > 0:
        model = pin.Model(robot.model)  # a copy: the robot's own model is not changed
        tip = model.frames[robot.tip_frame_id]
        com = tip.placement.act(np.array(payload.com))
        model.inertias[tip.parentJoint] += pin.Inertia(payload.mass, com, np.zeros((3, 3)))
    data = model.createData()
    out = np.empty_like(np.atleast_2d(q), dtype=float)
    for i, qi in enumerate(np.atleast_2d(q)):
        out[i] = pin.computeGeneralizedGravity(model, data, robot.configuration(qi))
    return out


@dataclass(frozen=True, eq=False)
class Extension:
    """One effect on one joint.

    Attributes:
        robot: the robot.
        effect: one of :data:`EFFECTS`.
        joint: the joint's name.
        harmonic: the multiple ``h`` of a ``gear_harmonic``.
        payload: a load on the tip, for the gravity torques of compliance and backlash.
    """

    robot: Robot
    effect: str
    joint: str
    harmonic: int = 1
    payload: Payload | None = None

    def __post_init__(self) -> None:
        if self.effect not in EFFECTS:
            raise DataError(f"unknown effect {self.effect!r}: choose one of {', '.join(EFFECTS)}")
        if self.joint not in self.robot.joint_names:
            raise DataError(
                f"unknown joint {self.joint!r}: the chain's joints are {', '.join(self.robot.joint_names)}"
            )

    @classmethod
    def parse(cls, robot: Robot, text: str, payload: Payload | None = None) -> Extension:
        """From ``EFFECT:JOINT`` (``gear_harmonic2:JOINT`` for the second harmonic)."""
        effect, sep, joint = text.partition(":")
        if not sep:
            raise DataError(
                f"--extend {text!r}: write EFFECT:JOINT, for example joint_compliance:{robot.joint_names[1]}"
            )
        if effect == "gear_harmonic2":
            return cls(robot, "gear_harmonic", joint, 2, payload)
        return cls(robot, effect, joint, 1, payload)

    @property
    def label(self) -> str:
        """``EFFECT:JOINT`` as :meth:`parse` reads it."""
        suffix = "2" if self.effect == "gear_harmonic" and self.harmonic == 2 else ""
        return f"{self.effect}{suffix}:{self.joint}"

    @property
    def index(self) -> int:
        """Position of the joint in the chain."""
        return self.robot.joint_names.index(self.joint)

    @property
    def names(self) -> tuple[str, ...]:
        """Parameter names."""
        j = self.joint
        if self.effect == "gear_harmonic":
            return (f"{j}.sin{self.harmonic}", f"{j}.cos{self.harmonic}")
        return (f"{j}.{_SHORT[self.effect]}",)

    @property
    def units(self) -> tuple[str, ...]:
        """Parameter units."""
        angle = "m" if self.robot.prismatic[self.index] else "rad"
        load = "N" if self.robot.prismatic[self.index] else "N·m"
        return {
            "joint_compliance": (f"{angle}/{load}",),
            "gear_harmonic": (angle, angle),
            "encoder_scale": (f"{angle}/{angle}",),
            "backlash": (angle,),
        }[self.effect]

    @property
    def n_params(self) -> int:
        """Number of parameters."""
        return len(self.names)

    def regressors(self, q: np.ndarray) -> np.ndarray:
        """The regressors ``r_k(q)`` (N, n_params) at commanded configurations (N, n)."""
        qj = np.atleast_2d(q)[:, self.index]
        if self.effect == "gear_harmonic":
            return np.column_stack([np.sin(self.harmonic * qj), np.cos(self.harmonic * qj)])
        if self.effect == "encoder_scale":
            lo, hi = self.robot.lower[self.index], self.robot.upper[self.index]
            middle = 0.5 * (lo + hi) if np.isfinite(lo) and np.isfinite(hi) else 0.0
            return (qj - middle)[:, None]
        torque = gravity_torques(self.robot, q, self.payload)[:, self.index]
        return (torque if self.effect == "joint_compliance" else np.sign(torque))[:, None]

    def joint_error(self, q: np.ndarray, p: np.ndarray) -> np.ndarray:
        """The joint-value error each pose reaches: (N, n), zero but for this joint."""
        out = np.zeros_like(np.atleast_2d(q), dtype=float)
        out[:, self.index] = self.regressors(q) @ p
        return out


def candidates(robot: Robot, payload: Payload | None = None) -> list[Extension]:
    """Every effect on every joint (both gear harmonics); compliance and backlash only where
    gravity loads the joint (a vertical first axis carries no gravity torque)."""
    out = []
    probe = robot.random_configurations(50, np.random.default_rng(0))
    loaded = np.abs(gravity_torques(robot, probe, payload)).max(axis=0) > 1e-6
    for j, joint in enumerate(robot.joint_names):
        for effect in EFFECTS:
            if effect in ("joint_compliance", "backlash") and not loaded[j]:
                continue
            for h in (1, 2) if effect == "gear_harmonic" else (1,):
                out.append(Extension(robot, effect, joint, h, payload))
    return out
