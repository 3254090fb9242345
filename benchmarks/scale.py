"""Time and peak memory of ``pincal`` commands on 10³ to 10⁶ UR5 rows (issue 33).

For each size, simulates a seeded laser-tracker experiment with pincal's simulator
(:func:`pincal.random_truth`: joint-placement errors, unknown tracker pose and reflector, 0.03 mm
noise, poses drawn within the joint limits), writes it as a measurement CSV, then runs the command
line in a child process and reports its wall-clock time, its CPU time and its peak resident
memory (``os.wait4``'s resource use of that child). The default command (``--params auto
--extend auto``) is timed too when ``--default`` is given (slower: it cross-validates).

``--commands`` names the rows of the million-row bar (each ≤ 60 s and ≤ 1.5 GB at 10⁶ rows,
also with another process keeping one core busy: ``--busy``): ``calibrate`` (position rows,
``--params all --extend none``), ``calibrate-pose`` (the same on ``x,y,z,qw,qx,qy,qz`` rows,
0.5 mrad orientation noise), ``diagnose``, ``diagnose-pose``, ``tcp`` (flange poses touching
one point, 0.02 mm noise).

Usage::

    python benchmarks/scale.py [--sizes 1000,10000,100000,1000000] [--default] [--folder /tmp/pincal_scale]
        [--commands calibrate,calibrate-pose,diagnose,diagnose-pose,tcp] [--busy]

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
import pinocchio as pin

import pincal

#: Rows of each run.
SIZES = (1_000, 10_000, 100_000, 1_000_000)
#: The command timed first: the whole geometry, no extension.
FIXED = ("--params", "all", "--extend", "none")
#: The million-row bar: seconds and peak resident memory [GB].
BAR_S, BAR_GB = 60.0, 1.5


def write_rows(path: Path, n: int, seed: int = 0, rot_noise: float | None = None) -> None:
    """``n`` simulated UR5 rows (metres, radians) written as a measurement CSV (with
    ``rot_noise`` [rad], pose rows)."""
    ur5 = pincal.load_robot("ur5")
    q = ur5.random_configurations(n, np.random.default_rng(seed), 0.05)
    truth = pincal.random_truth(ur5, seed=seed + 1)
    pincal.write_csv(path, truth.measure(q, 3e-5, rot_noise, seed=seed + 2))


def write_flange_poses(path: Path, n: int, seed: int = 0) -> None:
    """``n`` flange poses (``x,y,z,qw,qx,qy,qz``, metres) whose tool point touches one point:
    the tool 0.15 m along the flange's z, tilted up to about 0.4 rad from pointing down."""
    rng = np.random.default_rng(seed)
    turn = pin.exp3(np.array([np.pi, 0.0, 0.0]))
    rotations = np.array([turn @ pin.exp3(v) for v in rng.normal(scale=0.4, size=(n, 3))])
    positions = np.array([0.5, 0.1, 0.2]) - rotations @ np.array([0.01, -0.02, 0.15])
    positions += rng.normal(scale=2e-5, size=(n, 3))
    quats = np.array([pin.Quaternion(r).coeffs() for r in rotations])  # x, y, z, w
    with open(path, "w") as out:
        out.write("x,y,z,qw,qx,qy,qz\n")
        np.savetxt(out, np.column_stack([positions, quats[:, 3], quats[:, :3]]), delimiter=",", fmt="%.12g")


#: Each command of ``--commands``: its input (``pos``, ``pose`` or ``tcp``) and its arguments.
COMMANDS: dict[str, tuple[str, tuple[str, ...]]] = {
    "calibrate": ("pos", ("calibrate", "ur5", "{data}", *FIXED)),
    "calibrate-pose": ("pose", ("calibrate", "ur5", "{data}", *FIXED)),
    "diagnose": ("pos", ("diagnose", "ur5", "{data}")),
    "diagnose-pose": ("pose", ("diagnose", "ur5", "{data}")),
    "tcp": ("tcp", ("tcp", "{data}")),
}


def input_file(folder: Path, kind: str, n: int) -> Path:
    """The input of kind ``kind`` with ``n`` rows in ``folder``, written when missing, by a child
    process: a parent grown by the simulation would lend its size to every timed child's peak
    memory (a forked child's ``ru_maxrss`` starts at its parent's)."""
    path = folder / f"ur5_{n}.csv" if kind == "pos" else folder / f"{kind}_{n}.csv"
    if not path.exists():
        code = "import sys, scale; scale.write_input(sys.argv[1], sys.argv[2], int(sys.argv[3]))"
        here = str(Path(__file__).parent)
        subprocess.run([sys.executable, "-c", code, kind, str(path), str(n)], check=True, cwd=here)
    return path


def write_input(kind: str, path: str, n: int) -> None:
    """Write the input of kind ``kind`` (``pos``, ``pose`` or ``tcp``) with ``n`` rows to ``path``."""
    if kind == "tcp":
        write_flange_poses(Path(path), n)
    else:
        write_rows(Path(path), n, rot_noise=5e-4 if kind == "pose" else None)


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


def busy_core() -> subprocess.Popen[bytes]:
    """Another process keeping one core busy (ended by the caller)."""
    return subprocess.Popen([sys.executable, "-c", "while True: pass"])


def bar_rows(folder: Path, sizes: list[int], names: list[str]) -> None:
    """Each command of ``names`` on each size: seconds (wall and CPU) and peak GB against the bar."""
    print(
        f"{'rows':>9}  {'command':15}  {'wall [s]':>9}  {'cpu [s]':>8}  {'peak [GB]':>9}  bar (60 s, 1.5 GB)"
    )
    for n in sizes:
        for name in names:
            kind, argv = COMMANDS[name]
            data = input_file(folder, kind, n)
            wall, cpu, peak, code = run_child([a.format(data=data) for a in argv])
            holds = "yes" if cpu <= BAR_S and peak / 1024 <= BAR_GB and code == 0 else "NO"
            holds = holds if n >= 10**6 else f"({holds} at {n:,})"
            print(f"{n:>9,}  {name:15}  {wall:9.1f}  {cpu:8.1f}  {peak / 1024:9.2f}  {holds}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default=",".join(map(str, SIZES)))
    parser.add_argument("--default", action="store_true", help="also time the default command")
    parser.add_argument("--folder", type=Path, default=Path("/tmp/pincal_scale"))
    parser.add_argument("--commands", help=f"the bar's rows, of {','.join(COMMANDS)}")
    parser.add_argument("--busy", action="store_true", help="another process keeps one core busy")
    args = parser.parse_args()
    args.folder.mkdir(parents=True, exist_ok=True)
    sizes = [int(s) for s in args.sizes.split(",")]
    busy = busy_core() if args.busy else None
    try:
        if args.commands:
            bar_rows(args.folder, sizes, args.commands.split(","))
            return
        commands = [("--params all --extend none", FIXED)] + ([("default", ())] if args.default else [])
        print(f"{'rows':>9}  {'command':28}  {'wall [s]':>9}  {'cpu [s]':>8}  {'peak RSS [MB]':>13}  exit")
        for n in sizes:
            data = input_file(args.folder, "pos", n)
            for label, options in commands:
                wall, cpu, peak, code = run_child(["calibrate", "ur5", str(data), *options])
                print(f"{n:>9,}  {label:28}  {wall:9.1f}  {cpu:8.1f}  {peak:13.0f}  {code}", flush=True)
    finally:
        if busy is not None:
            busy.kill()


if __name__ == "__main__":
    main()
