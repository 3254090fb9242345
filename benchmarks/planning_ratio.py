"""Planned against random measurement poses: the calibrated robot's error on held-out poses.

The simulation of issue 15, with the project's simulator: for each seed a true UR5
(:func:`pincal.random_truth`: 0.5 mm / 0.5 mrad joint-origin errors, 1 mrad offsets, a tracker at
a random pose 2-4 m away, a reflector at a random direction 50-120 mm from the flange), neither
the tracker pose nor the reflector told to the planner (``pincal plan`` without
``--tool-point``). N poses are planned among 2000 feasible candidates; N random feasible poses
(another seed) are the baseline. Both are measured with 0.03 mm noise and calibrated as
``pincal calibrate`` does (``params="auto"``, ``extension="auto"``: the last line counts the
causes named, false alarms on this rigid truth); each calibrated robot is judged noise-free on
500 random held-out poses of the workspace (the model error alone). Prints, for N = 15, 20, 30
and 40, the wins of the plan over random and the median ratio planned/random, for the default
I-optimal plan and for the D-optimal one (``--criterion d``).

``--task``: the same for a task region, a 30 cm cube in front of the robot: the I-optimal plan
for those poses (``pincal plan --task``) against the D-optimal plan, judged on other poses in the
cube. ``--draws K`` calibrates each design on K noise draws instead of one: the ratios are then
of the RMS over the draws (what the plan can be expected to give), with the chance that one
calibration wins. ``--timing``: seconds to plan 20 of 2000 candidates, one BLAS thread.

Usage::

    python benchmarks/planning_ratio.py [--seeds 10] [--sizes 15,20,30,40] [--task] [--draws 30] [--timing]
        [--robot panda]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import pincal
from pincal.planning.candidates import candidate_poses
from pincal.planning.plan import plan_poses
from pincal.workers import limited

NOISE = 3e-5  # 1σ per coordinate [m]
CANDIDATES = 2000
CUBE = (np.array([0.25, -0.15, 0.15]), np.array([0.55, 0.15, 0.45]))  # the task region [m]
#: Whether each calibration's diagnosis (``--extend auto``, the command's default) named a cause
#: (the truth is rigid: any is a false alarm, printed at the end).
NAMED: list[bool] = []


def truth(robot: pincal.Robot, seed: int) -> pincal.simulation.truth.TrueRobot:
    """The seeded true robot of the issue's simulation."""
    return pincal.random_truth(robot, seed, tool_distance=(0.05, 0.12))


def model_error(
    robot: pincal.Robot, true: pincal.simulation.truth.TrueRobot, q: np.ndarray, judge: np.ndarray, seed: int
) -> float:
    """Noise-free held-out RMS [mm] of the robot calibrated on poses ``q``."""
    clean = true.measure(judge, 0.0, None, 0)
    fit = true.measure(q, NOISE, None, seed)
    cal = pincal.calibrate(robot, fit, "placements", test=clean, params="auto", extension="auto")
    assert cal.test_after is not None
    NAMED.append(cal.extension is not None)
    return cal.test_after.rms_mm


def in_cube(robot: pincal.Robot, n: int, seed: int) -> np.ndarray:
    """``n`` feasible poses whose flange is in the task cube."""
    q = candidate_poses(robot, 40 * n, seed)
    tips = np.array([robot.frame_placement(c).translation for c in q])
    inside = np.all((tips >= CUBE[0]) & (tips <= CUBE[1]), axis=1)
    return q[inside][:n]


def summary(label: str, ratios: list[float]) -> str:
    r = np.array(ratios)
    return f"{label}: wins {int((r < 1).sum())}/{len(r)}, median ratio {np.median(r):.3f}"


def errors(
    robot: pincal.Robot,
    true: pincal.simulation.truth.TrueRobot,
    q: np.ndarray,
    judge: np.ndarray,
    seed: int,
    draws: int,
) -> np.ndarray:
    """Noise-free held-out RMS [mm] of the robot calibrated on poses ``q``, for one noise draw
    (the tables' protocol) or ``draws`` of them."""
    noise_seeds = [30_000 + seed] if draws == 1 else [50_000 + 100 * seed + k for k in range(draws)]
    return np.array([model_error(robot, true, q, judge, s) for s in noise_seeds])


def compare(ours: np.ndarray, theirs: np.ndarray) -> tuple[float, float]:
    """RMS ratio over the draws, and the chance that one of ours beats one of theirs."""
    return float(np.sqrt(np.mean(ours**2) / np.mean(theirs**2))), float(
        (ours[:, None] < theirs[None, :]).mean()
    )


def workspace(robot: pincal.Robot, sizes: list[int], seeds: range, draws: int = 1) -> None:
    """The table; with ``draws`` > 1, over that many noise draws per design, and the chance of
    winning at least 9 of 10 seeds with one calibration each."""
    print(f"{robot.name}, placements, position; reflector and tracker unknown; {len(seeds)} seeds")
    for n in sizes:
        ratios: dict[str, list[float]] = {"i": [], "d": []}
        wins: dict[str, list[float]] = {"i": [], "d": []}
        for seed in seeds:
            true, judge = truth(robot, seed), candidate_poses(robot, 500, 10_000 + seed)
            random = errors(robot, true, candidate_poses(robot, n, 20_000 + seed), judge, seed, draws)
            for criterion in ratios:
                q = plan_poses(robot, n, criterion=criterion, candidates=CANDIDATES, seed=seed).q
                ratio, win = compare(errors(robot, true, q, judge, seed, draws), random)
                ratios[criterion].append(ratio)
                wins[criterion].append(win)
        print(f"N={n}: " + "; ".join(summary(f"{c.upper()}-optimal/random", r) for c, r in ratios.items()))
        if draws > 1:
            chances = (
                f"{c.upper()}: mean P(win) {np.mean(w):.2f}, P(9 of 10) {at_least(9, w):.2f}"
                for c, w in wins.items()
            )
            print(f"  over {draws} draws: " + "; ".join(chances))


def task_region(robot: pincal.Robot, seeds: range, n: int = 20, draws: int = 1) -> None:
    """The cube comparison; with ``draws`` > 1, each plan is calibrated on that many noise draws
    and each seed prints the RMS ratio over the draws and the probability that one I-optimal
    calibration beats one D-optimal one (every pair of draws); the summary then gives the chance
    of winning at least 8 of 10 seeds with those probabilities."""
    print(f"task: a 30 cm cube in front of the robot, N={n}, I-optimal for the cube against D-optimal")
    ratios, wins = [], []
    for seed in seeds:
        true, task, judge = (
            truth(robot, seed),
            in_cube(robot, 200, seed + 1),
            in_cube(robot, 300, 40_000 + seed),
        )
        found = [
            errors(
                robot,
                true,
                plan_poses(robot, n, criterion=c, task=task, candidates=CANDIDATES, seed=seed).q,
                judge,
                seed,
                draws,
            )
            for c in ("i", "d")
        ]
        ratio, win = compare(*found)
        ratios.append(ratio)
        wins.append(win)
        if draws > 1:
            print(f"  seed {seed}: RMS ratio over {draws} draws {ratio:.3f}, P(win) {win:.2f}")
    print(summary("I-optimal(task)/D-optimal on the cube", ratios))
    if draws > 1:
        print(f"mean P(win) per seed {np.mean(wins):.2f}; P(at least 8 of 10 wins) {at_least(8, wins):.2f}")


def at_least(k: int, p: list[float]) -> float:
    """Probability of at least ``k`` successes of independent trials of probabilities ``p`` (the
    first 10 seeds' when there are more)."""
    dist = np.array([1.0])
    for pi in p[:10]:
        dist = np.convolve(dist, [1.0 - pi, pi])
    return float(dist[k:].sum())


@limited
def timing(robot: pincal.Robot) -> None:
    plan_poses(robot, 20, candidates=200)
    start = time.perf_counter()
    plan_poses(robot, 20, candidates=2000)
    print(f"planning 20 of 2000 candidates: {time.perf_counter() - start:.2f} s (one BLAS thread)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--sizes", default="15,20,30,40")
    parser.add_argument("--task", action="store_true", help="only the task-region comparison")
    parser.add_argument(
        "--draws", type=int, default=1, help="noise draws per design (expected ratios, chance of a win)"
    )
    parser.add_argument("--timing", action="store_true", help="only the planning time")
    parser.add_argument("--robot", default="ur5", help="a bundled robot (the issue's simulation is ur5's)")
    args = parser.parse_args()
    robot = pincal.load_robot(args.robot)
    if args.timing:
        timing(robot)
    elif args.task:
        task_region(robot, range(args.seeds), draws=args.draws)
    else:
        workspace(robot, [int(n) for n in args.sizes.split(",")], range(args.seeds), args.draws)
    if NAMED:
        print(f"causes named by --extend auto (false alarms, rigid truth): {sum(NAMED)} of {len(NAMED)}")


if __name__ == "__main__":
    main()
