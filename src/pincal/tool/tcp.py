"""Tool frame calibration (TCP and tool orientation) from flange poses, Xiong et al. 2012.

TCP: the flange poses ``(R_i, p_i)`` touch one fixed point, so ``R_i t + p_i`` is the same for all
poses (eq. 5); the TCP ``t`` in the flange frame is the least-squares solution of the stacked
differences ``(R_i - R_{i+1}) t = p_{i+1} - p_i`` (eqs. 6-9), and δ (eq. 10) is the norm of their
residual. Each pose's residual is the distance of its TCP point ``R_i t + p_i`` from the common
point of a fit without that pose, so a badly taught pose stands out. The standard deviation of
``t`` is that of the eq. 7 estimate, with the noise of the TCP points estimated from their scatter.

Orientation (eqs. 11-18): ``default`` keeps the flange axes; ``z`` takes the tool's +Z from a
pure move along it (X from the flange's X); ``zx`` takes +X and +Z from two moves, then
orthonormalises as the paper does (``o = a × n``, ``a = n × o``). Lengths are in the data's unit.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pincal.errors import DataError
from pincal.options import ORIENTATIONS
from pincal.workers import limited

#: Shortest accepted orientation move [m].
MIN_MOVE = 0.005
#: Least spread [m] of the flange positions: touching one point from other orientations moves
#: the flange by about the tool's length, never by less than a millimetre.
MIN_FLANGE_SPREAD = 1e-3
#: Coefficient matrices worse conditioned than this get a warning.
WARN_CONDITION = 30.0
#: A pose is suspect when its leave-one-out distance exceeds this many times the others' scatter.
SUSPECT_RATIO = 6.0


@dataclass(frozen=True)
class ToolCalibration:
    """A calibrated tool frame on the flange.

    Attributes:
        tcp: tool centre point in the flange frame (3,), in the data's unit.
        rotation: ``flange_R_tool`` (3, 3).
        fit_error: δ of eq. 10, in the data's unit.
        tcp_std: standard deviation of each TCP coordinate (3,).
        point: the fixed point touched, in the base frame (3,).
        residuals: per TCP pose, distance of its TCP point from the common point of a fit
            without that pose (n,): a badly taught pose stands out (with 3 poses, from ``point``).
        condition_number: of the TCP coefficient matrix (eq. 6).
        suspects: per TCP pose, whether it looks badly taught (see :func:`_leave_one_out`).
        warnings: near-degenerate input, said in words.
    """

    tcp: np.ndarray
    rotation: np.ndarray
    fit_error: float
    tcp_std: np.ndarray
    point: np.ndarray
    residuals: np.ndarray
    condition_number: float
    suspects: np.ndarray
    warnings: tuple[str, ...] = field(default_factory=tuple)


def euler_zyx(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """``R = Rz(a) · Ry(b) · Rx(c)`` for angles [rad] (N,) -> (N, 3, 3) (Xiong's eq. 19, corrected)."""
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    return np.stack(
        [
            np.stack([ca * cb, ca * sb * sc - sa * cc, ca * sb * cc + sa * sc], -1),
            np.stack([sa * cb, sa * sb * sc + ca * cc, sa * sb * cc - ca * sc], -1),
            np.stack([-sb, cb * sc, cb * cc], -1),
        ],
        axis=1,
    )


def _differences(rotations: np.ndarray, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 6: the stacked ``R_i - R_{i+1}`` (3(n-1), 3) and ``p_{i+1} - p_i`` (3(n-1),)."""
    return (rotations[:-1] - rotations[1:]).reshape(-1, 3), (positions[1:] - positions[:-1]).reshape(-1)


def tcp_position(rotations: np.ndarray, positions: np.ndarray) -> tuple[np.ndarray, float, float]:
    """TCP by eqs. 6-9 and δ by eq. 10.

    Args:
        rotations: flange orientations ``base_R_flange`` (n, 3, 3), n >= 3.
        positions: flange positions (n, 3).

    Returns:
        The TCP (3,), δ, and the condition number of the coefficient matrix.

    Raises:
        DataError: fewer than 3 poses, or orientations that cannot locate the TCP (rank < 3).
    """
    n = len(rotations)
    if n < 3:
        raise DataError(
            f"{n} TCP pose(s): with 2 poses the coefficient matrix R1 - R2 is always singular "
            "(Xiong 2012, eq. 6); teach at least 3 poses touching the point from different orientations"
        )
    lhs, rhs = _differences(rotations, positions)
    sv = np.linalg.svd(lhs, compute_uv=False)
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
    if cond > 1e6:
        axis = np.linalg.svd(lhs)[2][-1]
        raise DataError(
            "the TCP poses' orientations all turn about one axis "
            f"({axis[0]:.3f}, {axis[1]:.3f}, {axis[2]:.3f} in the flange frame), so the TCP along it is "
            "unknown (rank < 3): tilt the tool about another axis in at least one pose"
        )
    tcp = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    return tcp, float(np.linalg.norm(lhs @ tcp - rhs)), cond


def _move_direction(
    rot_o: np.ndarray,
    p_o: np.ndarray,
    rot_m: np.ndarray,
    p_m: np.ndarray,
    tcp: np.ndarray,
    label: str,
    scale: float,
) -> np.ndarray:
    """Unit direction of a TCP move in the first pose's flange frame (eqs. 13-16)."""
    move = rot_m @ tcp - rot_o @ tcp + p_m - p_o
    length = float(np.linalg.norm(move))
    if length < MIN_MOVE * scale:
        raise DataError(
            f"the +{label} move is only {length:.4g} (data units): move the TCP at least "
            f"{MIN_MOVE * scale:.4g} along the tool's +{label} axis"
        )
    return rot_o.T @ move / length


def tool_orientation(
    method: str, rotations: np.ndarray, positions: np.ndarray, tcp: np.ndarray, scale: float = 1.0
) -> tuple[np.ndarray, list[str]]:
    """``flange_R_tool`` by the paper's default, Z or Z/X method.

    Args:
        method: ``default``, ``z`` (rows: origin, +Z) or ``zx`` (rows: origin, +X, +Z).
        rotations: the orientation rows' flange orientations.
        positions: their flange positions.
        tcp: the calibrated TCP.
        scale: data units per metre (1000 for mm), for the shortest accepted move.

    Returns:
        The rotation and any warnings.
    """
    warnings: list[str] = []
    if method == "default":
        return np.eye(3), warnings
    turn = max(
        np.degrees(np.arccos(np.clip((np.trace(rotations[0].T @ r) - 1) / 2, -1, 1))) for r in rotations
    )
    if turn > 1.0:
        warnings.append(
            f"the orientation rows turn the flange by up to {turn:.2f} deg: they should be pure moves"
        )
    if method == "z":
        a = _move_direction(rotations[0], positions[0], rotations[1], positions[1], tcp, "Z", scale)
        n = np.array([1.0, 0.0, 0.0])
    else:
        n = _move_direction(rotations[0], positions[0], rotations[1], positions[1], tcp, "X", scale)
        a = _move_direction(rotations[0], positions[0], rotations[2], positions[2], tcp, "Z", scale)
    angle = float(np.degrees(np.arccos(np.clip(abs(n @ a), 0.0, 1.0))))
    if angle < 30.0:
        what = "the +X and +Z moves" if method == "zx" else "the +Z move and the flange's X axis"
        raise DataError(f"{what} are nearly parallel ({angle:.1f} deg apart): they must be perpendicular")
    if angle < 80.0:
        warnings.append(f"the X and Z directions are {angle:.1f} deg apart, not 90: check the moves")
    o = np.cross(a, n)
    o /= np.linalg.norm(o)
    if method == "z":  # keep the measured Z, complete X from the flange's X
        n = np.cross(o, a)
        return np.column_stack([n, o, a]), warnings
    a = np.cross(n, o)
    return np.column_stack([n, o, a]), warnings


@limited
def _check_flange_spread(positions: np.ndarray, scale: float) -> None:
    """Refuse flange positions (n, 3) [data units, ``scale`` per metre] that spread less than
    :data:`MIN_FLANGE_SPREAD`: no tool is calibrated by poses that hardly move (metres read as
    millimetres give a tool of a fraction of a millimetre).

    Raises:
        DataError: the spread, with the unit that would make it plausible.
    """
    spread = float(np.sqrt(np.mean(np.sum((positions - positions.mean(axis=0)) ** 2, axis=1)))) / scale
    if spread >= MIN_FLANGE_SPREAD:
        return
    metres = scale == 1000.0 and spread * 1e3 >= MIN_FLANGE_SPREAD
    hint = "the x,y,z look like metres: drop units=mm" if metres else "check the unit of x,y,z (units=)"
    raise DataError(
        f"the flange positions spread {spread * 1e3:.3g} mm around their centre, but touching one point "
        f"from different orientations moves the flange by about the tool's length: {hint}"
    )


def calibrate_tool(
    rotations: np.ndarray, positions: np.ndarray, orientation: str = "default", scale: float = 1.0
) -> ToolCalibration:
    """TCP and tool orientation from flange poses (rows as ``docs/formats.md`` describes them).

    Args:
        rotations: ``base_R_flange`` of each row (n, 3, 3).
        positions: flange positions of each row (n, 3), in the data's unit.
        orientation: ``default`` (all rows are TCP rows), ``z`` (the last two rows are origin and
            +Z) or ``zx`` (the last three rows are origin, +X, +Z; every row but the last two is a
            TCP row, the origin row being shared).
        scale: data units per metre (1000 for mm), for the thresholds.
    """
    if orientation not in ORIENTATIONS:
        raise DataError(f"unknown orientation method {orientation!r}: use one of {', '.join(ORIENTATIONS)}")
    n_rows = len(rotations)
    n_orient = {"default": 0, "z": 2, "zx": 3}[orientation]
    n_tcp = n_rows - n_orient + 1 if n_orient else n_rows
    if n_orient and n_rows < n_orient + 2:
        raise DataError(
            f"orientation={orientation} needs at least {n_orient + 2} rows "
            f"(3 TCP poses, the last shared with the orientation rows), got {n_rows}"
        )
    _check_flange_spread(positions, scale)
    tcp, delta, cond = tcp_position(rotations[:n_tcp], positions[:n_tcp])
    warnings: list[str] = []
    if cond > WARN_CONDITION:
        warnings.append(
            f"the TCP poses are nearly degenerate (condition number {cond:.3g}): vary the orientations more"
        )
    orient_rows = slice(n_tcp - 1, n_rows)
    rot, more = tool_orientation(orientation, rotations[orient_rows], positions[orient_rows], tcp, scale)
    warnings += more

    points = rotations[:n_tcp] @ tcp + positions[:n_tcp]
    point = points.mean(axis=0)
    residuals, suspects = _leave_one_out(rotations[:n_tcp], positions[:n_tcp], tcp)
    return ToolCalibration(
        tcp=tcp,
        rotation=rot,
        fit_error=delta,
        tcp_std=_tcp_std(rotations[:n_tcp], positions[:n_tcp], points - point),
        point=point,
        residuals=residuals,
        suspects=suspects,
        condition_number=cond,
        warnings=tuple(warnings),
    )


def _tcp_std(rotations: np.ndarray, positions: np.ndarray, scatter: np.ndarray) -> np.ndarray:
    """Standard deviation of the eq. 7 estimate, each TCP point ``R_i t + p_i`` carrying independent
    noise of variance σ² per axis (estimated from ``scatter`` with 3n - 6 degrees of freedom).

    The residuals of eq. 6 are differences of consecutive points, ``D ε``, so the estimate's
    covariance is ``σ² A⁺ D Dᵀ A⁺ᵀ``; with ``A`` of full column rank (:func:`tcp_position` refuses
    the others) ``A⁺ = (AᵀA)⁻¹Aᵀ``, and ``AᵀD`` is the (3, 3n) row of blocks
    ``A_{i-1}ᵀ - A_iᵀ`` (``A_i = R_i - R_{i+1}``, zero outside 0..n-2): no (3n, 3n) matrix is formed.
    """
    n = len(rotations)
    lhs = rotations[:-1] - rotations[1:]  # (n - 1, 3, 3)
    gram = np.einsum("kij,kil->jl", lhs, lhs)
    zero = np.zeros((1, 3, 3))
    carried = np.concatenate([zero, lhs]) - np.concatenate([lhs, zero])  # A_{i-1} - A_i (n, 3, 3)
    inner = np.einsum("kij,kil->jl", carried, carried)  # (AᵀD)(AᵀD)ᵀ
    inverse = np.linalg.inv(gram)
    sigma2 = float(np.sum(scatter**2)) / max(1, 3 * n - 6)
    return np.sqrt(np.clip(np.diag(inverse @ inner @ inverse) * sigma2, 0.0, None))


class _LeaveOneOut:
    """The eq. 6-9 fit without each pose in turn, from sums over the poses (O(n), not n fits).

    Without pose i the differences ``(i-1, i)`` and ``(i, i+1)`` leave eq. 6 and ``(i-1, i+1)``
    joins it; each fit is solved as a correction ``d_i`` of the fit with every pose ``t0``, from
    the residuals ``e = rhs - A t0`` (small: no large sums cancel), and the points of the other
    poses ``R_k t + p_k`` are summed about the common point ``c0`` of that fit.
    """

    def __init__(self, rotations: np.ndarray, positions: np.ndarray, tcp: np.ndarray) -> None:
        self.rot, self.pos, self.tcp = rotations, positions, tcp
        self.lhs = rotations[:-1] - rotations[1:]  # A_i (n - 1, 3, 3)
        self.err = positions[1:] - positions[:-1] - self.lhs @ tcp  # e_i (n - 1, 3)
        self.gram = np.einsum("kij,kil->jl", self.lhs, self.lhs)
        self.grad = np.einsum("kij,ki->j", self.lhs, self.err)

    def corrections(self) -> np.ndarray:
        """``d_i`` (n, 3): each fit without pose i is ``t0 + d_i``."""
        n, lhs, err = len(self.rot), self.lhs, self.err
        gram = np.broadcast_to(self.gram, (n, 3, 3)).copy()
        grad = np.broadcast_to(self.grad, (n, 3)).copy()
        gram[1:] -= np.einsum("kij,kil->kjl", lhs, lhs)  # the pair (i-1, i) leaves
        grad[1:] -= np.einsum("kij,ki->kj", lhs, err)
        gram[:-1] -= np.einsum("kij,kil->kjl", lhs, lhs)  # the pair (i, i+1) leaves
        grad[:-1] -= np.einsum("kij,ki->kj", lhs, err)
        joined = self.rot[:-2] - self.rot[2:]  # the pair (i-1, i+1) joins, 0 < i < n-1
        residual = self.pos[2:] - self.pos[:-2] - joined @ self.tcp
        gram[1:-1] += np.einsum("kij,kil->kjl", joined, joined)
        grad[1:-1] += np.einsum("kij,ki->kj", joined, residual)
        return np.linalg.solve(gram, grad[:, :, None])[:, :, 0]

    def distances(self) -> tuple[np.ndarray, np.ndarray]:
        """Per pose, the distance of its TCP point from the others' common point, and the others'
        RMS scatter per axis (3(n-1) - 6 degrees of freedom)."""
        n, rot = len(self.rot), self.rot
        d = self.corrections()
        points = rot @ self.tcp + self.pos
        centre = points.mean(axis=0)
        off = points - centre  # each point about c0 with t0
        own = off + np.einsum("kij,kj->ki", rot, d)  # pose i's own point with t0 + d_i
        sum_off = off.sum(axis=0)
        sum_rot = rot.sum(axis=0)
        rot_off = np.einsum("kij,ki->j", rot, off)  # Σ R_kᵀ (x_k - c0)
        rot_rot = np.einsum("kij,kil->jl", rot, rot)  # Σ R_kᵀ R_k
        # Σ over all k of the points with t0 + d_i, about c0: first and second moments
        first = sum_off + d @ sum_rot.T
        second = float(off.ravel() @ off.ravel()) + 2 * d @ rot_off + np.einsum("ij,jl,il->i", d, rot_rot, d)
        first, second = first - own, second - np.sum(own**2, axis=1)  # without pose i
        common = first / (n - 1)  # the others' common point, about c0
        out = np.linalg.norm(own - common, axis=1)
        spread = np.clip(second - (n - 1) * np.sum(common**2, axis=1), 0.0, None)
        return out, np.sqrt(spread / max(1, 3 * (n - 1) - 6))


def _leave_one_out(
    rotations: np.ndarray, positions: np.ndarray, tcp: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Per pose, the distance of its TCP point from the common point of a fit without it (with 3
    poses, of the fit with all), and whether that distance is far outside the scatter of that fit.

    A pose is suspect when the others fit well without it: its distance exceeds
    :data:`SUSPECT_RATIO` times their RMS scatter per axis (5 or more poses; in simulation with
    6 poses this flags a 2 mm mistake among 0.01 mm noise 98 % of the time, a clean set 6 %).
    Each fit without a pose is found from sums over the poses (:class:`_LeaveOneOut`), about
    ``tcp``, the fit with every pose (:func:`tcp_position`).
    """
    n = len(rotations)
    if n < 4:
        points = rotations @ tcp + positions
        return np.linalg.norm(points - points.mean(axis=0), axis=1), np.zeros(n, dtype=bool)
    out, scatter = _LeaveOneOut(rotations, positions, tcp).distances()
    return out, (out > SUSPECT_RATIO * scatter) if n >= 5 else np.zeros(n, dtype=bool)
