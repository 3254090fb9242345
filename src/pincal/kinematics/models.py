"""Parameterizations of the geometric errors (``--model``): placements, poe, offsets (and mdh).

Each model maps a parameter vector ``x`` (zero = the URDF's nominal geometry) to a
:class:`~pincal.kinematics.chain.Chain`, and gives the local twists through which every parameter acts
on that chain (see :mod:`pincal.kinematics.chain`), from which the tip Jacobian follows. The measured
point or frame on the tip (the *tool*) and the instrument registration belong to the
measurement model (:mod:`pincal.identify.measurements`), not to these.

- ``placements``: ``C_j = C⁰_j · exp(δ_j)``, a 6-DoF correction of each joint's URDF origin in
  the joint's own frame; δ = (tx, ty, tz [m], rx, ry, rz [rad]) as a twist (``pin.exp6``).
- ``offsets``: joint zero offsets ``q_j + o_j`` [rad or m].
- ``poe``: twists ``ξ_j = Ad(exp η_j) ξ⁰_j`` (Gao et al. 2013, eqs. 3-4): every twist keeps
  its constraints (|ω| = 1, ω·v = 0) for any η, and a correction ``δη`` composes as
  ``Ad(exp δη) ξ`` to first order. The tip stays where the URDF puts it on the last link, so
  the home transform is ``M = G_n · C⁰_n`` (it moves with the last joint's frame, which is what
  lets a URDF hold the result); the tool point (``p_E0 = M · p``) is the measurement's.
- ``mdh``: see :mod:`pincal.kinematics.mdh`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import pinocchio as pin

from pincal.kinematics.chain import Chain
from pincal.kinematics.twists import Twists, left_jacobian, nominal_twists
from pincal.robot.robots import Robot

_PLACEMENT_COMPONENTS = (("tx", "m"), ("ty", "m"), ("tz", "m"), ("rx", "rad"), ("ry", "rad"), ("rz", "rad"))


@dataclass(frozen=True, eq=False)
class Model(ABC):
    """A parameterization of a robot's chain.

    Attributes:
        robot: the robot whose chain is parameterized.
        names: parameter names, ``<joint>.<component>``.
        units: unit of each parameter (``m`` or ``rad``).
        held: parameters held at zero by the model's own rule, with the reason (name -> reason).
    """

    robot: Robot
    names: tuple[str, ...] = field(init=False)
    units: tuple[str, ...] = field(init=False)
    held: dict[str, str] = field(init=False, default_factory=dict)

    kind: str = "model"

    @property
    def n_params(self) -> int:
        """Number of parameters."""
        return len(self.names)

    @abstractmethod
    def chain(self, x: np.ndarray) -> Chain:
        """The chain for parameters ``x``."""

    @abstractmethod
    def twists(self, x: np.ndarray) -> np.ndarray:
        """Local twists (2n + 1, 6, n_params) of each parameter at each chain position."""

    def _set(self, names: list[str], units: list[str]) -> None:
        object.__setattr__(self, "names", tuple(names))
        object.__setattr__(self, "units", tuple(units))


@dataclass(frozen=True, eq=False)
class PlacementsModel(Model):
    """6-DoF corrections of each joint's URDF origin, in the joint's own frame."""

    kind: str = "placements"

    def __post_init__(self) -> None:
        names, units = [], []
        for joint in self.robot.joint_names:
            for comp, unit in _PLACEMENT_COMPONENTS:
                names.append(f"{joint}.{comp}")
                units.append(unit)
        self._set(names, units)

    def chain(self, x: np.ndarray) -> Chain:
        nominal = self.robot.placements
        n = self.robot.n_joints
        placements = [nominal[j] * pin.exp6(pin.Motion(x[6 * j : 6 * j + 6])) for j in range(n)]
        if self.robot.is_tree:
            return Chain.nominal(self.robot).with_joints(placements)
        return Chain((*placements, nominal[n]), self.robot.axes)

    def twists(self, x: np.ndarray) -> np.ndarray:
        n = self.robot.n_joints
        out = np.zeros((2 * n + 1, 6, self.n_params))
        for j in range(n):
            out[2 * j, :, 6 * j : 6 * j + 6] = pin.Jexp6(pin.Motion(x[6 * j : 6 * j + 6]))
        return out


@dataclass(frozen=True, eq=False)
class OffsetsModel(Model):
    """Joint zero offsets: the robot reaches ``q + o`` when commanded ``q``."""

    kind: str = "offsets"

    def __post_init__(self) -> None:
        names = [f"{j}.offset" for j in self.robot.joint_names]
        units = ["m" if p else "rad" for p in self.robot.prismatic]
        self._set(names, units)

    def chain(self, x: np.ndarray) -> Chain:
        nominal, axes = self.robot.placements, self.robot.axes
        placements = [nominal[j] * pin.exp6(pin.Motion(axes[j] * x[j])) for j in range(len(x))]
        if self.robot.is_tree:
            return Chain.nominal(self.robot).with_joints(placements)
        return Chain((*placements, nominal[-1]), axes)

    def twists(self, x: np.ndarray) -> np.ndarray:
        n = self.robot.n_joints
        out = np.zeros((2 * n + 1, 6, n))
        for j in range(n):
            out[2 * j, :, j] = self.robot.axes[j]
        return out


@dataclass(frozen=True, eq=False)
class PoeModel(Model):
    """Product of exponentials with adjoint-transformed twists (Gao et al. 2013)."""

    kind: str = "poe"

    def __post_init__(self) -> None:
        names, units = [], []
        for joint in self.robot.joint_names:
            for comp, unit in (
                ("eta_vx", "m"),
                ("eta_vy", "m"),
                ("eta_vz", "m"),
                ("eta_wx", "rad"),
                ("eta_wy", "rad"),
                ("eta_wz", "rad"),
            ):
                names.append(f"{joint}.{comp}")
                units.append(unit)
        self._set(names, units)

    @cached_property
    def nominal(self) -> Twists:
        """The nominal twists, joint frames ``G⁰_j`` and home transform."""
        return nominal_twists(self.robot)

    def joint_frames(self, x: np.ndarray) -> list[pin.SE3]:
        """``G_j = exp(η_j) · G⁰_j``: frames whose local joint twist maps to ``ξ_j``."""
        nominal = self.nominal.joint_frames
        return [pin.exp6(pin.Motion(x[6 * j : 6 * j + 6])) * g for j, g in enumerate(nominal)]

    def joint_twists(self, x: np.ndarray) -> np.ndarray:
        """Base-frame joint twists ``ξ_j = Ad(exp η_j) ξ⁰_j`` (n, 6), order (v, ω)."""
        frames = self.joint_frames(x)
        return np.array([g.act(pin.Motion(s)).vector for g, s in zip(frames, self.robot.axes)])

    def chain(self, x: np.ndarray) -> Chain:
        prev = pin.SE3.Identity()
        placements = []
        for g in self.joint_frames(x):
            placements.append(prev.actInv(g))
            prev = g
        placements.append(self.robot.placements[-1])
        return Chain(tuple(placements), self.robot.axes)

    def twists(self, x: np.ndarray) -> np.ndarray:
        n = self.robot.n_joints
        out = np.zeros((2 * n + 1, 6, self.n_params))
        for j, g in enumerate(self.joint_frames(x)):
            local = g.inverse().action @ left_jacobian(x[6 * j : 6 * j + 6])
            out[2 * j, :, 6 * j : 6 * j + 6] = local
            if j < n - 1:  # the next placement G_j⁻¹ G_{j+1} holds G_j too; the tip's does not
                out[2 * j + 1, :, 6 * j : 6 * j + 6] = -local
        return out
