"""Issue 42's table: what the user waits for, each row a ratio against an anchor timed in the same run.

The anchor is FIGAROH 1.0.2's whole TIAGo script (``figaroh_tiago.py --script``: import, load,
identify, print), a fixed amount of work: the issue's bars were set on a quiet 2-core machine
where it took 3.6 s, so a bar of S seconds there is S / 3.6 of the anchor here, on a busy machine
too. Rows (whole processes unless said; medians of ``--repeat`` runs, alternating with the anchor):

1. ``pincal calibrate`` on TIAGo's training day (37 poses, ``--tip wrist_ft_tool_link``): ≤ 0.5;
2. ``pincal diagnose ur5`` on 100 simulated poses: ≤ 1.5 s, 0.42 of the anchor;
3. the default command on 10,000 simulated Panda pose rows, in-process (``pincal.cli.main`` in a
   process that has imported it, the start-up not counted): ≤ 10 s, 2.8 of the anchor;
4. with ``--million``, each ≤ 60 s (16.7 of the anchor) and a peak resident memory ≤ 1.5 GB:
   ``pincal calibrate ur5 --params all --extend none`` on 10⁶ simulated position rows, the same
   on 10⁶ pose rows, ``pincal diagnose`` on the position rows, ``pincal tcp`` on 10⁶ flange poses
   and the default command on the position rows (the inputs of ``benchmarks/scale.py``); with
   ``--busy`` another process keeps one core busy while they run.

Rows 1 and 2 also run with ``PINCAL_WORKERS=1`` (one process: what the second core gives), and
rows 1-3 and the first 10⁶ row with ``--baseline SRC`` (another source tree, e.g. ``git archive``
of an older commit, put first on ``PYTHONPATH``): before and after in the same run. This is a
benchmark, not a test.

Each source tree is compiled to bytecode first (:func:`compileall.compile_dir`), as ``pip install .``
(the README's install) and FIGAROH's install do: where Python may not write bytecode
(``PYTHONDONTWRITEBYTECODE``, set on the machine these bars were measured on), a source tree on
``PYTHONPATH`` would otherwise be compiled at every start of every command, 0.25-0.35 s of each,
which no installed copy pays.

Usage::

    python benchmarks/speed_bars.py [--repeat 3] [--tiago DIR] [--baseline SRC] [--million [--busy]]
        [--markdown docs/results/generated/speed_bars.md]
"""

from __future__ import annotations

import argparse
import compileall
import os
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import pincal

sys.path.insert(0, str(Path(__file__).resolve().parent))
from figaroh_tiago import figaroh_available  # noqa: E402
from markdown_page import command_line, table, write_page  # noqa: E402
from real_data import load_tiago_data  # noqa: E402

HERE = Path(__file__).resolve().parent
SOURCE = HERE.parent / "src"
TIAGO = HERE.parents[1] / "shared" / "datasets" / "tiago_qualisys"
#: FIGAROH's whole script on the quiet machine where the issue's bars were set [s].
ANCHOR_THERE = 3.6
#: Peak resident memory allowed for the 10⁶ rows [GB].
MEMORY_BAR = 1.5
#: In-process timing of the command (row 3): imports first, then ``main`` timed.
IN_PROCESS = (
    "import sys, time, contextlib, io, pincal.cli\n"
    "t = time.perf_counter()\n"
    "with contextlib.redirect_stdout(io.StringIO()):\n"
    "    code = pincal.cli.main(sys.argv[1:])\n"
    "print(time.perf_counter() - t, code)\n"
)


@dataclass
class Row:
    """One row of the table: a command, its bar (seconds on the issue's machine) and its runs.

    Attributes:
        label: what is run.
        argv: the ``pincal`` arguments.
        bar_s: the bar [s] on the machine where the anchor took :data:`ANCHOR_THERE`.
        in_process: timed inside the process (start-up not counted).
        env: environment variables set for the run.
        source: the source tree on ``PYTHONPATH``.
        seconds: wall-clock time of each run [s].
        peak_gb: the largest peak resident memory of the runs [GB].
    """

    label: str
    argv: list[str]
    bar_s: float
    in_process: bool = False
    env: dict[str, str] = field(default_factory=dict)
    source: Path = SOURCE
    seconds: list[float] = field(default_factory=list)
    peak_gb: float = 0.0

    def run(self) -> None:
        """Run once, record the time [s] and the peak memory [GB]."""
        env = {**os.environ, **self.env, "PYTHONPATH": str(self.source)}
        code = ["-c", IN_PROCESS] if self.in_process else ["-m", "pincal"]
        start = time.perf_counter()
        child = subprocess.Popen(
            [sys.executable, *code, *self.argv], env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL
        )
        out = child.stdout.read() if child.stdout is not None else b""
        _, status, usage = os.wait4(child.pid, 0)
        wall = time.perf_counter() - start
        child.returncode = os.waitstatus_to_exitcode(status)
        if child.returncode != 0 or (self.in_process and out.split()[-1:] != [b"0"]):
            raise RuntimeError(f"{self.label}: exit {child.returncode}: {out.decode()[-300:]}")
        self.seconds.append(float(out.split()[0]) if self.in_process else wall)
        self.peak_gb = max(self.peak_gb, usage.ru_maxrss / 1e6)  # ru_maxrss in kB on Linux

    def cells(self, anchor: float) -> list[object]:
        """Label, median [s], ratio to the anchor, the bar as a ratio, whether it holds, memory."""
        seconds = statistics.median(self.seconds)
        ratio, bar = seconds / anchor, self.bar_s / ANCHOR_THERE
        holds = ratio <= bar and (self.peak_gb <= MEMORY_BAR or "10⁶" not in self.label)
        return [
            self.label,
            f"{seconds:.2f}",
            f"{ratio:.2f}",
            f"≤ {bar:.2f}",
            "yes" if holds else "NO",
            f"{self.peak_gb:.2f}",
        ]


def write_inputs(folder: Path, tiago: Path, million: bool) -> dict[str, Path]:
    """The CSVs of the rows: TIAGo's training day, 100 UR5 poses, 10,000 Panda poses (10⁶ UR5 rows)."""
    paths = {name: folder / f"{name}.csv" for name in ("tiago", "ur5", "panda")}
    _, train, _ = load_tiago_data(tiago)
    pincal.write_csv(paths["tiago"], train)
    ur5, panda = pincal.load_robot("ur5"), pincal.load_robot("panda")
    pincal.write_csv(paths["ur5"], pincal.simulate(ur5, n_fit=100, n_test=0, seed=0)[1])
    pincal.write_csv(paths["panda"], pincal.simulate(panda, n_fit=10000, n_test=0, seed=0, rot_noise=5e-4)[1])
    if million:  # in a child: a parent grown by 10⁶ simulated rows would lend its size to every row's peak
        paths["million"] = folder / "ur5_million.csv"
        code = (
            "import sys, pincal\n"
            "ur5 = pincal.load_robot('ur5')\n"
            "pincal.write_csv(sys.argv[1], pincal.simulate(ur5, n_fit=10**6, n_test=0, seed=0)[1])\n"
        )
        subprocess.run([sys.executable, "-c", code, str(paths["million"])], check=True)
        for kind in ("pose", "tcp"):  # benchmarks/scale.py's inputs
            paths[f"million_{kind}"] = folder / f"{kind}_million.csv"
            code = "import sys, scale; scale.write_input(sys.argv[1], sys.argv[2], 10**6)"
            subprocess.run(
                [sys.executable, "-c", code, kind, str(paths[f"million_{kind}"])], check=True, cwd=HERE
            )
    return paths


def make_rows(paths: dict[str, Path], tiago: Path, folder: Path, baseline: Path | None) -> list[Row]:
    """Every row, with its one-process and baseline variants."""
    out = str(folder / "report.json")
    urdf = str(tiago / "tiago_48_schunk.urdf")
    tiago_args = ["calibrate", urdf, str(paths["tiago"]), "--tip", "wrist_ft_tool_link"]
    tiago_args += ["--report", out, "--force"]
    diag_args = ["diagnose", "ur5", str(paths["ur5"]), "--json", out, "--force"]
    rows = [
        Row("pincal calibrate, TIAGo training day (37 poses)", tiago_args, 0.5 * ANCHOR_THERE),
        Row("pincal diagnose, 100 UR5 poses", diag_args, 1.5),
        Row(
            "default command, 10,000 Panda pose rows, in-process",
            ["calibrate", "panda", str(paths["panda"]), "--report", out, "--force"],
            10.0,
            in_process=True,
        ),
    ]
    if "million" in paths:
        rows += million_rows(paths, out)
    serial = [Row(f"{r.label}, one process", r.argv, r.bar_s, env={"PINCAL_WORKERS": "1"}) for r in rows[:2]]
    before = (
        []
        if baseline is None
        else [Row(f"{r.label}, baseline", r.argv, r.bar_s, r.in_process, source=baseline) for r in rows[:4]]
    )
    return rows + serial + before


def million_rows(paths: dict[str, Path], out: str) -> list[Row]:
    """The 10⁶ rows: the whole geometry on position and on pose rows, ``diagnose``, ``tcp`` and the
    default command, each ≤ 60 s on the issue's machine."""
    reported = ["--report", out, "--force"]
    fixed = ["--params", "all", "--extend", "none", *reported]
    position, pose, tcp = str(paths["million"]), str(paths["million_pose"]), str(paths["million_tcp"])
    return [
        Row("10⁶ UR5 rows, --params all --extend none", ["calibrate", "ur5", position, *fixed], 60.0),
        Row("10⁶ UR5 pose rows, --params all --extend none", ["calibrate", "ur5", pose, *fixed], 60.0),
        Row("pincal diagnose, 10⁶ UR5 rows", ["diagnose", "ur5", position, "--json", out, "--force"], 60.0),
        Row("pincal tcp, 10⁶ flange poses", ["tcp", tcp, "--report", out, "--force"], 60.0),
        Row(
            "default command, 10⁶ UR5 rows", ["calibrate", "ur5", position, "--report", out, "--force"], 60.0
        ),
    ]


def run_busy(row: Row) -> None:
    """Run ``row`` while another process keeps one core busy."""
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        row.run()
    finally:
        busy.kill()
        busy.wait()


def anchor_once(tiago: Path) -> float:
    """FIGAROH's whole TIAGo script, one process [s]."""
    start = time.perf_counter()
    script = [sys.executable, str(HERE / "figaroh_tiago.py"), "--script", str(tiago)]
    subprocess.run(script, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def main(argv: list[str] | None = None) -> None:
    """Run the rows alternating with the anchor, print the table (and write it as Markdown)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="runs of each row and of the anchor")
    parser.add_argument("--tiago", type=Path, default=TIAGO, help="the TIAGo dataset folder")
    parser.add_argument("--baseline", type=Path, help="another source tree, timed in the same run")
    parser.add_argument("--million", action="store_true", help="also the 10⁶ rows (minutes)")
    parser.add_argument("--busy", action="store_true", help="another process keeps a core busy (10⁶ rows)")
    parser.add_argument("--markdown", type=Path, help="also write the table in Markdown")
    args = parser.parse_args(argv)
    if args.baseline is not None and not (args.baseline / "pincal" / "__init__.py").is_file():
        sys.exit(f"--baseline {args.baseline}: no pincal source tree there (give the folder holding pincal/)")
    if not figaroh_available():
        sys.exit("the anchor is FIGAROH's script: pip install figaroh==1.0.2 (or '.[bench]')")
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        rows = make_rows(write_inputs(folder, args.tiago, args.million), args.tiago, folder, args.baseline)
        for source in {row.source for row in rows}:  # as installed (see the module's docstring)
            compileall.compile_dir(source, quiet=1)
        anchors = []
        for k in range(args.repeat):
            anchors.append(anchor_once(args.tiago))
            for row in rows:
                if "10⁶" not in row.label:
                    row.run()
                elif k == 0:  # the 10⁶ rows once
                    run_busy(row) if args.busy else row.run()
    anchor = statistics.median(anchors)
    header: list[object] = ["what", "median [s]", "/ anchor", "bar", "holds", "peak [GB]"]
    body: list[list[object]] = [r.cells(anchor) for r in rows]
    note = (
        f"anchor: FIGAROH's whole TIAGo script, median {anchor:.2f} s of {len(anchors)} runs "
        f"({ANCHOR_THERE} s where the bars were set); load average {load:.1f} at the start, "
        f"{os.cpu_count()} cores"
        + ("; another process kept one core busy during the 10⁶ rows" if args.busy else "")
    )
    text = "\n".join("  ".join(str(c) for c in row) for row in [header, *body])
    print(text + "\n" + note)
    if args.markdown is not None:
        names = {str(args.tiago).rstrip("/"): "TIAGO_DIR"}
        if args.baseline is not None:
            names[str(args.baseline).rstrip("/")] = "BASELINE_SRC"
        command = command_line("speed_bars.py", sys.argv[1:] if argv is None else argv, names)
        write_page(args.markdown, command, [table([str(h) for h in header], body), "", note])


if __name__ == "__main__":
    main()
