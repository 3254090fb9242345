"""Time and peak memory of ``pincal calibrate`` on 10³ to 10⁶ UR5 rows (issue 33).

For each size, simulates a seeded laser-tracker experiment with pincal's simulator
(:func:`pincal.random_truth`: joint-placement errors, unknown tracker pose and reflector, 0.03 mm
noise, poses drawn within the joint limits), writes it as a measurement CSV, then runs the command
line in a child process and reports its wall-clock time, its CPU time and its peak resident
memory (``os.wait4``'s resource use of that child). The default command (``--params auto
--extend auto``) is timed too when ``--default`` is given (slower: it cross-validates).

Usage::

    python benchmarks/scale.py [--sizes 1000,10000,100000,1000000] [--default] [--folder /tmp/pincal_scale]

The figures depend on the machine and on its load (other processes on the same cores): the
command's own CPU time (user + system) is printed beside the wall clock.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import pincal

#: Rows of each run.
SIZES = (1_000, 10_000, 100_000, 1_000_000)
#: The command timed first: the whole geometry, no extension.
FIXED = ("--params", "all", "--extend", "none")


def write_rows(path: Path, n: int, seed: int = 0) -> None:
    """``n`` simulated UR5 rows (metres, radians) written as a measurement CSV."""
    ur5 = pincal.load_robot("ur5")
    q = ur5.random_configurations(n, np.random.default_rng(seed), 0.05)
    pincal.write_csv(path, pincal.random_truth(ur5, seed=seed + 1).measure(q, 3e-5, seed=seed + 2))


def run_child(args: list[str]) -> tuple[float, float, float, int]:
    """Wall time [s], CPU time [s], peak RSS [MB] and exit code of ``pincal ARGS`` in a child
    (``os.wait4``: that child's own resource use)."""
    started = time.perf_counter()
    with tempfile.TemporaryFile() as err:
        command = [sys.executable, "-m", "pincal", *args]
        child = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=err)
        _, status, usage = os.wait4(child.pid, 0)
        child.returncode = os.waitstatus_to_exitcode(status)
        wall = time.perf_counter() - started
        if child.returncode != 0:
            err.seek(0)
            print(err.read().decode().strip(), file=sys.stderr)
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024, child.returncode


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default=",".join(map(str, SIZES)))
    parser.add_argument("--default", action="store_true", help="also time the default command")
    parser.add_argument("--folder", type=Path, default=Path("/tmp/pincal_scale"))
    args = parser.parse_args()
    args.folder.mkdir(parents=True, exist_ok=True)
    commands = [("--params all --extend none", FIXED)] + ([("default", ())] if args.default else [])
    print(f"{'rows':>9}  {'command':28}  {'wall [s]':>9}  {'cpu [s]':>8}  {'peak RSS [MB]':>13}  exit")
    for n in (int(s) for s in args.sizes.split(",")):
        data = args.folder / f"ur5_{n}.csv"
        if not data.exists():
            write_rows(data, n)
        for label, options in commands:
            wall, cpu, peak, code = run_child(["calibrate", "ur5", str(data), *options])
            print(f"{n:>9,}  {label:28}  {wall:9.1f}  {cpu:8.1f}  {peak:13.0f}  {code}", flush=True)


if __name__ == "__main__":
    main()
