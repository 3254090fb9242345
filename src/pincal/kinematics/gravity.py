"""Gravity torques a chain's joints carry, from the URDF's inertias and a payload on the tip:
what joint compliance and backlash follow (:mod:`pincal.kinematics.effects`).

Gravity is 9.81 m/s² along -z of the base; torques are ``pin.computeGeneralizedGravity``'s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pincal.errors import DataError
from pincal.robot.robots import Robot


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
        if len(values) != 4 or not np.all(np.abs(values) < 1e6) or values[0] < 0:  # NaN fails too
            raise DataError(
                f"payload={text!r}: write MASS,X,Y,Z, numbers below 1e6 (kg, then m in the tip frame)"
            )
        return cls(values[0], (values[1], values[2], values[3]))

    def __post_init__(self) -> None:
        """A mass of 0 kg or more and a centre of mass within 1e6 m, all finite (issue 33)."""
        if not (0.0 <= self.mass < 1e6 and all(abs(c) < 1e6 for c in self.com)):  # NaN fails too
            raise DataError(
                f"payload mass {self.mass} kg, centre of mass {self.com} m: a load has a finite mass "
                "of 0 kg or more and a centre of mass within 1e6 m"
            )


#: The last few :func:`gravity_torques` answers: a diagnosis asks for the same poses' torques
#: for every loaded joint's compliance and backlash, and each costs a Pinocchio call per pose. A
#: large problem asks block by block (:mod:`pincal.identify.chunked`), so what is kept is bounded
#: by rows (every block of a million poses is kept), not by answers.
_GRAVITY: list[tuple[Robot, Payload | None, bytes, np.ndarray]] = []
#: Rows of torques kept at most (48 MB for a 6-joint arm).
_GRAVITY_ROWS = 1_000_000
#: Answers kept at most.
_GRAVITY_KEPT = 64


def gravity_torques(robot: Robot, q: np.ndarray, payload: Payload | None = None) -> np.ndarray:
    """Gravity torque each chain joint carries [N·m or N] at configurations ``q`` (N, n), from the
    URDF's inertias and an optional payload on the tip."""
    key = np.ascontiguousarray(np.atleast_2d(q), dtype=float).tobytes()
    for k, (known, load, at, torques) in enumerate(_GRAVITY):
        if known is robot and load == payload and at == key:
            _GRAVITY.insert(0, _GRAVITY.pop(k))  # the most recently used first
            return torques.copy()
    torques = _gravity_torques(robot, q, payload)
    _GRAVITY.insert(0, (robot, payload, key, torques.copy()))
    rows = np.cumsum([len(entry[3]) for entry in _GRAVITY])
    del _GRAVITY[max(1, min(_GRAVITY_KEPT, int(np.searchsorted(rows, _GRAVITY_ROWS, side="right")))) :]
    return torques


def _gravity_torques(robot: Robot, q: np.ndarray, payload: Payload | None) -> np.ndarray:
    model = robot.model
    if payload is not None and payload.mass > 0:
        model = pin.Model(robot.model)  # a copy: the robot's own model is not changed
        tip = model.frames[robot.tip_frame_id]
        com = tip.placement.act(np.array(payload.com))
        model.inertias[tip.parentJoint] += pin.Inertia(payload.mass, com, np.zeros((3, 3)))
    data = model.createData()
    configurations = robot.configurations(np.atleast_2d(q))
    out = np.empty((len(configurations), model.nv))
    for i, config in enumerate(configurations):
        out[i] = pin.computeGeneralizedGravity(model, data, config)
    return out.reshape(np.shape(np.atleast_2d(q)))


def massless(robot: Robot) -> bool:
    """True when no body of the chain has a mass: the URDF has no ``<inertial>`` (gravity
    torques, and with them compliance and backlash, are then zero)."""
    return sum(inertia.mass for inertia in robot.model.inertias) <= 0.0
