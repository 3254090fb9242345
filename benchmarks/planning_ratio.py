"""Planned against random measurement poses: the calibrated robot's error on held-out poses.

The simulation, with the project's simulator: for each seed a true robot
(:func:`pincal.random_truth`: 0.5 mm / 0.5 mrad joint-origin errors, 1 mrad offsets, a tracker at
a random pose 2-4 m away, a reflector at a random direction 50-120 mm from the flange), neither
the tracker pose nor the reflector told to the planner (``pincal plan`` without
``--tool-point``). N poses are planned among 2000 feasible candidates; N random feasible poses
(another seed) are the baseline. Both are measured with 0.03 mm noise and calibrated as
``pincal calibrate`` does (``params="auto"``, ``extension="auto"``: the last line counts the
causes named, false alarms on this rigid truth, and the fits the guard refused, the URDF's
geometry delivered instead); each calibrated robot is judged noise-free on
500 random held-out poses of the workspace (the model error alone). Prints, for N = 15, 20, 30
and 40, the wins of the plan over random and the median ratio planned/random, for the default
I-optimal plan and for the D-optimal one (``--criterion d``).

``--task``: the same for a task region, a 30 cm cube in front of the robot: the I-optimal plan
for those poses (``pincal plan --task``) against the D-optimal plan, judged on other poses in the
cube. ``--draws K`` calibrates each design on K noise draws instead of one: the ratios are then
of the RMS over the draws (what the plan can be expected to give), with the chance that one
calibration wins. ``--robot`` takes a bundled robot or several, comma separated (UR5 by default).
``--markdown PATH`` writes what is printed as a page of the documentation's results
(``docs/results/planning.md`` includes them). ``--timing``: seconds to plan 20 of 2000
candidates, one BLAS thread (a timing of the machine it runs on: it writes no page).

Usage::

    python benchmarks/planning_ratio.py [--seeds 10] [--sizes 15,20,30,40] [--task] [--draws 30]
        [--robot ur5|panda,zu3] [--markdown docs/results/generated/planning_ratio.md] [--timing]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from markdown_page import publish, table  # noqa: E402

import pincal  # noqa: E402
from pincal.planning.candidates import candidate_poses  # noqa: E402
from pincal.planning.plan import plan_poses  # noqa: E402
from pincal.workers import limited  # noqa: E402

NOISE = 3e-5  # 1σ per coordinate [m]
CANDIDATES = 2000
CUBE = (np.array([0.25, -0.15, 0.15]), np.array([0.55, 0.15, 0.45]))  # the task region [m]
#: Each calibration's diagnosis (``--extend auto``, the command's default): where it ran and the
#: cause it named, or None (the truth is rigid: any cause is a false alarm, said at the end).
NAMED: list[tuple[str, str | None]] = []
#: Each calibration the guard delivered the URDF's geometry for (its fit refused): where, and why
#: (its statistic at or below its threshold, or the check across the joint limits).
REFUSED: list[tuple[str, str]] = []


def truth(robot: pincal.Robot, seed: int) -> pincal.simulation.truth.TrueRobot:
    """The seeded true robot of the simulation."""
    return pincal.random_truth(robot, seed, tool_distance=(0.05, 0.12))


def model_error(
    robot: pincal.Robot,
    true: pincal.simulation.truth.TrueRobot,
    q: np.ndarray,
    judge: np.ndarray,
    seed: int,
    where: str,
) -> float:
    """Noise-free held-out RMS [mm] of the robot calibrated on poses ``q``."""
    clean = true.measure(judge, 0.0, None, 0)
    fit = true.measure(q, NOISE, None, seed)
    cal = pincal.calibrate(robot, fit, "placements", test=clean, params="auto", extension="auto")
    assert cal.test_after is not None
    NAMED.append((where, None if cal.extension is None else cal.extension.label))
    if cal.guard is not None and not cal.guard.kept_fit:
        why = "its z at or below the threshold" if not cal.guard.reliable else "the check across the limits"
        REFUSED.append((where, why))
    return cal.test_after.rms_mm


def in_cube(robot: pincal.Robot, n: int, seed: int) -> np.ndarray:
    """``n`` feasible poses whose flange is in the task cube."""
    q = candidate_poses(robot, 40 * n, seed)
    tips = np.array([robot.frame_placement(c).translation for c in q])
    inside = np.all((tips >= CUBE[0]) & (tips <= CUBE[1]), axis=1)
    return q[inside][:n]


def errors(
    robot: pincal.Robot,
    true: pincal.simulation.truth.TrueRobot,
    q: np.ndarray,
    judge: np.ndarray,
    seed: int,
    draws: int,
    where: str,
) -> np.ndarray:
    """Noise-free held-out RMS [mm] of the robot calibrated on poses ``q``, for one noise draw
    (the tables' protocol) or ``draws`` of them."""
    noise_seeds = [30_000 + seed] if draws == 1 else [50_000 + 100 * seed + k for k in range(draws)]
    return np.array([model_error(robot, true, q, judge, s, where) for s in noise_seeds])


def compare(ours: np.ndarray, theirs: np.ndarray) -> tuple[float, float]:
    """RMS ratio over the draws, and the chance that one of ours beats one of theirs."""
    return float(np.sqrt(np.mean(ours**2) / np.mean(theirs**2))), float(
        (ours[:, None] < theirs[None, :]).mean()
    )


def won(ratios: list[float]) -> str:
    """The seeds whose ratio is below 1, of all."""
    return f"{int((np.array(ratios) < 1).sum())} of {len(ratios)}"


def workspace(robot: pincal.Robot, sizes: list[int], seeds: range, draws: int = 1) -> list[str]:
    """The table of planned against random poses on the whole workspace (Markdown); with
    ``draws`` > 1, over that many noise draws per design, with the chance that one calibration
    of the plan beats one of random poses and that of winning at least 9 of 10 seeds with one
    calibration each."""
    over = "one calibration per design" if draws == 1 else f"{draws} noise draws per design"
    head = [
        f"**{robot.name}**, placements, position data, reflector and tracker unknown to the planner; "
        f"{len(seeds)} seeds, {over}; ratio of the noise-free held-out RMS, planned/random "
        + ("(median over the seeds)" if draws == 1 else "(RMS over the draws, median over the seeds)"),
        "",
    ]
    header = ["N", "plan", "median ratio planned/random", "seeds the plan wins"]
    if draws > 1:
        header += [
            "P(one calibration wins), mean over the seeds",
            "P(9 of 10 seeds won, one calibration each)",
        ]
    rows = []
    for n in sizes:
        ratios: dict[str, list[float]] = {"i": [], "d": []}
        wins: dict[str, list[float]] = {"i": [], "d": []}
        for seed in seeds:
            true, judge = truth(robot, seed), candidate_poses(robot, 500, 10_000 + seed)
            where = f"{robot.name}, N = {n}"
            q = candidate_poses(robot, n, 20_000 + seed)
            random = errors(robot, true, q, judge, seed, draws, f"{where}, random poses")
            for criterion in ratios:
                q = plan_poses(robot, n, criterion=criterion, candidates=CANDIDATES, seed=seed).q
                mine = errors(
                    robot, true, q, judge, seed, draws, f"{where}, {criterion.upper()}-optimal plan"
                )
                ratio, win = compare(mine, random)
                ratios[criterion].append(ratio)
                wins[criterion].append(win)
        for criterion in ratios:
            row: list[object] = [
                n,
                f"{criterion.upper()}-optimal",
                f"{np.median(ratios[criterion]):.3f}",
                won(ratios[criterion]),
            ]
            if draws > 1:
                row += [f"{np.mean(wins[criterion]):.2f}", f"{at_least(9, wins[criterion]):.2f}"]
            rows.append(row)
        print(f"  N = {n} done", file=sys.stderr, flush=True)
    return ["\n".join(head) + "\n" + table(header, rows)]


def task_region(robot: pincal.Robot, seeds: range, n: int = 20, draws: int = 1) -> list[str]:
    """The cube comparison (Markdown); with ``draws`` > 1, each plan is calibrated on that many
    noise draws and each seed has the RMS ratio over the draws and the probability that one
    I-optimal calibration beats one D-optimal one (every pair of draws); the summary then gives
    the chance of winning at least 8 of 10 seeds with those probabilities."""
    over = "one calibration per plan" if draws == 1 else f"{draws} noise draws per plan"
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
                f"{robot.name}, cube, N = {n}, seed {seed}, "
                + ("task plan" if c == "i" else "D-optimal plan"),
            )
            for c in ("i", "d")
        ]
        ratio, win = compare(*found)
        ratios.append(ratio)
        wins.append(win)
    sections = [
        f"**{robot.name}**, a 30 cm cube in front of the robot, N = {n}: the I-optimal plan for "
        f"poses in the cube against the D-optimal plan, judged on other poses in the cube; "
        f"{len(seeds)} seeds, {over}. Ratio I-optimal(task)/D-optimal of the noise-free RMS in the "
        f"cube: median {np.median(ratios):.3f} ({min(ratios):.3f} to {max(ratios):.3f}), the "
        f"task plan ahead in {won(ratios)} seeds."
    ]
    if draws > 1:
        sections[0] += (
            f" Probability that one calibration of the task plan beats one of the D-optimal plan: "
            f"mean {np.mean(wins):.2f} ({min(wins):.2f} to {max(wins):.2f}); at least 8 of 10 "
            f"seeds won with one calibration each: {at_least(8, wins):.2f}."
        )
        rows = [[seed, f"{r:.3f}", f"{w:.2f}"] for seed, r, w in zip(seeds, ratios, wins)]
        sections += ["", table(["seed", f"RMS ratio over {draws} draws", "P(one calibration wins)"], rows)]
    return ["\n".join(sections)]


def at_least(k: int, p: list[float]) -> float:
    """Probability of at least ``k`` successes of independent trials of probabilities ``p`` (the
    first 10 seeds' when there are more)."""
    dist = np.array([1.0])
    for pi in p[:10]:
        dist = np.convolve(dist, [1.0 - pi, pi])
    return float(dist[k:].sum())


def refused() -> str:
    """The calibrations whose fit the guard refused (the URDF's geometry delivered), where and why."""
    counts = Counter(REFUSED)
    line = f"The guard refused the fit (and delivered the URDF's geometry) in {len(REFUSED)} of them"
    if not counts:
        return line + "."
    return (
        line + ": " + "; ".join(f"{where}, {why}: {k}×" for (where, why), k in sorted(counts.items())) + "."
    )


def false_alarms() -> str:
    """The causes ``--extend auto`` named, where (a rigid truth: each is a false alarm)."""
    named = Counter((where, label) for where, label in NAMED if label is not None)
    line = (
        f"`--extend auto` named a cause in {sum(named.values())} of these {len(NAMED)} calibrations "
        "(the truth is rigid: each is a false alarm)"
    )
    if not named:
        return line + "."
    return (
        line
        + ": "
        + "; ".join(f"{label} ({where}) {k}×" for (where, label), k in sorted(named.items()))
        + "."
    )


@limited
def timing(robot: pincal.Robot) -> None:
    plan_poses(robot, 20, candidates=200)
    start = time.perf_counter()
    plan_poses(robot, 20, candidates=2000)
    print(f"planning 20 of 2000 candidates: {time.perf_counter() - start:.2f} s (one BLAS thread)")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--sizes", default="15,20,30,40")
    parser.add_argument("--task", action="store_true", help="only the task-region comparison")
    parser.add_argument(
        "--draws", type=int, default=1, help="noise draws per design (expected ratios, chance of a win)"
    )
    parser.add_argument("--timing", action="store_true", help="only the planning time")
    parser.add_argument("--robot", default="ur5", help="a bundled robot, or several comma separated")
    parser.add_argument("--markdown", type=Path, help="write the results page's figures here")
    args = parser.parse_args(argv)
    robots = [pincal.load_robot(name) for name in args.robot.split(",")]
    if args.timing:
        if args.markdown is not None:
            parser.error("--timing writes no page: it times the machine it runs on")
        for robot in robots:
            timing(robot)
        return
    sections: list[str] = []
    for robot in robots:
        if args.task:
            sections += task_region(robot, range(args.seeds), draws=args.draws)
        else:
            sizes = [int(n) for n in args.sizes.split(",")]
            sections += workspace(robot, sizes, range(args.seeds), args.draws)
    sections.append(false_alarms() + " " + refused())
    text = "\n\n".join(sections)
    publish("planning_ratio.py", argv, text, (), None, args.markdown)


if __name__ == "__main__":
    main()
