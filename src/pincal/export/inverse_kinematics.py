"""Inverse kinematics of the calibrated tool: the commands that put it at a target pose, the
joint change from a start kept smallest (the engine of :mod:`pincal.export.compensate`).

Commanded ``q``, the joints reach what :meth:`CalibratedRobot.reached` says, each joint moving in
the direction it comes from the row before (:class:`Approach`: lost motion sees it as it sees the
rows of a file), and the tool is at
``FK_cal(reached) · tip_T_tool``. Tasks, in order of priority, each solved in the null space of
those before it:

1. the point: ``p(q) = p*``;
2. the orientation (``pose`` task): ``log3(R* R(q)ᵀ) = 0``; on a chain of fewer than six joints,
   as close as the joints left by the point allow;
3. the smallest joint change from the start: the joints the first tasks leave free (seven joints
   or more, or the ``position`` task) go back toward it.

Each step solves them by least squares on Pinocchio's frame Jacobian of the tool
(``pin.computeFrameJacobian``, ``LOCAL_WORLD_ALIGNED``; ``pin.log3`` and ``pin.Jlog3`` for the
orientation). From commands near the solution, plain Gauss-Newton converges in a few iterations;
where it does not (near a singularity), Levenberg-Marquardt, whose error never grows, comes as
close as it can, and Gauss-Newton then takes what it reached back toward the start. ``∂e/∂q`` of
an extension is left out of the Jacobian (small beside the identity; the error itself is exact).
A joint stops on its limit, and stays there while the tasks would push it out.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin

from pincal.data.directions import STILL
from pincal.data.program import Targets
from pincal.export.calibrated_robot import CalibratedRobot
from pincal.options import ROTATION_WEIGHT


@dataclass(frozen=True)
class Settings:
    """How a search goes (see :func:`pincal.export.compensate.compensate_program`)."""

    task: str
    tol: float
    rot_tol: float
    max_iter: int
    rcond: float
    max_step: float
    damping: float
    step_tol: float = 1e-10  # [rad or m]: a step this small has settled the lower tasks


@dataclass(frozen=True)
class Approach:
    """Where the robot comes from into a row: the commands of the row before, and each joint's
    direction of motion into that row, as :func:`~pincal.data.directions.move_directions` reads
    the rows of a file."""

    previous: np.ndarray | None = None  # (n,) [rad or m]; None for the first row
    moving: np.ndarray | None = None  # (n,) +1, -1 or 0

    def then(self, q: np.ndarray) -> Approach:
        """Into the row after commands ``q`` (n,), run coming as this says."""
        return Approach(np.array(q, dtype=float), self.directions(q))

    def directions(self, q: np.ndarray) -> np.ndarray:
        """Each joint's direction into commands ``q`` (n,): +1 rose, -1 fell, the direction into the
        row before when it moved by :data:`~pincal.data.directions.STILL` or less, 0 on the first row."""
        if self.previous is None or self.moving is None:
            return np.zeros(len(q))
        step = np.asarray(q, dtype=float) - self.previous
        return np.where(np.abs(step) > STILL, np.sign(step), self.moving)


@dataclass(frozen=True)
class Found:
    """What a search found."""

    q: np.ndarray  # commands (n,) [rad or m]
    position: float  # distance of the point to the target [m]
    rotation: float  # angle to the target's orientation [rad]
    iterations: int
    converged: bool
    start: np.ndarray  # where the first search started, the reference of the joint change (n,)
    ratio: float  # σmin/σmax of the task Jacobian at the start
    first_step: float  # largest joint change of the undamped Gauss-Newton step at the start [rad or m]
    error: float  # the task's error: position + weight · rotation (pose task), position [m]

    def cost(self) -> tuple[bool, float]:
        """Order of preference: converged (the later iterate the better: it is nearer the smallest
        joint change), then the least error."""
        return (not self.converged, 0.0 if self.converged else self.error)


def search(
    cal: CalibratedRobot,
    target: pin.SE3,
    tries: list[np.ndarray],
    before: Approach,
    opts: Settings,
) -> Found:
    """The best :func:`solve` result over the starting commands ``tries``: the first converged
    search (on a chain of fewer than six joints with the pose task, the converged search whose
    orientation is closest), else the one of least ``position + weight · rotation`` error. Each
    search keeps the joint change from its own start smallest.

    Args:
        cal: the calibration.
        target: the tool pose wanted in the base frame [m].
        tries: starting commands (n,) [rad or m], in the order tried.
        before: where the robot comes from (the program's row before).
        opts: the search's settings.
    """
    closest = opts.task == "pose" and cal.robot.n_joints < 6  # converged searches still differ

    def rank(found: Found) -> tuple[bool, float]:
        return (not found.converged, found.rotation if closest and found.converged else found.error)

    best = solve(cal, target, tries[0], before, opts)
    for guess in tries[1:]:
        if best.converged and not closest:
            break
        found = solve(cal, target, guess, before, opts)
        if rank(found) < rank(best):
            best = found
    return best


def solve(
    cal: CalibratedRobot, target: pin.SE3, start: np.ndarray, before: Approach, opts: Settings
) -> Found:
    """Prioritised Gauss-Newton from ``start`` toward ``target``: the point, then (pose task) the
    orientation, then the smallest change from ``start`` (see the module docstring).

    First plain Gauss-Newton (every step taken, at most ``max_step``): from commands near the
    solution it converges in a few iterations, near a singularity too. Should it not converge,
    Levenberg-Marquardt on the tasks alone (:func:`_iterate`, ``monotone``), whose error never
    grows: it comes as close as it can; what it reaches, plain Gauss-Newton then brings back
    toward ``start`` as far as the tasks allow. A step that would take a joint past its limit
    stops it there; a joint on its limit stays there while the tasks would push it out
    (:func:`_step`).

    Args:
        cal: the calibration.
        target: the tool pose wanted in the base frame [m].
        start: the first commands (n,) [rad or m], and the reference of the smallest joint change.
        before: where the robot comes from (the program's row before).
        opts: the search's settings.
    """
    newton = _iterate(cal, target, start, start, before, opts, monotone=False, pull=True)
    if newton.converged:
        return newton
    careful = _iterate(cal, target, start, start, before, opts, monotone=True, pull=False)
    if careful.converged:
        nearer = _iterate(cal, target, careful.q, start, before, opts, monotone=False, pull=True)
        careful = nearer if nearer.converged else careful
    best = careful if careful.cost() < newton.cost() else newton
    return replace(best, ratio=newton.ratio, first_step=newton.first_step)  # as seen from start


def _iterate(
    cal: CalibratedRobot,
    target: pin.SE3,
    begin: np.ndarray,
    start: np.ndarray,
    before: Approach,
    opts: Settings,
    monotone: bool,
    pull: bool,
) -> Found:
    """One search of :func:`solve` from ``begin``: Gauss-Newton steps (damping
    ``_NEWTON_DAMPING``) taken as they come, or (``monotone``) Levenberg-Marquardt: a step is
    taken only if the error (``position + weight · rotation`` for the pose task, ``position`` for
    the position task) does not grow, the damping (from ``opts.damping``) divided by 10 after it;
    else the damping is multiplied by 10 and the step halved, and tried again. When nothing helps,
    the search has come as close as it can. With ``pull``, each step also moves toward ``start``
    as far as the tasks allow (the smallest joint change)."""
    robot = cal.robot
    lo, hi = robot.lower, robot.upper
    here = _At.of(cal, target, np.clip(np.asarray(begin, dtype=float), lo, hi), before, opts.task)
    ratio = _ratio(here.levels)
    first = float(np.abs(_step(here, start, lo, hi, opts.rcond, 0.0)).max())  # the undamped correction
    best: Found | None = None
    stuck, damping = False, (opts.damping if monotone else _NEWTON_DAMPING)
    slack = 1e-2 * opts.tol  # below it the point is reached: moves toward the smallest change are free
    for it in range(opts.max_iter + 1):
        dq = _step(here, start if pull else here.q, lo, hi, opts.rcond, damping)
        settled = stuck or float(np.abs(dq).max()) <= opts.step_tol
        if opts.task == "position" or (robot.n_joints < 6 and settled):
            converged = here.position <= opts.tol  # the orientation as close as the joints allow
        else:
            converged = here.position <= opts.tol and here.rotation <= opts.rot_tol
        found = Found(here.q, here.position, here.rotation, it, converged, start, ratio, first, here.cost)
        if best is None or found.cost() <= best.cost():
            best = found
        if settled or it == opts.max_iter:  # settled: converged, or no step left to take
            return best
        cut = 1.0
        for _ in range(_CUTS if monotone else 1):
            scale = cut * min(1.0, opts.max_step / max(float(np.abs(dq).max()), 1e-300))
            trial = _At.of(cal, target, np.clip(here.q + scale * dq, lo, hi), before, opts.task)
            if not monotone or trial.cost <= max(here.cost, slack):
                here = trial
                damping = damping if not monotone else (damping / 10 if damping > 1e-9 else 0.0)
                break
            damping, cut = max(10 * damping, 1e-4), cut / 2
            dq = _step(here, start if pull else here.q, lo, hi, opts.rcond, damping)
        else:
            stuck = True
    raise AssertionError("unreachable")  # pragma: no cover: the loop returns at max_iter


#: Damping of the plain Gauss-Newton search [m/rad]: it only keeps the steps finite at a singularity.
_NEWTON_DAMPING = 1e-4


def _step(
    here: _At, start: np.ndarray, lo: np.ndarray, hi: np.ndarray, rcond: float, damping: float
) -> np.ndarray:
    """The prioritised step from ``here`` (:func:`_prioritised`, toward ``start`` last), the joints
    on a limit that it would push outward held still."""
    free = np.ones(len(start), dtype=bool)
    while True:
        dq = _prioritised(here.levels, start - here.q, free, rcond, damping)
        out = free & (((here.q <= lo) & (dq < 0)) | ((here.q >= hi) & (dq > 0)))
        if not out.any():
            return dq
        free &= ~out


#: Halvings of a step before a search counts as stuck.
_CUTS = 12


@dataclass(frozen=True)
class _At:
    """The calibrated tool at commands ``q`` against a target: errors and the linear tasks."""

    q: np.ndarray  # commands (n,) [rad or m]
    position: float  # distance of the point to the target [m]
    rotation: float  # angle to the target's orientation [rad]
    cost: float  # position + weight · rotation (pose task), position (position task) [m]
    levels: list[tuple[np.ndarray, np.ndarray]]  # (A, b) of each task, A dq = b, by priority

    @classmethod
    def of(cls, cal: CalibratedRobot, target: pin.SE3, q: np.ndarray, before: Approach, task: str) -> _At:
        """The tool at ``q`` (n,): the point's task ``J_v dq = p* - p``, and for the pose task the
        orientation's ``Jlog3(R* Rᵀ) J_ω dq = log3(R* Rᵀ)`` (world-aligned Jacobian)."""
        pose, jac = _tool(cal, q, before)
        e_p = target.translation - pose.translation
        turn = target.rotation @ pose.rotation.T
        e_r = pin.log3(turn)
        pos, rot = float(np.linalg.norm(e_p)), float(np.linalg.norm(e_r))
        levels = [(jac[:3], e_p)]
        if task == "pose":
            levels.append((pin.Jlog3(turn) @ jac[3:], e_r))
        cost = pos + ROTATION_WEIGHT * rot if task == "pose" else pos
        return cls(q, pos, rot, cost, levels)


def _tool(cal: CalibratedRobot, q: np.ndarray, before: Approach) -> tuple[pin.SE3, np.ndarray]:
    """The calibrated tool's pose at commands ``q`` (n,), coming as ``before`` says, and its frame
    Jacobian (6, n), ``LOCAL_WORLD_ALIGNED`` (rows v [m/unit], ω [rad/unit]) at the joint values
    reached."""
    model, fid = cal.tool_frame
    joints = cal.reached(q[None], before.directions(q)[None])[0]
    data = model.createData()
    jac = pin.computeFrameJacobian(model, data, cal.robot.configuration(joints), fid, pin.LOCAL_WORLD_ALIGNED)
    return data.oMf[fid].copy(), jac


def _prioritised(
    levels: list[tuple[np.ndarray, np.ndarray]],
    toward: np.ndarray,
    free: np.ndarray,
    rcond: float,
    damping: float = 0.0,
) -> np.ndarray:
    """A step ``dq`` that solves each linear task ``A dq = b`` of ``levels`` by least squares in
    the null space of those before it, then moves as far toward ``toward`` as that null space
    allows (the smallest joint change). Joints not ``free`` do not move.

    Args:
        levels: (A (m, n), b (m,)) in order of priority.
        toward: the joint change wanted from what remains (n,).
        free: (n,) mask of the joints that may move.
        rcond: singular values below ``rcond`` times a task's largest are left out.
        damping: λ of the damped least squares, ``σ / (σ² + λ²)`` in place of ``1 / σ``.
    """
    null = np.diag(free.astype(float))  # orthogonal projector onto the changes still allowed
    dq = np.zeros(len(toward))
    for a, b in levels:
        u, s, vt = np.linalg.svd(a @ null, full_matrices=False)
        keep = s > rcond * s[0] if s.size and s[0] > 0 else np.zeros(s.size, dtype=bool)
        v = vt[keep].T
        dq = dq + v @ ((u[:, keep].T @ (b - a @ dq)) * s[keep] / (s[keep] ** 2 + damping**2))
        null = null - v @ v.T
    return dq + null @ (toward - dq)


def _ratio(levels: list[tuple[np.ndarray, np.ndarray]]) -> float:
    """σmin/σmax of the stacked task Jacobian, orientation rows weighted by ROTATION_WEIGHT [m/rad]."""
    weights = [1.0, ROTATION_WEIGHT]
    jac = np.vstack([w * a for w, (a, _) in zip(weights, levels)])
    sv = np.linalg.svd(jac, compute_uv=False)
    return float(sv[-1] / sv[0]) if sv.size and sv[0] > 0 else 0.0


def tool_errors(
    cal: CalibratedRobot, targets: Sequence[pin.SE3] | Targets, q: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Per row, the distance [m] and the angle [rad] from the calibrated tool at commands ``q``
    (N, n), run in order (:meth:`CalibratedRobot.tool_poses`), to ``targets[i]``."""
    pos, rot = np.zeros(len(q)), np.zeros(len(q))
    for i, tool in enumerate(cal.tool_poses(q)):
        target = targets[i]
        pos[i] = np.linalg.norm(target.translation - tool.translation)
        rot[i] = np.linalg.norm(pin.log3(target.rotation @ tool.rotation.T))
    return pos, rot
