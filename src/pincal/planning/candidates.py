"""Candidate measurement poses: random joint configurations the robot can safely be measured in.

A candidate is drawn uniformly within the joint limits (a ``margin`` of each range left out) and
kept when every joint origin that moves, and the measured point, stay ``clearance`` above the floor
(``z`` in the base frame), and, if the instrument has a ``reach``, the measured point is within it.
:func:`pincal.planning.plan.plan_poses` chooses its measurement poses among these. Lengths are metres,
angles radians.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from pincal.errors import DataError
from pincal.identify.kinds import get_kind
from pincal.kinematics.chain import Chain, forward
from pincal.robot.robots import Robot

if TYPE_CHECKING:
    from pincal.simulation.truth import TrueRobot


def candidate_poses(
    robot: Robot,
    n: int,
    seed: int = 0,
    margin: float = 0.05,
    floor: float = 0.0,
    clearance: float = 0.05,
    tool: np.ndarray | None = None,
    instrument: np.ndarray | None = None,
    reach: float | None = None,
) -> np.ndarray:
    """``n`` random feasible configurations (n, n_joints) [rad or m].

    Args:
        robot: the robot.
        n: number wanted.
        seed: random seed.
        margin: fraction of each joint range left out at both ends.
        floor: height of the floor in the base frame [m].
        clearance: every joint origin that moves, and the measured point, stay this far above it [m].
        tool: the measured point on the tip (3,) [m] (default: the tip's origin).
        instrument: the instrument's position in the base frame (3,) [m] (default: the base origin).
        reach: the instrument's range [m] (default: unlimited).

    Raises:
        DataError: too few configurations are feasible.
    """
    rng = np.random.default_rng(seed)
    point = np.zeros(3) if tool is None else np.asarray(tool, float)
    centre = np.zeros(3) if instrument is None else np.asarray(instrument, float)
    chain = Chain.nominal(robot)
    kept: list[np.ndarray] = []
    drawn = 0
    while sum(len(k) for k in kept) < n and drawn < 200 * n:
        q = robot.random_configurations(max(n, 100), rng, margin)
        drawn += len(q)
        kept.append(q[_feasible(chain, q, point, floor + clearance, centre, reach)])
    out = np.concatenate(kept)
    if len(out) < n:
        within = "" if reach is None else f" and within the reach of {reach:g} m"
        raise DataError(
            f"only {len(out)} of {drawn} random configurations keep the moving joints and the measured "
            f"point {floor + clearance:g} m above the floor (the clearance){within}: lower the "
            "clearance, widen the reach or ask for fewer candidates"
        )
    return out[:n]


def _feasible(
    chain: Chain, q: np.ndarray, point: np.ndarray, lowest: float, centre: np.ndarray, reach: float | None
) -> np.ndarray:
    """Which configurations keep the robot above the floor and the measured point within reach.

    Args:
        chain: the nominal chain.
        q: configurations (N, n) [rad or m].
        point: the measured point on the tip (3,) [m].
        lowest: the lowest height a moving joint origin or the measured point may reach [m].
        centre: the instrument's position in the base frame (3,) [m].
        reach: the instrument's range [m], or None for unlimited.

    Returns:
        (N,) mask of the feasible configurations.
    """
    frames = forward(chain, q)
    tip = frames.tip_translation + frames.tip_rotation @ point
    heights = frames.translations[:, :, 2]
    moving = heights.std(axis=1) > 1e-9  # the joint origins a configuration can bring down
    ok = np.all(heights[moving] >= lowest, axis=0) & (tip[:, 2] >= lowest)
    if reach is not None:
        ok &= np.linalg.norm(tip - centre, axis=1) <= reach
    return ok


def perturbed(
    robot: Robot,
    q: np.ndarray,
    n_each: int,
    step: float,
    rng: np.random.Generator,
    margin: float = 0.05,
    clearance: float = 0.05,
    tool: np.ndarray | None = None,
    instrument: np.ndarray | None = None,
    reach: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Feasible configurations near each of ``q`` (N, n) [rad or m], and which pose each is near.

    Each pose is moved ``n_each`` times by a normal step of ``step`` times each joint's range
    (at most a turn) per joint; moves past the limits (less ``margin`` of the range), below the
    floor or out of reach are dropped (see :func:`candidate_poses` for the arguments).

    Returns:
        (M, n) the configurations and (M,) the index in ``q`` of the pose each is near.
    """
    lo, hi = robot.lower, robot.upper
    span = np.where(np.isfinite(hi - lo), hi - lo, 2 * np.pi)
    owner = np.repeat(np.arange(len(q)), n_each)
    moved = q[owner] + step * np.minimum(span, 2 * np.pi) * rng.standard_normal((len(owner), q.shape[1]))
    inside = np.all((moved >= lo + margin * span) & (moved <= hi - margin * span), axis=1)
    point = np.zeros(3) if tool is None else np.asarray(tool, float)
    centre = np.zeros(3) if instrument is None else np.asarray(instrument, float)
    ok = np.zeros(len(moved), bool)
    if inside.any():
        ok[inside] = _feasible(Chain.nominal(robot), moved[inside], point, clearance, centre, reach)
    return moved[ok], owner[ok]


def socket_candidates(
    robot: Robot,
    sockets: np.ndarray,
    n: int,
    seed: int = 0,
    margin: float = 0.05,
    clearance: float = 0.05,
    tool: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``n`` configurations (n, n_joints) [rad or m] that put the measured point in a socket, and
    which socket each is at (n,): damped least squares on the nominal robot from random starts,
    shared out over the sockets, kept when above the floor (fixed-point data).

    Args:
        robot: the robot.
        sockets: (K, 3) where the sockets are in the base frame, roughly [m].
        n: number wanted.
        seed: random seed.
        margin: fraction of each joint range left out at both ends of the starts.
        clearance: every moving joint origin stays this far above the floor z = 0 [m].
        tool: the ball's centre on the tip (3,) [m] (default: the tip's origin).

    Raises:
        DataError: a socket is out of reach (:func:`check_sockets`), or too few configurations
            are above the floor.
    """
    from pincal.kinematics.models import PlacementsModel
    from pincal.simulation.truth import TrueRobot, simulate_points  # the same reaching as the simulator's

    point = np.zeros(3) if tool is None else np.asarray(tool, float)
    model = PlacementsModel(robot)
    nominal = TrueRobot(model, np.zeros(model.n_params), pin.SE3.Identity(), pin.SE3(np.eye(3), point))
    rng = np.random.default_rng(seed)
    check_sockets(nominal, sockets, rng, margin)
    kept_q, kept_at = [], []
    for _ in range(10):
        try:
            data = simulate_points(nominal, sockets, 2 * n, 0.0, rng, margin=margin, tol=1e-6)
        except DataError:  # its message lists rows of a simulation: say what matters here
            raise DataError(
                f"some starts of the {2 * n} attempts did not reach their socket in 20 tries: the "
                "sockets are at the edge of the arm's workspace; move them nearer its middle"
            ) from None
        ok = _feasible(Chain.nominal(robot), data.q, point, clearance, np.zeros(3), None)
        kept_q.append(data.q[ok])
        kept_at.append(np.asarray(data.labels)[ok])
        if sum(len(k) for k in kept_q) >= n:
            break
    q, at = np.concatenate(kept_q), np.concatenate(kept_at)
    if len(q) < n:
        raise DataError(
            f"only {len(q)} configurations reach the sockets above the floor: lower the clearance"
        )
    order = rng.permutation(len(q))[:n]
    return q[order], at[order]


#: Random starts of the reach check of each socket (damped least squares from each, at once).
REACH_STARTS = 200


def arm_reach(robot: Robot, tool: np.ndarray) -> tuple[np.ndarray, float]:
    """How far the measured point can get from the first joint's origin.

    Args:
        robot: the robot.
        tool: the measured point on the tip (3,) [m].

    Returns:
        The first joint's origin in the base frame (3,) [m]; an upper bound that no
        configuration passes, the sum of the link lengths, prismatic strokes and the point's
        distance from the tip [m] (infinite for an unlimited prismatic joint).
    """
    chain = Chain.nominal(robot)
    origin = chain.placements[0].translation.copy()
    stroke = np.maximum(np.abs(robot.lower), np.abs(robot.upper))[np.array(robot.prismatic, bool)]
    links = sum(float(np.linalg.norm(c.translation)) for c in chain.placements[1:])
    return origin, links + float(np.sum(stroke)) + float(np.linalg.norm(tool))


def farthest(robot: Robot, tool: np.ndarray, origin: np.ndarray, samples: int = 20_000) -> float:
    """The farthest the measured point ``tool`` (3,) [m] gets from ``origin`` (3,) [m] among
    ``samples`` random configurations [m] (for the message of :func:`check_sockets`)."""
    frames = forward(Chain.nominal(robot), robot.random_configurations(samples, np.random.default_rng(0)))
    return float(np.linalg.norm(frames.tip_translation + frames.tip_rotation @ tool - origin, axis=1).max())


def check_sockets(truth: TrueRobot, sockets: np.ndarray, rng: np.random.Generator, margin: float) -> None:
    """Refuse sockets the measured point cannot reach, before any search for many poses: those
    beyond the arm's longest stretch (:func:`arm_reach`), and those that none of
    :data:`REACH_STARTS` random starts of damped least squares reaches.

    Args:
        truth: the nominal robot with the ball's centre as its tool.
        sockets: (K, 3) the sockets in the base frame [m].
        rng: random generator of the starts.
        margin: fraction of each joint range left out at both ends of the starts.

    Raises:
        DataError: one line naming the sockets out of reach, their distance from the first
            joint's origin and the arm's reach.
    """
    from pincal.simulation.truth import reach  # the simulator's reaching, without its many restarts

    sockets = np.atleast_2d(np.asarray(sockets, float))
    origin, bound = arm_reach(truth.robot, truth.tool.translation)
    distance = np.linalg.norm(sockets - origin, axis=1)
    out = distance > bound
    inside = np.flatnonzero(~out)
    if inside.size:
        targets = np.repeat(sockets[inside], REACH_STARTS, axis=0)
        starts = truth.robot.random_configurations(len(targets), rng, margin)
        _, reached = reach(truth, targets, starts, 1e-6)
        out[inside] = ~reached.reshape(len(inside), REACH_STARTS).any(axis=1)
    if not out.any():
        return
    xyz = lambda v: ", ".join(f"{c:g}" for c in v)  # noqa: E731
    named = "; ".join(
        f"socket {k} ({xyz(sockets[k])}) is {distance[k]:.3g} m from it"
        + ("" if distance[k] > bound else f" but none of {REACH_STARTS} inverse-kinematics starts reached it")
        for k in np.flatnonzero(out)
    )
    far = farthest(truth.robot, truth.tool.translation, origin)
    raise DataError(
        f"sockets= out of the arm's reach: the measured point gets at most about {far:.3g} m from "
        f"the first joint's origin ({xyz(origin)}), and {named}: check the coordinates and units="
    )


#: Copies of each candidate's identification rows the planner holds at once (measured: 3 to 4).
_ROW_COPIES = 4


def check_memory(robot: Robot, candidates: int, measure: str, n_poses: int) -> None:
    """Refuse a number of candidates whose identification rows would not fit in memory.

    Each candidate holds a Jacobian row block (3 rows for a point, 6 for a pose) over at most
    ``6 (n + 1) + 9`` parameters, a few copies of it, and for distance data its pairs with the
    chosen poses.

    Raises:
        DataError: the estimate is above half the memory available, with the largest count that fits.
    """
    params = 6 * (robot.n_joints + 1) + 9
    kind = get_kind(measure)
    rows = 6 if kind.orientation else 3
    per_candidate = 8 * params * (_ROW_COPIES * rows + (3 * n_poses if kind.by_pairs else 0)) + 1024
    free = available_memory()
    if free is None or candidates * per_candidate <= free / 2:
        return
    most = max(1, int(free / 2 // per_candidate))
    raise DataError(
        f"candidates={candidates} needs about {candidates * per_candidate / 1e9:.3g} GB of memory, "
        f"and {free / 1e9:.3g} GB is available: ask for {most} or fewer (1000 to 10000 are plenty)"
    )


def available_memory() -> float | None:
    """Memory this process can still use [bytes]: the system's available memory, or the control
    group's limit if lower (None when neither can be read)."""
    found: list[float] = []
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    found.append(float(line.split()[1]) * 1024)
    except (OSError, ValueError, IndexError):
        pass
    try:
        with open("/sys/fs/cgroup/memory.max", encoding="ascii") as fh:
            limit = fh.read().strip()
        with open("/sys/fs/cgroup/memory.current", encoding="ascii") as fh:
            used = float(fh.read().strip())
        if limit != "max":
            found.append(float(limit) - used)
    except (OSError, ValueError):
        pass
    return min(found) if found else None
