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
- ``backlash``: ``b · sign(τ_j(q))``, the flank of the gear play gravity pushes the joint to [rad];
- ``lost_motion``: ``v · s_j``, the reversal error: ``s_j`` is +1 when the joint's command rose
  from the previous row, -1 when it fell, the previous row's when it did not move (it stays on
  its flank), 0 on the first row [rad]. Rows are taken in the order the robot visited them
  (:func:`move_directions`).

Each kind is one class (:class:`Effect`): its parameter names and units and its regressors.
Several effects at once (on several joints, of several kinds) are an :class:`Effects`, which
presents the same interface as one :class:`Extension`.

For a prismatic joint the same hold in metres and newtons.

Gravity torques and the payload are :mod:`pincal.kinematics.gravity`'s; whether an identified
effect can be what it is named, :mod:`pincal.kinematics.stiffness`'s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pincal.data.directions import STILL, move_directions
from pincal.errors import DataError
from pincal.kinematics.gravity import Payload, gravity_torques
from pincal.robot.robots import Robot


class Effect:
    """One kind of non-geometric effect: its parameters and the regressors of one joint.

    Attributes:
        name: the effect's name in the sidecar and on the command line.
        loaded: it follows the gravity torque (only joints that gravity loads are candidates).
    """

    name = ""
    loaded = False

    def suffixes(self, harmonic: int) -> tuple[str, ...]:
        """The parameters' names after ``JOINT.``."""
        raise NotImplementedError

    def units(self, angle: str, load: str) -> tuple[str, ...]:
        """The parameters' units, for a joint measured in ``angle`` (rad or m) under ``load``."""
        raise NotImplementedError

    def regressors(self, ext: Extension, q: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """``r_k`` (N, k) at commands ``q`` (N, n) reached moving in ``directions`` (N, n)."""
        raise NotImplementedError


class Compliance(Effect):
    """``c · τ_j(q)``: the joint deflects in proportion to the gravity torque it carries."""

    name, loaded = "joint_compliance", True

    def suffixes(self, harmonic: int) -> tuple[str, ...]:
        return ("compliance",)

    def units(self, angle: str, load: str) -> tuple[str, ...]:
        return (f"{angle}/{load}",)

    def regressors(self, ext: Extension, q: np.ndarray, directions: np.ndarray) -> np.ndarray:
        return gravity_torques(ext.robot, q, ext.payload)[:, ext.index, None]


class GearHarmonic(Effect):
    """``a · sin(h q_j) + b · cos(h q_j)``: a periodic transmission error of order ``h``."""

    name = "gear_harmonic"

    def suffixes(self, harmonic: int) -> tuple[str, ...]:
        return (f"sin{harmonic}", f"cos{harmonic}")

    def units(self, angle: str, load: str) -> tuple[str, ...]:
        return (angle, angle)

    def regressors(self, ext: Extension, q: np.ndarray, directions: np.ndarray) -> np.ndarray:
        qj = ext.harmonic * q[:, ext.index]
        return np.column_stack([np.sin(qj), np.cos(qj)])


class EncoderScale(Effect):
    """``s · (q_j - q_mid)``: a gear-ratio or encoder scale error, about the range's middle."""

    name = "encoder_scale"

    def suffixes(self, harmonic: int) -> tuple[str, ...]:
        return ("scale",)

    def units(self, angle: str, load: str) -> tuple[str, ...]:
        return (f"{angle}/{angle}",)

    def regressors(self, ext: Extension, q: np.ndarray, directions: np.ndarray) -> np.ndarray:
        lo, hi = ext.robot.lower[ext.index], ext.robot.upper[ext.index]
        middle = 0.5 * (lo + hi) if np.isfinite(lo) and np.isfinite(hi) and hi - lo < 1e6 else 0.0
        return (q[:, ext.index] - middle)[:, None]


class Backlash(Effect):
    """``b · sign(τ_j(q))``: the flank of the gear play that gravity pushes the joint to."""

    name, loaded = "backlash", True

    def suffixes(self, harmonic: int) -> tuple[str, ...]:
        return ("backlash",)

    def units(self, angle: str, load: str) -> tuple[str, ...]:
        return (angle,)

    def regressors(self, ext: Extension, q: np.ndarray, directions: np.ndarray) -> np.ndarray:
        torque = gravity_torques(ext.robot, q, ext.payload)[:, ext.index]
        return (np.sign(torque) * (np.abs(torque) > STILL))[:, None]


class LostMotion(Effect):
    """``v · s_j``: the reversal error, an offset that follows the direction the joint last moved."""

    name = "lost_motion"

    def suffixes(self, harmonic: int) -> tuple[str, ...]:
        return ("lost_motion",)

    def units(self, angle: str, load: str) -> tuple[str, ...]:
        return (angle,)

    def regressors(self, ext: Extension, q: np.ndarray, directions: np.ndarray) -> np.ndarray:
        return directions[:, ext.index, None].astype(float)


#: Every effect kind by name.
KINDS: dict[str, Effect] = {
    kind.name: kind for kind in (Compliance(), GearHarmonic(), EncoderScale(), Backlash(), LostMotion())
}
EFFECTS = tuple(KINDS)


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
        if not 1 <= self.harmonic <= 8:
            raise DataError(f"harmonic {self.harmonic}: a gear harmonic's order is 1 to 8")

    @classmethod
    def parse(cls, robot: Robot, text: str, payload: Payload | None = None) -> Extension:
        """From ``EFFECT:JOINT`` (``gear_harmonic2:JOINT`` for the second harmonic)."""
        effect, sep, joint = text.partition(":")
        if not sep:
            raise DataError(
                f"extension={text!r}: write EFFECT:JOINT, for example joint_compliance:{robot.joint_names[1]}"
            )
        if effect.startswith("gear_harmonic") and effect[13:].isdigit():
            return cls(robot, "gear_harmonic", joint, int(effect[13:]), payload)
        return cls(robot, effect, joint, 1, payload)

    @property
    def kind(self) -> Effect:
        """The effect's kind."""
        return KINDS[self.effect]

    @property
    def parts(self) -> tuple[Extension, ...]:
        """The single effects this is made of: itself."""
        return (self,)

    def on(self, robot: Robot) -> Extension:
        """The same effect on ``robot`` (its gravity torques computed on that chain)."""
        return Extension(robot, self.effect, self.joint, self.harmonic, self.payload)

    @property
    def label(self) -> str:
        """``EFFECT:JOINT`` as :meth:`parse` reads it."""
        suffix = str(self.harmonic) if self.effect == "gear_harmonic" and self.harmonic != 1 else ""
        return f"{self.effect}{suffix}:{self.joint}"

    @property
    def index(self) -> int:
        """Position of the joint in the chain."""
        return self.robot.joint_names.index(self.joint)

    @property
    def names(self) -> tuple[str, ...]:
        """Parameter names."""
        return tuple(f"{self.joint}.{s}" for s in self.kind.suffixes(self.harmonic))

    @property
    def units(self) -> tuple[str, ...]:
        """Parameter units."""
        prismatic = self.robot.prismatic[self.index]
        return self.kind.units("m" if prismatic else "rad", "N" if prismatic else "N·m")

    @property
    def n_params(self) -> int:
        """Number of parameters."""
        return len(self.names)

    @property
    def param_joints(self) -> np.ndarray:
        """The chain index of the joint each parameter moves (n_params,)."""
        return np.full(self.n_params, self.index)

    def regressors(self, q: np.ndarray, directions: np.ndarray | None = None) -> np.ndarray:
        """The regressors ``r_k`` (N, n_params) at commanded configurations (N, n), the joints
        moving in ``directions`` (N, n; default: the rows' order, :func:`move_directions`)."""
        q = np.atleast_2d(q)
        moves = move_directions(q) if directions is None else np.atleast_2d(directions)
        return self.kind.regressors(self, q, moves)

    def joint_error(self, q: np.ndarray, p: np.ndarray, directions: np.ndarray | None = None) -> np.ndarray:
        """The joint-value error each pose reaches: (N, n), zero but for this joint."""
        out = np.zeros_like(np.atleast_2d(q), dtype=float)
        out[:, self.index] = self.regressors(q, directions) @ p
        return out


@dataclass(frozen=True, eq=False)
class Effects:
    """Several effects at once (each on its joint), with the interface of one :class:`Extension`:
    their parameters one after the other, their joint errors summed."""

    parts: tuple[Extension, ...]

    def __post_init__(self) -> None:
        labels = [e.label for e in self.parts]
        if len(self.parts) < 2 or len(set(labels)) < len(labels):
            raise DataError(f"several effects are at least two different ones, not {', '.join(labels)}")

    @property
    def robot(self) -> Robot:
        """The robot (the first part's)."""
        return self.parts[0].robot

    def on(self, robot: Robot) -> Effects:
        """The same effects on ``robot``."""
        return Effects(tuple(e.on(robot) for e in self.parts))

    @property
    def payload(self) -> Payload | None:
        """The load on the tip (the first loaded part's)."""
        return next((e.payload for e in self.parts if e.payload is not None), None)

    @property
    def label(self) -> str:
        """The parts' labels joined by ``+``."""
        return "+".join(e.label for e in self.parts)

    @property
    def names(self) -> tuple[str, ...]:
        """Every part's parameter names."""
        return tuple(n for e in self.parts for n in e.names)

    @property
    def units(self) -> tuple[str, ...]:
        """Every part's parameter units."""
        return tuple(u for e in self.parts for u in e.units)

    @property
    def n_params(self) -> int:
        """Number of parameters."""
        return len(self.names)

    @property
    def param_joints(self) -> np.ndarray:
        """The chain index of the joint each parameter moves."""
        return np.concatenate([e.param_joints for e in self.parts])

    def regressors(self, q: np.ndarray, directions: np.ndarray | None = None) -> np.ndarray:
        """Every part's regressors side by side (N, n_params)."""
        moves = move_directions(q) if directions is None else directions
        return np.hstack([e.regressors(q, moves) for e in self.parts])

    def joint_error(self, q: np.ndarray, p: np.ndarray, directions: np.ndarray | None = None) -> np.ndarray:
        """The joint-value errors of every part, summed (N, n)."""
        moves = move_directions(q) if directions is None else directions
        bounds = np.cumsum([0, *(e.n_params for e in self.parts)])
        return sum(
            (e.joint_error(q, p[a:b], moves) for e, a, b in zip(self.parts, bounds[:-1], bounds[1:])),
            np.zeros_like(np.atleast_2d(q), dtype=float),
        )


#: One effect or several.
AnyEffect = Extension | Effects


def combined(parts: tuple[Extension, ...] | list[Extension]) -> AnyEffect | None:
    """None, the one effect, or :class:`Effects` of several."""
    parts = tuple(parts)
    return None if not parts else parts[0] if len(parts) == 1 else Effects(parts)


def split_params(effect: AnyEffect, p: np.ndarray) -> list[tuple[Extension, np.ndarray]]:
    """Each single effect with its parameters, from the parameters ``p`` of ``effect``."""
    out, k = [], 0
    for e in effect.parts:
        out.append((e, np.asarray(p[k : k + e.n_params], dtype=float)))
        k += e.n_params
    return out


def candidates(robot: Robot, payload: Payload | None = None) -> list[Extension]:
    """Every effect on every joint (both gear harmonics); compliance and backlash only where
    gravity loads the joint (a vertical first axis carries no gravity torque)."""
    out = []
    probe = robot.random_configurations(50, np.random.default_rng(0))
    loaded = np.abs(gravity_torques(robot, probe, payload)).max(axis=0) > 1e-6
    for j, joint in enumerate(robot.joint_names):
        for effect, kind in KINDS.items():
            if kind.loaded and not loaded[j]:
                continue
            for h in (1, 2) if effect == "gear_harmonic" else (1,):
                out.append(Extension(robot, effect, joint, h, payload))
    return out
