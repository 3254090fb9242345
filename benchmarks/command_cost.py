"""What a change costs the user: the whole default command, this checkout against another, in one run.

Times ``pincal calibrate ROBOT data.csv --units mm --noise 0.03`` (the default: parameters and
causes chosen, outliers screened) as whole processes, this source tree's code and a reference
checkout's (``--reference DIR``: another clone or ``git worktree`` of pincal, for example at the
previous release), alternating, on simulated UR5 position data of 100 and 1000 poses in visiting
order (seeded :func:`pincal.simulate` truth, 0.03 mm noise): rigid, and with a lost motion and a
gear harmonic hidden (0.4 mm RMS at the tip each), which the default now names together. Prints
each median wall-clock time and the ratio this / reference against the bound ``--bound`` (1.3:
a new capability may cost at most 30 % more). Exit status 1 when a ratio exceeds it.

Usage::

    python benchmarks/command_cost.py --reference ../ref [--sizes 100 1000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pincal
import pincal.simulation.truth
from pincal.kinematics.effects import Extension

HERE = Path(__file__).resolve().parents[1]
HIDDEN = ("lost_motion:shoulder_lift_joint", "gear_harmonic:elbow_joint")


def write_data(folder: Path, n: int, hidden: bool, seed: int = 0) -> Path:
    """Simulated UR5 position data [mm], ``n`` poses in visiting order, effects hidden or not."""
    robot = pincal.load_robot("ur5")
    truth, fit, _ = pincal.simulate(robot, n_fit=n, n_test=1, seed=seed)
    if hidden:
        parts = [Extension.parse(robot, label) for label in HIDDEN]
        truth = pincal.simulation.truth.hide_effects(truth, parts, fit.q, 0.4e-3, seed)
    data = truth.measure(fit.q, noise=3e-5, seed=seed + 1)
    path = folder / f"ur5_{n}_{'effects' if hidden else 'rigid'}.csv"
    pincal.write_csv(path, data, units="mm")
    return path


def run_once(source: Path, data: Path) -> float:
    """Wall-clock seconds of one ``pincal calibrate`` with the code of ``source``."""
    env = {**os.environ, "PYTHONPATH": str(source / "src")}
    argv = [sys.executable, "-m", "pincal", "calibrate", "ur5", str(data), "--units", "mm", "--noise", "0.03"]
    start = time.perf_counter()
    subprocess.run(argv, env=env, check=True, capture_output=True)
    return time.perf_counter() - start


def compare(reference: Path, data: Path, repeats: int) -> tuple[float, float]:
    """Median seconds of this tree and of ``reference`` on ``data``, runs alternating."""
    mine, theirs = [], []
    for _ in range(repeats):
        mine.append(run_once(HERE, data))
        theirs.append(run_once(reference, data))
    return statistics.median(mine), statistics.median(theirs)


def main(argv: list[str] | None = None) -> int:
    """Print the table; 1 when a ratio exceeds the bound."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reference", type=Path, required=True, help="another pincal checkout")
    parser.add_argument("--sizes", type=int, nargs="+", default=[100, 1000])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--bound", type=float, default=1.3)
    args = parser.parse_args(argv)
    failed = False
    print(f"{'data':28s} {'this [s]':>9s} {'reference [s]':>14s} {'ratio':>7s}  bound {args.bound}")
    with tempfile.TemporaryDirectory(prefix="pincal-cost-") as folder:
        for n in args.sizes:
            for hidden in (False, True):
                path = write_data(Path(folder), n, hidden)
                mine, theirs = compare(args.reference, path, args.repeats)
                ratio = mine / theirs
                failed |= ratio > args.bound
                verdict = "ok" if ratio <= args.bound else "SLOWER"
                print(f"{path.stem:28s} {mine:9.2f} {theirs:14.2f} {ratio:7.2f}  {verdict}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
