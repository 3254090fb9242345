"""How long one identification takes: a 6-DOF arm, 1,000 measured poses.

Simulates a seeded UR5 laser-tracker experiment (:func:`pincal.simulate`: 0.5 mm / 0.5 mrad joint
origin errors, 1 mrad joint offsets, unknown tracker pose and reflector, 0.03 mm noise), times
``pincal.calibrate(robot, fit, "placements")`` on position data (best of ``--repeat`` runs, wall
clock by :func:`time.perf_counter`) and compares it with the 0.5 s target; then times the other
models the same way. This is a benchmark, not a test: nothing is asserted.

Usage::

    python benchmarks/identification_speed.py [--poses 1000] [--repeat 5] [--robot ur5]
"""

from __future__ import annotations

import argparse
import time

import pincal

#: Target time of one ``placements`` identification with 1,000 poses [s].
TARGET_S = 0.5


def best_time(robot: pincal.Robot, data: pincal.Dataset, model: str, repeat: int) -> float:
    """Shortest wall-clock time [s] of ``repeat`` calls of :func:`pincal.calibrate`.

    Args:
        robot: the robot.
        data: the fitted poses.
        model: the parameterization.
        repeat: number of timed calls.
    """
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        pincal.calibrate(robot, data, model)
        best = min(best, time.perf_counter() - start)
    return best


def main(argv: list[str] | None = None) -> None:
    """Run the benchmark and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=1000, help="fitted poses (default 1000)")
    parser.add_argument("--repeat", type=int, default=5, help="timed runs per model (default 5)")
    parser.add_argument("--robot", default="ur5", help="bundled robot or URDF (default ur5)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the simulation")
    args = parser.parse_args(argv)
    if args.poses < 10 or args.repeat < 1:
        parser.error("--poses must be at least 10 and --repeat at least 1")

    robot = pincal.load_robot(args.robot)
    _, fit, _ = pincal.simulate(robot, n_fit=args.poses, n_test=0, seed=args.seed)
    pincal.calibrate(robot, fit.subset(range(min(50, len(fit)))), "placements")  # warm-up

    print(
        f"pincal {pincal.__version__}: {robot.name} ({robot.n_joints} joints), "
        f"{len(fit)} poses, position data, best of {args.repeat}"
    )
    seconds = best_time(robot, fit, "placements", args.repeat)
    print(
        f"placements: {seconds:.3f} s per identification "
        f"= {seconds / TARGET_S:.2f} x the {TARGET_S} s target"
    )
    for model in ("poe", "mdh", "offsets"):
        t = best_time(robot, fit, model, args.repeat)
        print(f"{model + ':':11s} {t:.3f} s per identification = {t / TARGET_S:.2f} x the target")


if __name__ == "__main__":
    main()
