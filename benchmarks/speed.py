"""pincal's speed, each figure next to a bound or a rival measured in the same run.

Prints, with one BLAS thread (pincal's default) unless said otherwise:

1. ``pincal.calibrate(robot, data, "placements")`` (every identifiable parameter) on 100 to
   100,000 simulated poses: UR5 position data and Panda pose data (seeded :func:`pincal.simulate`:
   0.5 mm / 0.5 mrad joint-origin errors, unknown registration and tool, 0.03 mm noise);
   and what the command runs by default (``params="auto"``, ``extension="auto"``, the outlier
   screen) against the same bound, up to 10,000 poses;
2. the cost of one Levenberg-Marquardt iteration (the fit's time over its Jacobian evaluations)
   against its lower bound: a Python loop of Pinocchio's ``forwardKinematics`` +
   ``computeFrameJacobian`` over the same poses plus NumPy's QR of a matrix the size of the
   fitted Jacobian;
3. ``pincal.auto.diagnose.diagnose`` with every candidate effect and 5 folds;
4. where a second BLAS thread starts to pay off;
5. the command line: ``pincal --help`` CPU time, and ``pincal calibrate`` on 100 poses in the
   default environment against ``PINCAL_THREADS=1``;
6. TIAGo (``--tiago DIR``, ``../shared/datasets/tiago_qualisys`` by default) against FIGAROH
   1.0.2 in one process, alternating, when ``figaroh`` is installed (``pip install '.[bench]'``).

Times are medians of wall-clock :func:`time.perf_counter`. This is a benchmark, not a test.
``--markdown PATH`` also writes what it prints as a page of the documentation (the library's
figures on ``docs/results/speed.md``).

Usage::

    python benchmarks/speed.py [--quick] [--tiago DIR] [--markdown docs/results/generated/speed_library.md]
"""

from __future__ import annotations

import argparse
import contextlib
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

import pincal
import pincal.auto.diagnose
from pincal.identify.solver import identifiable_set, register, set_up, solve
from pincal.threads import blas_threads

sys.path.insert(0, str(Path(__file__).resolve().parent))
import markdown_page  # noqa: E402
from figaroh_tiago import FigarohTiago, figaroh_available, time_whole_script  # noqa: E402
from real_data import load_tiago_data, timed  # noqa: E402

TIAGO = Path(__file__).resolve().parents[2] / "shared" / "datasets" / "tiago_qualisys"
CASES = (("ur5", "position"), ("panda", "pose"))
#: The installed ``pincal`` command (or the module, from a source tree without the script).
PINCAL = [found] if (found := shutil.which("pincal")) else [sys.executable, "-m", "pincal.cli"]


def experiment(name: str, kind: str, n: int) -> tuple[pincal.Robot, pincal.Dataset]:
    """A seeded simulated experiment of ``n`` poses of position or pose data."""
    robot = pincal.load_robot(name)
    _, fit, _ = pincal.simulate(robot, n_fit=n, n_test=0, seed=0, rot_noise=5e-4 if kind == "pose" else None)
    return robot, fit


def lower_bound(robot: pincal.Robot, data: pincal.Dataset, shape: tuple[int, int], repeat: int) -> float:
    """Pinocchio's forward kinematics and frame Jacobian over the poses plus a QR [s]."""
    model, pdata = robot.model, robot.model.createData()
    configurations = [robot.configuration(q) for q in data.q]
    matrix = np.random.default_rng(0).standard_normal(shape)

    def run() -> Any:
        for q in configurations:
            pin.forwardKinematics(model, pdata, q)
            pin.computeFrameJacobian(model, pdata, q, robot.tip_frame_id, pin.LOCAL_WORLD_ALIGNED)
        return np.linalg.qr(matrix, mode="r")

    return timed(repeat, run)[1]


def identification(sizes: tuple[int, ...]) -> None:
    """Section 1 and 2: calibrate's time, and the LM iteration against its bound."""
    print("\n## Identification: pincal.calibrate(robot, data, 'placements'), every identifiable parameter")
    print(
        f"{'case':16s} {'poses':>7s} {'calibrate [s]':>14s} {'iterations':>10s} {'per iter [ms]':>14s}"
        f" {'bound [ms]':>11s} {'ratio':>6s}"
    )
    for name, kind in CASES:
        for n in sizes:
            robot, data = experiment(name, kind, n)
            repeat = 5 if n <= 1000 else 3 if n <= 10000 else 1
            pincal.calibrate(robot, data.subset(range(min(n, 100))), "placements", kind)  # warm-up
            seconds = timed(repeat, pincal.calibrate, robot, data, "placements", kind)[1]
            setup = set_up(robot, data, "placements", kind)
            start = register(setup)
            free = identifiable_set(setup, start).identifiable
            runs = []
            for _ in range(repeat):
                began = time.perf_counter()
                result = solve(setup, start, free)[1]
                runs.append((time.perf_counter() - began) / result.njev)
            per_iteration = statistics.median(runs)
            shape = (len(setup.problem.residuals(start)), int(free.sum()))
            bound = lower_bound(robot, data, shape, repeat)
            ratio = per_iteration / bound
            print(
                f"{name + ' ' + kind:16s} {n:7d} {seconds:14.3f} {result.njev:10d}"
                f" {per_iteration * 1e3:14.2f} {bound * 1e3:11.2f} {ratio:6.2f}"
            )


def default_call(sizes: tuple[int, ...]) -> None:
    """Section 1b: what ``pincal calibrate`` runs by default (parameter choice, outlier screen,
    the diagnosis of ``--extend auto``), against the same bound as one LM iteration."""
    print("\n## The command's default: pincal.calibrate(..., params='auto', extension='auto', outliers=6)")
    print(f"{'case':16s} {'poses':>7s} {'default [s]':>12s} {'bound [ms]':>11s} {'default / bound':>16s}")
    for name, kind in CASES:
        for n in sizes:
            robot, data = experiment(name, kind, n)
            repeat = 3 if n <= 10000 else 1
            options: dict[str, Any] = dict(params="auto", extension="auto", outliers=6.0)
            pincal.calibrate(robot, data.subset(range(min(n, 100))), "placements", kind, **options)  # warm-up
            seconds = timed(repeat, pincal.calibrate, robot, data, "placements", kind, **options)[1]
            setup = set_up(robot, data, "placements", kind)
            start = register(setup)
            free = identifiable_set(setup, start).identifiable
            bound = lower_bound(robot, data, (len(setup.problem.residuals(start)), int(free.sum())), repeat)
            ratio = seconds / bound
            print(f"{name + ' ' + kind:16s} {n:7d} {seconds:12.3f} {bound * 1e3:11.2f} {ratio:16.0f}")


def diagnosis(cases: tuple[tuple[str, str, int], ...]) -> None:
    """Section 3: the whole diagnosis, every candidate."""
    print("\n## Diagnosis: pincal.auto.diagnose.diagnose(robot, data), every candidate, 5 folds")
    for name, kind, n in cases:
        robot, data = experiment(name, kind, n)
        answer, seconds = timed(3, pincal.auto.diagnose.diagnose, robot, data, measure=kind)
        print(f"{name} {kind}, {n} poses: {seconds:.2f} s for {len(answer.candidates)} candidates")
        print(f"  {answer.summary()}")


def threads(sizes: tuple[int, ...]) -> None:
    """Section 4: one BLAS thread against two, in-process."""
    print("\n## BLAS threads: calibrate with 1 and 2 threads (UR5, position)")
    for n in sizes:
        robot, data = experiment("ur5", "position", n)
        times = {}
        for count in (1, 2):
            with blas_threads(count):
                times[count] = timed(3 if n <= 10000 else 1, pincal.calibrate, robot, data)[1]
        gain = times[1] / times[2]
        print(f"{n:7d} poses: 1 thread {times[1]:.3f} s, 2 threads {times[2]:.3f} s ({gain:.2f}x)")


def process_time(command: list[str], env: dict[str, str] | None = None) -> tuple[float, float]:
    """Wall time [s] and CPU time [s] (user + system) of a child process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True, env=env)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def command_line(repeat: int) -> None:
    """Section 5: the command's start-up, and its BLAS threads in the default environment."""
    print("\n## Command line")
    cpu = statistics.median(process_time([*PINCAL, "--help"])[1] for _ in range(repeat))
    print(f"pincal --help: {cpu:.3f} s of CPU")
    robot, data = experiment("ur5", "position", 100)
    with tempfile.TemporaryDirectory() as folder:
        csv = Path(folder) / "poses.csv"
        pincal.write_csv(csv, data)
        command = [*PINCAL, "calibrate", "ur5", str(csv)]
        default = {k: v for k, v in os.environ.items() if k not in ("PINCAL_THREADS", "OPENBLAS_NUM_THREADS")}
        walls = {}
        for label, env in (
            ("default environment", default),
            ("PINCAL_THREADS=1", {**default, "PINCAL_THREADS": "1"}),
        ):
            walls[label] = statistics.median(process_time(command, env)[0] for _ in range(repeat))
        ratio = walls["default environment"] / walls["PINCAL_THREADS=1"]
        print(
            f"pincal calibrate ur5 (100 poses): default environment {walls['default environment']:.2f} s, "
            f"PINCAL_THREADS=1 {walls['PINCAL_THREADS=1']:.2f} s ({ratio:.2f}x)"
        )


def against_figaroh(folder: Path, repeat: int) -> None:
    """Section 6: TIAGo, pincal and FIGAROH alternating in one process, then whole processes."""
    print("\n## TIAGo (37 poses) against FIGAROH 1.0.2")
    if not figaroh_available():
        print("skipped: figaroh is not installed (pip install '.[bench]')")
        return
    if not folder.is_dir():
        print(f"skipped: no TIAGo data at {folder} (--tiago DIR)")
        return
    robot, train, _ = load_tiago_data(folder)
    rival = FigarohTiago(folder)
    rival.prepare()
    calls = {
        "pincal, the command's default": lambda: pincal.calibrate(
            robot, train, params="auto", extension="auto"
        ),
        "pincal, selected (--extend none)": lambda: pincal.calibrate(robot, train, params="auto"),
        "pincal, every parameter": lambda: pincal.calibrate(robot, train),
        "FIGAROH full_params": rival.identify,
    }
    runs: dict[str, list[float]] = {label: [] for label in calls}
    for _ in range(repeat):
        for label, call in calls.items():
            start = time.perf_counter()
            call()
            runs[label].append(time.perf_counter() - start)
    figaroh = statistics.median(runs["FIGAROH full_params"])
    for label, times in runs.items():
        seconds = statistics.median(times)
        print(f"{label:42s} {seconds:.4f} s  (FIGAROH / this: {figaroh / seconds:.1f}x)")
    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "train.csv"
        pincal.write_csv(csv, train)
        command = [*PINCAL, "calibrate", str(folder / "tiago_48_schunk.urdf"), str(csv)]
        command += ["--tip", "wrist_ft_tool_link"]
        ours = statistics.median(process_time(command)[0] for _ in range(3))
    theirs = statistics.median(time_whole_script(folder) for _ in range(3))
    ratio = theirs / ours
    print(f"whole process: pincal calibrate {ours:.2f} s, FIGAROH's script {theirs:.2f} s ({ratio:.1f}x)")


def main(argv: list[str] | None = None) -> None:
    """Run the benchmark and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="up to 10,000 poses and fewer repeats")
    parser.add_argument("--tiago", type=Path, default=TIAGO, help="the TIAGo dataset folder")
    parser.add_argument("--markdown", type=Path, help="also write what it prints as a results page here")
    args = parser.parse_args(argv)
    print(f"pincal {pincal.__version__}, one BLAS thread unless said, {os.cpu_count()} cores")
    printed = markdown_page.Tee(sys.stdout)  # the page's own first line names the version and cores
    with contextlib.redirect_stdout(printed):
        sections(args.quick, args.tiago)
    if args.markdown is not None:
        names = {str(args.tiago).rstrip("/"): "TIAGO_DIR"}
        command = markdown_page.command_line("speed.py", sys.argv[1:] if argv is None else argv, names)
        page = markdown_page.text_block(printed.getvalue().strip("\n"))
        markdown_page.write_page(args.markdown, command, [page])


def sections(quick: bool, tiago: Path) -> None:
    """Print every section (``quick``: up to 10,000 poses and fewer repeats)."""
    sizes = (100, 1000, 10000) if quick else (100, 1000, 10000, 100000)
    with blas_threads(1):
        identification(sizes)
        default_call(sizes[:-1] if len(sizes) > 3 else sizes)
        diagnosis((("ur5", "position", 100), ("panda", "pose", 100), ("ur5", "position", 1000)))
    threads((1000, 10000) if quick else (1000, 10000, 100000))
    command_line(3 if quick else 5)
    against_figaroh(tiago, 5 if quick else 11)


if __name__ == "__main__":
    main()
