"""Modified Denavit-Hartenberg with Hayati's β, converted from any URDF chain.

Frames ``F_j`` have z along joint ``j``'s axis and x along the common normal to the next axis
(Craig's convention). Between consecutive frames

    F_j = F_{j-1} · Rx(α_j) · Tx(a_j) · Ry(β_j) · Rz(θ_j + q_j) · Tz(d_j)

(``q_j`` enters ``d_j`` instead for a prismatic joint). Hayati's β is used where consecutive
axes are parallel or nearly so (within :data:`PARALLEL_TOL`), where the common normal is
ill-defined or far away and DH alone is not continuous; elsewhere it is held at zero. There the
x axis points to where the next axis crosses the plane normal to this one, and α with a nominal
β tilts z onto the next axis: β is 0 for exactly parallel axes and a few mrad for a URDF that
was calibrated before (instead of a common normal half a metre away), so every chain converts
exactly. The first frame ``F_0`` sits on joint 0's axis; a 6-DoF ``base`` correction (a
twist, like ``placements``) places it, and the tip is a constant transform from ``F_{n-1}``.
Parameters are errors added to the nominal a [m], α [rad], d [m], θ [rad], β [rad].
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from pincal.errors import DataError, PincalError
from pincal.kinematics.chain import Chain, right_twists
from pincal.kinematics.models import Model, OffsetsModel, PlacementsModel, PoeModel
from pincal.kinematics.twists import chain_twists
from pincal.options import MODELS
from pincal.robot.robots import Robot

#: Consecutive axes closer than this to parallel get Hayati's β [rad].
PARALLEL_TOL = 0.05
_COMPONENTS = (("a", "m"), ("alpha", "rad"), ("d", "m"), ("theta", "rad"), ("beta", "rad"))
_EX_V = np.array([1.0, 0, 0, 0, 0, 0])
_EZ_V = np.array([0, 0, 1.0, 0, 0, 0])
_EX_W = np.array([0, 0, 0, 1.0, 0, 0])
_EY_W = np.array([0, 0, 0, 0, 1.0, 0])
_EZ_W = np.array([0, 0, 0, 0, 0, 1.0])


class MdhTable(NamedTuple):
    """Nominal modified DH description of a chain.

    Attributes:
        a, alpha, d, theta, beta: (n,) nominal parameters [m, rad, m, rad, rad]; row ``j`` maps
            ``F_{j-1}`` to ``F_j`` (row 0 is zero: ``F_0`` is the base frame of the DH chain);
            β is non-zero only where the axes are nearly, not exactly, parallel.
        parallel: (n,) whether axis ``j`` is (nearly) parallel to axis ``j-1`` (row 0: True).
        base: ``base_T_F0``.
        tool: ``F_{n-1}_T_tip``.
    """

    a: np.ndarray
    alpha: np.ndarray
    d: np.ndarray
    theta: np.ndarray
    beta: np.ndarray
    parallel: np.ndarray
    base: pin.SE3
    tool: pin.SE3


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _perpendicular(z: np.ndarray, hint: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to ``z``, as close as possible to ``hint``."""
    for candidate in (hint, np.array([1.0, 0, 0]), np.array([0, 1.0, 0])):
        p = candidate - (candidate @ z) * z
        if np.linalg.norm(p) > 1e-9:
            return _unit(p)
    raise AssertionError("unreachable")  # pragma: no cover


def _nearly_parallel(z: np.ndarray, z_next: np.ndarray) -> bool:
    """Whether two unit axis directions are within :data:`PARALLEL_TOL` of (anti)parallel."""
    return bool(np.linalg.norm(np.cross(z, z_next)) < np.sin(PARALLEL_TOL))


def _common_normal(
    origin: np.ndarray, z: np.ndarray, p_next: np.ndarray, z_next: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The common normal's feet on axis ``(origin, z)`` and on axis ``(p_next, z_next)``, for
    axes that are not (nearly) parallel."""
    w = origin - p_next
    b, dd, ee = z @ z_next, z @ w, z_next @ w
    denom = 1.0 - b * b
    return origin + ((b * ee - dd) / denom) * z, p_next + ((ee - b * dd) / denom) * z_next


def mdh_table(chain: Chain) -> MdhTable:
    """Convert a chain (URDF joint origins and axes) to modified DH with Hayati's β.

    Where consecutive axes are skew or intersecting, frame ``j``'s x runs along their common
    normal (β = 0). Where they are parallel or nearly so (:data:`PARALLEL_TOL`), the common normal
    is far away or undefined: frame ``j`` keeps its origin, x points to where the next axis crosses
    the plane normal to axis ``j`` through that origin, and α and a nominal β tilt z onto the next
    axis (Hayati). The table reproduces the chain exactly either way, so a URDF calibrated once
    (axes parallel to a few mrad, not exactly) converts like the nominal one.
    """
    tw = chain_twists(chain)
    n = len(tw.joint_frames)
    points = [g.translation for g in tw.joint_frames]
    dirs = []
    for g, s in zip(tw.joint_frames, chain.axes):
        dirs.append(_unit(g.rotation @ (s[3:] if np.any(s[3:]) else s[:3])))
    origins, xs = [], []
    origin = points[0]
    x_prev = _perpendicular(dirs[0], np.array([1.0, 0, 0]))
    parallel = np.ones(n, dtype=bool)
    for j in range(n):
        z = dirs[j]
        foot = origin
        if j < n - 1:
            z_next, p_next = dirs[j + 1], points[j + 1]
            parallel[j + 1] = _nearly_parallel(z, z_next)
            if not parallel[j + 1]:  # skew or intersecting: unique common normal
                origin, foot = _common_normal(origin, z, p_next, z_next)
                gap = foot - origin
                x = _unit(gap) if np.linalg.norm(gap) > 1e-9 else _unit(np.cross(z, z_next))
            else:  # (nearly) parallel: keep the origin, go to the next axis in the normal plane
                foot = p_next - (((p_next - origin) @ z) / (z_next @ z)) * z_next
                gap = foot - origin
                gap = gap - (gap @ z) * z  # zero already, up to rounding
                x = _unit(gap) if np.linalg.norm(gap) > 1e-9 else _perpendicular(z, x_prev)
        else:
            x = _perpendicular(z, x_prev)
        origins.append(origin)
        xs.append(x)
        x_prev = x
        origin = foot  # the next frame's origin starts at the foot on the next axis
    frames = [pin.SE3(np.column_stack([x, np.cross(z, x), z]), o) for x, z, o in zip(xs, dirs, origins)]
    a, alpha, d, theta, beta = (np.zeros(n) for _ in range(5))
    for j in range(1, n):
        rel = frames[j - 1].actInv(frames[j])
        z_rel = rel.rotation[:, 2]  # (sin β, -sin α cos β, cos α cos β)
        alpha[j] = np.arctan2(-z_rel[1], z_rel[2])
        if parallel[j]:
            beta[j] = np.arctan2(z_rel[0], np.hypot(z_rel[1], z_rel[2]))
        u = _rx(alpha[j]).actInv(rel).translation  # (a + d sin β, 0, d cos β)
        a[j] = u[0] - u[2] * np.tan(beta[j])
        rest = (_rx(alpha[j]) * _tx(a[j]) * _ry(beta[j])).actInv(rel)  # Rz(θ) Tz(d)
        theta[j] = np.arctan2(rest.rotation[1, 0], rest.rotation[0, 0])
        d[j] = rest.translation[2]
    return MdhTable(a, alpha, d, theta, beta, parallel, frames[0], frames[-1].actInv(tw.home))


def _rx(angle: float) -> pin.SE3:
    return pin.exp6(pin.Motion(_EX_W * angle))


def _ry(angle: float) -> pin.SE3:
    return pin.exp6(pin.Motion(_EY_W * angle))


def _rz(angle: float) -> pin.SE3:
    return pin.exp6(pin.Motion(_EZ_W * angle))


def _tx(dist: float) -> pin.SE3:
    return pin.SE3(np.eye(3), np.array([dist, 0.0, 0.0]))


def _tz(dist: float) -> pin.SE3:
    return pin.SE3(np.eye(3), np.array([0.0, 0.0, dist]))


@dataclass(frozen=True, eq=False)
class MdhModel(Model):
    """Modified DH + Hayati's β: 6 base parameters, then (a, α, d, θ, β) errors per joint."""

    kind: str = "mdh"

    def __post_init__(self) -> None:
        names = [f"base.{c}" for c in ("tx", "ty", "tz", "rx", "ry", "rz")]
        units = ["m"] * 3 + ["rad"] * 3
        held = {}
        for j, joint in enumerate(self.robot.joint_names):
            for comp, unit in _COMPONENTS:
                names.append(f"{joint}.{comp}")
                units.append(unit)
            if not self.table.parallel[j]:
                held[f"{joint}.beta"] = "Hayati's beta is used only where consecutive axes are parallel"
        self._set(names, units)
        object.__setattr__(self, "held", held)

    @cached_property
    def table(self) -> MdhTable:
        """The nominal DH table of the robot's chain."""
        return mdh_table(Chain.nominal(self.robot))

    def _factors(self, x: np.ndarray) -> list[list[pin.SE3]]:
        t = self.table
        n = self.robot.n_joints
        p = x[6:].reshape(n, 5)  # a, alpha, d, theta, beta
        out = []
        for j in range(n + 1):
            head = [t.base, pin.exp6(pin.Motion(x[:6]))] if j == 0 else [_tz(t.d[j - 1] + p[j - 1, 2])]
            if j < n:
                dh = [
                    _rx(t.alpha[j] + p[j, 1]),
                    _tx(t.a[j] + p[j, 0]),
                    _ry(t.beta[j] + p[j, 4]),
                    _rz(t.theta[j] + p[j, 3]),
                ]
            else:
                dh = [t.tool]
            out.append(head + dh)
        return out

    def chain(self, x: np.ndarray) -> Chain:
        placements = []
        for factors in self._factors(x):
            c = pin.SE3.Identity()
            for f in factors:
                c = c * f
            placements.append(c)
        axes = np.array([_EZ_V if pr else _EZ_W for pr in self.robot.prismatic])
        return Chain(tuple(placements), axes)

    def twists(self, x: np.ndarray) -> np.ndarray:
        n = self.robot.n_joints
        out = np.zeros((2 * n + 1, 6, self.n_params))
        jexp = pin.Jexp6(pin.Motion(x[:6]))
        for j, factors in enumerate(self._factors(x)):
            local: list[tuple[int, int, np.ndarray]] = []
            offset = 1 if j == 0 else 0
            if j == 0:
                local += [(k, 1, jexp[:, k]) for k in range(6)]
            else:
                local.append((6 + 5 * (j - 1) + 2, 0, _EZ_V))  # d of the previous joint
            if j < n:
                base = 6 + 5 * j
                local += [
                    (base + 1, offset + 1, _EX_W),  # alpha
                    (base + 0, offset + 2, _EX_V),  # a
                    (base + 4, offset + 3, _EY_W),  # beta
                    (base + 3, offset + 4, _EZ_W),  # theta
                ]
            out[2 * j] = right_twists(factors, local, self.n_params)
        return out


def make_model(kind: str, robot: Robot) -> Model:
    """The parameterization named ``kind`` (one of :data:`MODELS`) for ``robot`` (here, above every
    kind: :class:`MdhModel` builds on :class:`~pincal.kinematics.models.Model`)."""
    classes: dict[str, type[Model]] = {
        "placements": PlacementsModel,
        "poe": PoeModel,
        "mdh": MdhModel,
        "offsets": OffsetsModel,
    }
    if kind not in classes:
        raise PincalError(f"unknown model {kind!r}: choose one of {', '.join(MODELS)}")
    if robot.is_tree and kind not in ("placements", "offsets"):
        raise DataError(
            f"model={kind} describes a serial chain, and the markers are on the branches of a tree "
            f"({', '.join(robot.tips)}): use model=placements or model=offsets"
        )
    return classes[kind](robot)
