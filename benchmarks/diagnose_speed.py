"""How long one diagnosis takes: a 6-DOF arm, 100 measured poses, every candidate effect.

Simulates a seeded UR5 laser-tracker experiment (:func:`pincal.simulate`: 0.5 mm / 0.5 mrad joint
origin errors, 1 mrad joint offsets, unknown tracker pose and reflector, 0.03 mm noise, nothing
hidden), times ``pincal.diagnose.diagnose(robot, fit)`` with its default candidates (every effect
of :mod:`pincal.effects` on every joint) and 5 folds (best of ``--repeat`` runs, wall clock by
:func:`time.perf_counter`), and compares it with the 10 s target. One diagnosis is
``(1 + candidates) x (folds + 1)`` calibrations. This is a benchmark, not a test: nothing is
asserted. On a machine shared with other busy processes, OpenBLAS's threads can make it several
times slower; ``OPENBLAS_NUM_THREADS=1`` gives a steadier figure.

Usage::

    python benchmarks/diagnose_speed.py [--poses 100] [--repeat 1] [--robot ur5]
"""

from __future__ import annotations

import argparse
import time

import pincal
import pincal.diagnose
from pincal.effects import candidates

#: Target time of one diagnosis of 100 poses of a 6-DOF arm, every candidate [s].
TARGET_S = 10.0


def main(argv: list[str] | None = None) -> None:
    """Run the benchmark and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=100, help="fitted poses (default 100)")
    parser.add_argument("--repeat", type=int, default=1, help="timed diagnoses (default 1)")
    parser.add_argument("--robot", default="ur5", help="bundled robot or URDF (default ur5)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the simulation")
    args = parser.parse_args(argv)
    if args.poses < 20 or args.repeat < 1:
        parser.error("--poses must be at least 20 and --repeat at least 1")

    robot = pincal.load_robot(args.robot)
    _, fit, _ = pincal.simulate(robot, n_fit=args.poses, n_test=0, seed=args.seed)
    n_candidates = len(candidates(robot))
    folds = 5  # diagnose's default
    pincal.calibrate(robot, fit.subset(range(min(50, len(fit)))), "placements")  # warm-up

    print(
        f"pincal {pincal.__version__}: {robot.name} ({robot.n_joints} joints), {len(fit)} poses, "
        f"position data, {n_candidates} candidates, {folds}-fold CV "
        f"({(1 + n_candidates) * (folds + 1)} calibrations), best of {args.repeat}"
    )
    best = float("inf")
    for _ in range(args.repeat):
        start = time.perf_counter()
        diagnosis = pincal.diagnose.diagnose(robot, fit, folds=folds)
        best = min(best, time.perf_counter() - start)
    print(
        f"diagnose: {best:.2f} s for {len(diagnosis.candidates)} candidates "
        f"({best / len(diagnosis.candidates):.3f} s per candidate) "
        f"= {best / TARGET_S:.2f} x the {TARGET_S:g} s target"
    )
    print(f"answer: {diagnosis.summary()}")


if __name__ == "__main__":
    main()
