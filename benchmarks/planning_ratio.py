"""Planned against random measurement poses: the held-out RMS after calibration, over 10 seeds.

For each seed: a seeded true robot (:func:`pincal.random_truth`: 0.5 mm / 0.5 mrad joint-origin
errors, 1 mrad offsets, an unknown tracker pose and reflector), N poses planned by
:func:`pincal.planning.plan_poses` (D-optimal among 1000 feasible random candidates, the reflector's
place known to a centimetre as ``--tool-point`` would give it) and N random feasible poses (the
first N candidates), both measured with 0.03 mm noise and calibrated; both are judged on the same
1000 random held-out poses. Prints, for N = 20, 30 and 40, how many of the 10 trials the plan wins,
the median of the ratio planned/random held-out RMS, the same ratio on noise-free held-out
positions (the model error alone), and the ratio the plan predicted. This is a benchmark, not a
test: nothing is asserted (``tests/test_planning.py`` asserts the N = 20 result).

Usage::

    python benchmarks/planning_ratio.py [--robot ur5] [--model placements] [--measure position]
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

import pincal
from pincal.planning import candidate_poses, plan_poses

SEEDS = range(10)
NOISE = 3e-5  # 1σ per coordinate [m]
ROT_NOISE = 1.5e-4  # 1σ per axis [rad], pose data only


def trial(robot: pincal.Robot, n: int, seed: int, model: str, measure: str, n_test: int) -> dict[str, float]:
    """Held-out RMS [mm] of the planned and the random poses for one seed, noisy and noise-free."""
    rot = ROT_NOISE if measure == "pose" else None
    truth = pincal.random_truth(robot, seed)
    tool = np.round(truth.tool.translation, 2)
    plan = plan_poses(robot, n, model=model, measure=measure, seed=seed, tool=tool)
    test_q = candidate_poses(robot, n_test, 10_000 + seed)
    test = truth.measure(test_q, NOISE, rot, 20_000 + seed)
    clean = truth.measure(test_q, 0.0, 0.0 if rot else None, 0)
    out = {"predicted": plan.planned.predicted_rms_mm / plan.random.predicted_rms_mm}
    for label, q in (("planned", plan.planned.q), ("random", plan.random.q)):
        cal = pincal.calibrate(robot, truth.measure(q, NOISE, rot, 30_000 + seed), model, measure, test=test)
        assert cal.test_after is not None
        out[label] = cal.test_after.rms_mm
        meas = replace(cal.measurement, pairs=None)
        out[label + "_clean"] = pincal.evaluate(cal.model, meas, cal.theta, clean, cal.extension).rms_mm
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--robot", default="ur5")
    parser.add_argument("--model", default="placements")
    parser.add_argument("--measure", default="position")
    parser.add_argument("--test-poses", type=int, default=1000)
    args = parser.parse_args()
    robot = pincal.load_robot(args.robot)
    print(f"{args.robot}, {args.model}, {args.measure}: planned/random held-out RMS over {len(SEEDS)} seeds")
    for n in (20, 30, 40):
        runs = [trial(robot, n, seed, args.model, args.measure, args.test_poses) for seed in SEEDS]
        wins = sum(r["planned"] < r["random"] for r in runs)
        ratio = np.median([r["planned"] / r["random"] for r in runs])
        clean = np.median([r["planned_clean"] / r["random_clean"] for r in runs])
        predicted = np.median([r["predicted"] for r in runs])
        planned = np.median([r["planned"] for r in runs])
        random = np.median([r["random"] for r in runs])
        print(
            f"N={n}: planned wins {wins}/{len(SEEDS)}, median ratio {ratio:.3f} "
            f"({planned:.4f} vs {random:.4f} mm); model error alone {clean:.3f}; predicted {predicted:.3f}"
        )


if __name__ == "__main__":
    main()
