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

A compliance as a stiffness (:func:`compliance_stiffness`). ``τ`` is the torque the motor holds
against gravity; an elastic joint's link lags its motor by ``τ / K`` (link angle = motor angle
- ``τ / K``, stiffness ``K > 0``), so a joint that sags under its load has ``c = -1/K < 0``. A
coefficient is *plausible* as a stiffness when (1) the joint sags (``K > 0``; ``c > 0`` would
make it rise against its load) and (2) its deflection at the largest gravity torque it carries
over the data, ``|c| · max |τ_j|``, lies within :data:`PLAUSIBLE_DEFLECTION` (0.01 to 20 mrad).
Why: harmonic-drive and cycloidal gearboxes of any size deflect about 1-2 mrad at their rated
torque (catalogue torsional stiffness ÷ rated torque), cobot joints with torque sensors up to a
few mrad; gravity loads a joint at most to about its rated torque. Relating ``K`` to the load the
joint actually carries makes the range independent of the joint's size, where a range of ``K``
itself would not be (a wrist's 500 N·m/rad and a shoulder's 50 000 N·m/rad are both real).
Below 0.01 mrad the effect is far below what position data can identify; above 20 mrad (over
1°) no working arm sags. An implausible coefficient still locates an error that follows the
load (wrong URDF inertias, a payload left out, a bent link...), but not an elasticity. For a
prismatic joint the same rule holds in metres: :data:`PLAUSIBLE_DEFLECTION_PRISMATIC`, 1 µm to
1 mm (linear axes on ball screws or belts).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from pincal.data.directions import STILL, move_directions
from pincal.errors import DataError
from pincal.robot.robots import Robot

#: Deflection of a revolute joint at its largest gravity torque that a real joint shows [rad].
PLAUSIBLE_DEFLECTION = (1e-5, 2e-2)
#: The same for a prismatic joint [m].
PLAUSIBLE_DEFLECTION_PRISMATIC = (1e-6, 1e-3)
#: The least stiffness a real joint has [N·m/rad; N/m for a prismatic joint]: the smallest
#: harmonic drives are stiffer than 100 N·m/rad, hobby servos about 20; below it, an error that
#: follows the load is something else (a bent tool on an unloaded wrist, wrong inertias).
LEAST_STIFFNESS = (20.0, 2e4)
#: The largest joint error an effect other than compliance plausibly makes over the data [rad;
#: m for a prismatic joint]: gear transmission errors, backlash and encoder scale errors of
#: working arms stay below about 1 degree (harmonic drives: arc-minutes).
PLAUSIBLE_JOINT_ERROR = (2e-2, 2e-3)


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
#: for every loaded joint's compliance and backlash, and each costs a Pinocchio call per pose.
_GRAVITY: list[tuple[Robot, Payload | None, bytes, np.ndarray]] = []
_GRAVITY_KEPT = 4


def gravity_torques(robot: Robot, q: np.ndarray, payload: Payload | None = None) -> np.ndarray:
    """Gravity torque each chain joint carries [N·m or N] at configurations ``q`` (N, n), from the
    URDF's inertias and an optional payload on the tip."""
    key = np.ascontiguousarray(np.atleast_2d(q), dtype=float).tobytes()
    for known, load, at, torques in _GRAVITY:
        if known is robot and load == payload and at == key:
            return torques.copy()
    torques = _gravity_torques(robot, q, payload)
    _GRAVITY.insert(0, (robot, payload, key, torques.copy()))
    del _GRAVITY[_GRAVITY_KEPT:]
    return torques


def _gravity_torques(robot: Robot, q: np.ndarray, payload: Payload | None) -> np.ndarray:
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


def massless(robot: Robot) -> bool:
    """True when no body of the chain has a mass: the URDF has no ``<inertial>`` (gravity
    torques, and with them compliance and backlash, are then zero)."""
    return sum(inertia.mass for inertia in robot.model.inertias) <= 0.0


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


@dataclass(frozen=True)
class Stiffness:
    """A ``joint_compliance`` coefficient read as a joint stiffness (see the module docstring).

    Attributes:
        coefficient: ``c`` [rad/(N·m), or m/N for a prismatic joint].
        stiffness: ``K = -1/c`` [N·m/rad or N/m]; inf when ``c == 0``.
        max_torque: largest ``|τ_j|`` over the data [N·m or N].
        deflection: ``|c| · max_torque``, how far the joint deflects at its largest load [rad or m].
        sags: the joint yields to its load, ``0 < K < inf`` (``c < 0``).
        plausible: it sags and its deflection is within :data:`PLAUSIBLE_DEFLECTION` (or
            :data:`PLAUSIBLE_DEFLECTION_PRISMATIC`).
        verdict: one short sentence.
        prismatic: the joint is prismatic (units N/m, m and N).
    """

    coefficient: float
    stiffness: float
    max_torque: float
    deflection: float
    sags: bool
    plausible: bool
    verdict: str
    prismatic: bool = False

    @property
    def unit(self) -> str:
        """Unit of :attr:`stiffness`."""
        return "N/m" if self.prismatic else "N·m/rad"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (no inf or NaN: an infinite ``K`` is None)."""
        k = self.stiffness
        return {
            "coefficient": self.coefficient,
            "K": k if np.isfinite(k) else None,
            "unit_K": self.unit,
            "max_torque": self.max_torque,
            "deflection": self.deflection,
            "sags": self.sags,
            "plausible": self.plausible,
            "verdict": self.verdict,
        }


def compliance_stiffness(extension: Extension, coefficient: float, q: np.ndarray) -> Stiffness:
    """Read a ``joint_compliance`` coefficient as a stiffness, over the commanded configurations
    ``q`` (N, n) of the data (for the largest gravity torque the joint carries)."""
    if extension.effect != "joint_compliance":
        raise ValueError(f"{extension.label} is no joint_compliance")
    c = float(coefficient)
    prismatic = bool(extension.robot.prismatic[extension.index])
    torque = float(np.abs(extension.regressors(q)).max()) if len(np.atleast_2d(q)) else 0.0
    k = -1.0 / c if c != 0 else np.inf
    deflection = abs(c) * torque
    lo, hi = PLAUSIBLE_DEFLECTION_PRISMATIC if prismatic else PLAUSIBLE_DEFLECTION
    sags = c < 0
    stiff = k >= LEAST_STIFFNESS[1 if prismatic else 0]
    plausible = sags and stiff and lo <= deflection <= hi
    # Deflections in mrad (or mm), torques in N·m (or N).
    unit_k, unit_d, unit_t = ("N/m", "mm", "N") if prismatic else ("N·m/rad", "mrad", "N·m")
    shown = f"{_short(deflection * 1e3)} {unit_d}"
    if torque == 0:
        verdict = "no stiffness: the joint carries no gravity torque over the data"
    elif c == 0:
        verdict = "no deflection under gravity (c = 0): infinitely stiff"
    elif not sags:
        verdict = (
            f"implausible as a stiffness: the joint would rise against its load (K = {k:.3g} {unit_k}"
            " < 0); an error that follows the load, not an elasticity"
        )
    elif not stiff and deflection <= hi:
        verdict = (
            f"implausible as a stiffness: K = {k:.3g} {unit_k} is below any real joint's "
            f"({LEAST_STIFFNESS[1 if prismatic else 0]:g} {unit_k}); an error that follows the load "
            "(a bent tool, wrong inertias), not an elasticity"
        )
    elif plausible:
        verdict = (
            f"sags under gravity: K = {k:.3g} {unit_k} "
            f"(deflects {shown} at its largest load, {_short(torque)} {unit_t})"
        )
    else:
        why = "another error follows the load" if deflection > hi else "the effect is too small to identify"
        verdict = (
            f"implausible as a stiffness: K = {k:.3g} {unit_k} deflects {shown} at its largest load "
            f"(plausible: {lo * 1e3:g}–{hi * 1e3:g} {unit_d}); the URDF's inertias may be wrong, or {why}"
        )
    return Stiffness(c, k, torque, deflection, sags, plausible, verdict, prismatic)


def _short(x: float) -> str:
    """Two significant digits, without an exponent up to 10⁵."""
    return f"{x:.2g}" if x < 100 or x >= 1e5 else f"{x:.0f}"


def implausible(extension: Extension, params: np.ndarray, q: np.ndarray) -> str | None:
    """Why an identified effect cannot be what it is named (None: plausible) over the commanded
    configurations ``q`` (N, n): a compliance must read as a stiffness (:func:`compliance_stiffness`),
    any other effect must move its joint by less than :data:`PLAUSIBLE_JOINT_ERROR`."""
    if extension.effect == "joint_compliance":
        stiffness = compliance_stiffness(extension, float(params[0]), q)
        return None if stiffness.plausible else stiffness.verdict
    prismatic = bool(extension.robot.prismatic[extension.index])
    largest = float(np.abs(extension.regressors(q) @ np.asarray(params, float)).max()) if len(q) else 0.0
    bound, unit = PLAUSIBLE_JOINT_ERROR[1 if prismatic else 0], "mm" if prismatic else "mrad"
    if largest <= bound:
        return None
    return (
        f"implausible as {extension.effect.replace('_', ' ')}: it moves {extension.joint} by up to "
        f"{largest * 1e3:.3g} {unit} (a working arm's: below {bound * 1e3:g} {unit}); "
        "an error of another kind follows this variable"
    )
