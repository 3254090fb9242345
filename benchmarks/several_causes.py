"""Several listed causes at once (issue 39, acceptance items 1 and 2), on two simulators.

Each run simulates a robot with one to three listed effects at once on different joints (lost
motion among them in most cases), or a control (nothing hidden; one effect outside the list),
runs ``pincal calibrate ROBOT train.csv --extend auto --noise 0.03 --test later.csv --report r.json
-o cal.urdf`` as an outside user would (a subprocess, CSV in, files out), and reads the written URDF
+ sidecar by ``contracts.md`` alone (``../shared/tools/contract_predict.py``, imported by path).

Simulators (``--sims``):

* ``own``: pincal's own (:func:`pincal.simulation.truth.random_truth`, the effects hidden by
  :func:`pincal.simulation.truth.hide_effects`, each scaled to its tip RMS on its own; the
  out-of-list ``sin3`` is pincal's ``gear_harmonic`` of order 3, which the diagnosis does not list);
* ``pin``: an independent one, Pinocchio only (the truth of ``verdict_audit.py``: perturbed joint
  placements and zeros, unknown registration and tool point 5 cm from the tip), with the effects
  written here from ``contracts.md``'s definitions, as joint errors added to the reached angle:
  ``joint_compliance`` ``c·τ`` (c < 0: the joint sags), ``backlash`` ``b·sign(τ)`` (b < 0: toward
  gravity), gravity torques ``pin.computeGeneralizedGravity`` on the true model; ``gear_harmonic``
  orders 1 and 2 ``a·sin(h q + φ)``; ``encoder_scale`` ``s·(q - middle of the range)``;
  ``lost_motion`` ``v·s`` (v < 0: the joint lags its command), s the sign of the command's move
  from the previous row of the whole session (the previous row's sign when it moved by 1e-9 or
  less, 0 on the very first row). Out-of-list controls: ``sin3`` (``a·sin(3q + φ)``) and ``drift``
  (the instrument drifts linearly with the row index along a fixed direction).

Every effect moves the measured point by a random 0.3-0.6 mm RMS on its own over the session. The
session is ``--poses`` (default 120) fitted rows then ``--test-poses`` (default 30) held-out rows,
LATER in time, all random configurations visited one after another (outer 5 % of each range
avoided); 0.03 mm Gaussian noise per axis; registration and tool point unknown to pincal. The
held-out rows are a separate ``--test`` CSV, whose first row's direction is unknown (s = 0).

Checks per run (exit status 1 when one fails, or a run does not exit 0):

1. ``names``: the report's ``choice.causes`` are exactly the hidden listed effects, each with its
   joint (``EFFECT:JOINT``, ``gear_harmonic2:JOINT``); nothing for a rigid control (an out-of-list
   control: shown, not judged);
2. ``truth``: the RMS over the held-out rows but the first of the full model's prediction (URDF +
   sidecar, by the contract) minus the noise-free truth is at most 0.6 × the noise floor
   (√3 × 0.03 mm) for listed effects and rigid controls (out-of-list: shown, not judged);
3. ``verdict``: ``explained`` for listed effects and rigid controls, ``unexplained`` out of the list;
4. ``files``: the files, by the contract alone, reproduce ``test.after`` (full model) and
   ``test.exported`` (URDF alone) on the held-out CSV, and ``train.after`` / ``train.exported`` on
   the fitted CSV (its ``train.rows``), each to 1e-6 mm.

Usage::

    python benchmarks/several_causes.py [--quick] [--sims own pin] [--robots ur5 panda]
        [--cases NAME ...] [--seeds 1] [--first-seed 0] [--poses 120] [--test-poses 30] [--jobs 1]
        [--markdown docs/results/generated/several_causes.md] [--json FILE] [--keep DIR]

The default runs every case on ur5 and panda with both simulators (36 runs, about 25 min on two
cores). ``--quick``: four runs per simulator on ur5 (a rigid control, two and three listed
effects, one out-of-list control), 8 runs of 10-60 s each.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import importlib.util  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import zlib  # noqa: E402
from concurrent.futures import ThreadPoolExecutor  # noqa: E402
from dataclasses import asdict, dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402
from types import ModuleType  # noqa: E402

import numpy as np  # noqa: E402
import verdict_audit  # noqa: E402  (the independent simulator's truth, Pinocchio only)
from markdown_page import command_line, table, text_block, write_page  # noqa: E402

NOISE_MM = 0.03
FLOOR_MM = np.sqrt(3.0) * NOISE_MM
TRUTH_FACTOR = 0.6  # check 2: held-out RMS against the truth <= this x the floor
REPRO_MM = 1e-6  # check 4
SIZE_MM = (0.3, 0.6)  # each effect's RMS at the tip
TIMEOUT_S = 1200.0
CONTRACT_PREDICT = Path(__file__).resolve().parents[2] / "shared" / "tools" / "contract_predict.py"

#: The joints the cases name by role, per robot.
ROLES = {
    "ur5": {
        "base": "shoulder_pan_joint",
        "lift": "shoulder_lift_joint",
        "elbow": "elbow_joint",
        "wrist1": "wrist_1_joint",
        "wrist2": "wrist_2_joint",
    },
    "panda": {
        "base": "panda_joint1",
        "lift": "panda_joint2",
        "elbow": "panda_joint4",
        "wrist1": "panda_joint6",
        "wrist2": "panda_joint5",
    },
}

#: Each case: its effects as ``EFFECT:ROLE`` (listed) or ``sin3:ROLE`` / ``drift`` (out of the list).
CASES: dict[str, tuple[str, ...]] = {
    "rigid": (),
    "lm": ("lost_motion:elbow",),
    "comp+lm": ("joint_compliance:lift", "lost_motion:wrist1"),
    "h1+scale": ("gear_harmonic:elbow", "encoder_scale:wrist1"),
    "lm+lm": ("lost_motion:lift", "lost_motion:wrist2"),
    "h2+h1+lm": ("gear_harmonic2:wrist2", "gear_harmonic:lift", "lost_motion:base"),
    "bl+lm+h2": ("backlash:elbow", "lost_motion:lift", "gear_harmonic2:base"),
    "sin3": ("sin3:elbow",),
    "drift": ("drift",),
}
OUTSIDE = ("sin3", "drift")
QUICK = {"own": ("rigid", "comp+lm", "h2+h1+lm", "sin3"), "pin": ("rigid", "h1+scale", "bl+lm+h2", "drift")}


def load_contract_predict(path: Path) -> ModuleType:
    """``contract_predict.py`` imported by path, as an outside test does."""
    spec = importlib.util.spec_from_file_location("contract_predict", path)
    if spec is None or spec.loader is None:
        raise SystemExit(f"cannot import {path}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def case_kind(case: str) -> str:
    """``rigid``, ``outside`` or ``listed``."""
    if not CASES[case]:
        return "rigid"
    return "outside" if any(e.split(":")[0] in OUTSIDE for e in CASES[case]) else "listed"


def labels(case: str, robot: str) -> list[str]:
    """The case's effects as ``EFFECT:JOINT`` (``drift`` alone)."""
    out = []
    for item in CASES[case]:
        effect, _, role = item.partition(":")
        out.append(f"{effect}:{ROLES[robot][role]}" if role else effect)
    return out


def case_rng(sim: str, robot: str, case: str, seed: int) -> np.random.Generator:
    """A generator seeded by the run's names, stable across runs and case lists."""
    key = [zlib.crc32(s.encode()) for s in (sim, robot, case)] + [seed]
    return np.random.default_rng(np.random.SeedSequence(key))


def rms_mm(displacement: np.ndarray) -> float:
    """RMS over rows of the norm of a (N, 3) displacement in metres, in mm."""
    return float(np.sqrt(np.mean(np.sum(displacement**2, axis=1)))) * 1e3


def drift_displacement(n: int, size_m: float, rng: np.random.Generator) -> np.ndarray:
    """The instrument drifting along a fixed direction linearly with the row index, centred (N, 3) [m]."""
    direction = rng.normal(size=3)
    shape = (np.arange(n) / (n - 1) - 0.5)[:, None] * (direction / np.linalg.norm(direction))[None, :]
    return shape * size_m / np.sqrt(np.mean(np.sum(shape**2, axis=1)))


# --------------------------------------------------------------------------------------------------
# The two simulators: (joint names, tip, commands (N, n) in visiting order, noise-free points (N, 3))
# --------------------------------------------------------------------------------------------------


@dataclass
class Session:
    """A simulated session: commands in the order visited, noise-free and measured points [m]."""

    joints: list[str]
    tip: str
    q: np.ndarray
    clean: np.ndarray
    measured: np.ndarray
    sizes_mm: list[float]


def simulate_own(robot_name: str, case: str, n: int, rng: np.random.Generator) -> Session:
    """pincal's own simulator: :func:`random_truth` with the case's effects hidden by
    :func:`hide_effects` over the whole session (directions from the rows' order)."""
    import pincal
    from pincal.kinematics.effects import Extension
    from pincal.simulation.truth import hide_effects, random_truth

    robot = pincal.load_robot(robot_name)
    seed = int(rng.integers(2**31))
    truth = random_truth(robot, seed)
    q = robot.random_configurations(n, rng, margin=0.05)
    items = labels(case, robot_name)
    sizes = [float(rng.uniform(*SIZE_MM)) for _ in items]
    joint_items = [(lab, s) for lab, s in zip(items, sizes) if lab != "drift"]
    extensions = []
    for lab, _ in joint_items:
        effect, _, joint = lab.partition(":")
        if effect == "sin3":
            extensions.append(Extension(robot, "gear_harmonic", joint, 3))
        else:
            extensions.append(Extension.parse(robot, lab))
    if extensions:
        truth = hide_effects(truth, extensions, q, [s * 1e-3 for _, s in joint_items], seed)
    clean = truth.target(q)[0]
    for lab, s in zip(items, sizes):
        if lab == "drift":
            clean = clean + drift_displacement(n, s * 1e-3, rng)
    measured = clean + rng.normal(0.0, NOISE_MM * 1e-3, clean.shape)
    return Session(list(robot.joint_names), robot.tip, q, clean, measured, sizes)


def move_signs(q: np.ndarray) -> np.ndarray:
    """The direction of each joint's command into each row (contracts.md), written here again."""
    step = np.diff(q, axis=0, prepend=q[:1])
    sign = np.sign(step) * (np.abs(step) > 1e-9)
    for i in range(1, len(sign)):
        still = sign[i] == 0
        sign[i, still] = sign[i - 1, still]
    return sign


def effect_shape(
    effect: str,
    q: np.ndarray,
    tau: np.ndarray,
    signs: np.ndarray,
    phase: float,
    sign: float,
    limits: tuple[float, float],
) -> np.ndarray:
    """The joint error's shape (N,) of an effect on one joint, before scaling: commands ``q``,
    gravity torques ``tau`` and move directions ``signs`` of that joint, a harmonic's ``phase``, an
    encoder scale's ``sign`` and the joint's ``limits``."""
    if effect == "joint_compliance":
        return -tau  # the joint sags under its load
    if effect == "backlash":
        return -np.sign(tau) * (np.abs(tau) > 1e-9)  # on the flank gravity pushes it to
    if effect == "lost_motion":
        return -signs  # the joint lags its command
    if effect == "encoder_scale":
        return sign * (q - 0.5 * (limits[0] + limits[1]))
    order = {"gear_harmonic": 1, "gear_harmonic2": 2, "sin3": 3}[effect]
    return np.sin(order * q + phase)


def simulate_pin(robot_name: str, case: str, n: int, rng: np.random.Generator) -> Session:
    """The independent simulator (Pinocchio only): ``verdict_audit``'s truth and joint-error scaling,
    the effects written from contracts.md here."""
    robot = verdict_audit.Robot.load(verdict_audit.SPECS[robot_name])
    truth = verdict_audit.Truth.draw(robot, rng)
    q_cmd = robot.sample(rng, n)
    reached = q_cmd + truth.offsets
    items = labels(case, robot_name)
    sizes = [float(rng.uniform(*SIZE_MM)) for _ in items]
    errors = np.zeros_like(q_cmd)
    tau = truth.gravity(reached)
    signs = move_signs(q_cmd)
    drift = np.zeros((n, 3))
    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    for lab, size in zip(items, sizes):
        if lab == "drift":
            drift = drift + drift_displacement(n, size * 1e-3, rng)
            continue
        effect, _, joint = lab.partition(":")
        j = robot.joint_index(joint)
        phase = rng.uniform(0.0, 2.0 * np.pi)
        sign = rng.choice([-1.0, 1.0])
        shape = effect_shape(effect, q_cmd[:, j], tau[:, j], signs[:, j], phase, sign, (lo[j], hi[j]))
        each, _ = verdict_audit.joint_effect(truth, reached, {j: shape}, size * 1e-3)
        errors = errors + each
    clean = truth.points(reached + errors) + drift
    measured = clean + rng.normal(0.0, NOISE_MM * 1e-3, clean.shape)
    return Session(list(robot.joints), robot.tip, q_cmd, clean, measured, sizes)


SIMULATORS = {"own": simulate_own, "pin": simulate_pin}


# --------------------------------------------------------------------------------------------------
# One run
# --------------------------------------------------------------------------------------------------


@dataclass
class Run:
    """One simulator x robot x case x seed, and what it gave."""

    sim: str
    robot: str
    case: str
    seed: int
    kind: str
    hidden: list[str]
    sizes_mm: list[float]
    named: list[str] = field(default_factory=list)
    verdict: str | None = None
    unexplained_mm: float | None = None
    truth_full_mm: float | None = None  # held-out rows but the first: full model - noise-free truth
    truth_alone_mm: float | None = None  # the same for the URDF alone
    test_after_mm: float | None = None
    test_exported_mm: float | None = None
    repro_mm: float | None = None  # the largest |files - report| of the four ERRs
    rc: int = 0
    seconds: float = 0.0
    error: str = ""
    checks: dict[str, bool | None] = field(default_factory=dict)

    @property
    def ratio(self) -> float | None:
        return None if self.truth_full_mm is None else self.truth_full_mm / FLOOR_MM

    @property
    def passed(self) -> bool:
        return self.rc == 0 and all(v is not False for v in self.checks.values())


def write_csv(path: Path, joints: list[str], q: np.ndarray, points: np.ndarray) -> None:
    """The measurement CSV of contracts.md (rad, m), rows in the order visited."""
    verdict_audit.write_csv(path, joints, q, points)


def expected_names(run: Run) -> list[str]:
    """The causes the report should list: the hidden listed effects (``gear_harmonic:J`` for order 1)."""
    return sorted(run.hidden) if run.kind == "listed" else []


def execute(run: Run, n_fit: int, n_test: int, workdir: Path, cp: ModuleType) -> Run:
    """Simulate, calibrate, read the files by the contract and check."""
    rng = case_rng(run.sim, run.robot, run.case, run.seed)
    session = SIMULATORS[run.sim](run.robot, run.case, n_fit + n_test, rng)
    run.sizes_mm = [round(s, 3) for s in session.sizes_mm]
    stem = workdir / f"{run.sim}_{run.robot}_{run.case.replace('+', '_')}_s{run.seed}"
    fit_csv, test_csv = Path(f"{stem}.fit.csv"), Path(f"{stem}.test.csv")
    write_csv(fit_csv, session.joints, session.q[:n_fit], session.measured[:n_fit])
    write_csv(test_csv, session.joints, session.q[n_fit:], session.measured[n_fit:])
    report_path, urdf = Path(f"{stem}.report.json"), Path(f"{stem}.urdf")
    args = [run.robot, str(fit_csv), "--tip", session.tip, "--extend", "auto", "--noise", f"{NOISE_MM:g}"]
    args += ["--test", str(test_csv), "--report", str(report_path), "-o", str(urdf)]
    env = dict(os.environ, PINCAL_THREADS=os.environ.get("PINCAL_THREADS", "1"))
    start = time.perf_counter()
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "pincal", "calibrate", *args],
            capture_output=True,
            text=True,
            timeout=TIMEOUT_S,
            env=env,
            check=False,
        )
        run.rc, stderr = proc.returncode, proc.stderr
    except subprocess.TimeoutExpired:
        run.rc, stderr = -9, f"timeout after {TIMEOUT_S:.0f} s"
    run.seconds = time.perf_counter() - start
    if run.rc != 0 or not report_path.exists():
        run.error = " | ".join(line for line in stderr.strip().splitlines()[-3:])
        return run
    report = json.loads(report_path.read_text())
    run.named = [c["cause"] for c in (report.get("choice") or {}).get("causes") or []]
    residual = report.get("residual") or {}
    run.verdict, run.unexplained_mm = residual.get("verdict"), residual.get("unexplained_mm")
    run.test_after_mm = report["test"]["after"]["rms_mm"]
    run.test_exported_mm = report["test"]["exported"]["rms_mm"]
    sidecar = Path(f"{stem}.calibration.json")
    joints = json.loads(sidecar.read_text())["joints"]
    gaps = []
    for part, csv_path in (("test", test_csv), ("train", fit_csv)):
        q, meas = cp._read(str(csv_path), joints, False, 1.0)
        measured = next(iter(meas.values()))
        rows = np.arange(len(q))
        if part == "train":
            rows = np.asarray(report["train"].get("rows") or rows + 1) - 1
        for key, alone in (("after", False), ("exported", True)):
            predicted = cp.predict(str(sidecar), q, alone=alone)
            gaps.append(abs(cp.rms_mm(predicted[rows], measured[rows]) - report[part][key]["rms_mm"]))
            if part == "test":  # against the noise-free truth, the first held-out row left out
                truth = session.clean[n_fit:]
                value = rms_mm(predicted[1:] - truth[1:])
                if alone:
                    run.truth_alone_mm = value
                else:
                    run.truth_full_mm = value
    run.repro_mm = float(max(gaps))
    listed = run.kind != "outside"
    run.checks = {
        "names": bool(sorted(run.named) == expected_names(run)) if listed else None,
        "truth": bool((run.truth_full_mm or 0.0) <= TRUTH_FACTOR * FLOOR_MM) if listed else None,
        "verdict": bool(run.verdict == ("explained" if listed else "unexplained")),
        "files": bool(run.repro_mm <= REPRO_MM),
    }
    return run


# --------------------------------------------------------------------------------------------------
# Table, page, main
# --------------------------------------------------------------------------------------------------

HEADER = (
    "sim",
    "robot",
    "case",
    "hidden (mm RMS each)",
    "named",
    "verdict (unexpl. mm)",
    "held-out vs truth: full / alone [mm]",
    "full / floor",
    "test after / exported [mm]",
    "files gap [mm]",
    "checks",
    "time [s]",
)


def _mark(value: bool | None) -> str:
    return "-" if value is None else "ok" if value else "FAIL"


def row(run: Run) -> list[str]:
    """The table's row of a run."""
    hidden = ", ".join(f"{h} {s:.2f}" for h, s in zip(run.hidden, run.sizes_mm)) or "none"

    def f(x: float | None, digits: int = 3) -> str:
        return "-" if x is None else f"{x:.{digits}f}"

    checks = " ".join(f"{k}:{_mark(v)}" for k, v in run.checks.items()) if run.rc == 0 else f"rc {run.rc}"
    return [
        run.sim,
        run.robot,
        f"{run.case} s{run.seed}",
        hidden,
        ", ".join(run.named) or "none",
        f"{run.verdict} ({f(run.unexplained_mm)})",
        f"{f(run.truth_full_mm)} / {f(run.truth_alone_mm)}",
        f(run.ratio, 2),
        f"{f(run.test_after_mm)} / {f(run.test_exported_mm)}",
        "-" if run.repro_mm is None else f"{run.repro_mm:.1e}",
        checks,
        f"{run.seconds:.0f}",
    ]


def summary(runs: list[Run]) -> list[str]:
    """Pass counts per check and the failing runs."""
    lines = []
    for check in ("names", "truth", "verdict", "files"):
        judged = [r for r in runs if r.checks.get(check) is not None]
        ok = sum(bool(r.checks[check]) for r in judged)
        lines.append(f"{check}: {ok}/{len(judged)} pass")
    crashed = [r for r in runs if r.rc != 0]
    lines.append(f"runs exiting 0: {len(runs) - len(crashed)}/{len(runs)}")
    for r in runs:
        if not r.passed:
            failed = [k for k, v in r.checks.items() if v is False] or [f"rc {r.rc}: {r.error}"]
            ratio = "-" if r.ratio is None else f"{r.ratio:.2f}"
            lines.append(
                f"FAIL {r.sim} {r.robot} {r.case} s{r.seed}: {', '.join(failed)}; hidden "
                f"{', '.join(r.hidden) or 'none'}, named {', '.join(r.named) or 'none'}, verdict "
                f"{r.verdict}, full/floor {ratio}"
            )
    lines.append(f"overall: {'PASS' if all(r.passed for r in runs) else 'FAIL'}")
    lines.append(f"calibrate time: {sum(r.seconds for r in runs):.0f} s in all, {len(runs)} runs")
    return lines


def parse(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="4 runs per simulator on ur5")
    parser.add_argument("--sims", nargs="+", choices=tuple(SIMULATORS), default=list(SIMULATORS))
    parser.add_argument("--robots", nargs="+", choices=tuple(ROLES), default=list(ROLES))
    parser.add_argument("--cases", nargs="+", choices=tuple(CASES), help="default: every case")
    parser.add_argument("--seeds", type=int, default=1)
    parser.add_argument("--first-seed", type=int, default=0, help="seeds run: first-seed .. + seeds - 1")
    parser.add_argument("--poses", type=int, default=120, help="fitted rows")
    parser.add_argument("--test-poses", type=int, default=30, help="held-out rows, after the fitted ones")
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--contract-predict", type=Path, default=CONTRACT_PREDICT)
    parser.add_argument("--markdown", type=Path, metavar="MD", help="write the table and summary here")
    parser.add_argument("--json", type=Path, help="save every run's record")
    parser.add_argument("--keep", type=Path, help="keep the CSVs, reports and files here")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse(argv)
    cp = load_contract_predict(args.contract_predict)
    runs = []
    for sim in args.sims:
        robots = ["ur5"] if args.quick else args.robots
        cases = args.cases or (QUICK[sim] if args.quick else tuple(CASES))
        for robot in robots:
            for case in cases:
                for seed in range(args.first_seed, args.first_seed + (1 if args.quick else args.seeds)):
                    hidden = labels(case, robot)
                    runs.append(Run(sim, robot, case, seed, case_kind(case), hidden, []))
    print(f"{len(runs)} runs; noise {NOISE_MM} mm per axis, floor {FLOOR_MM:.4f} mm", flush=True)
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        workdir = args.keep or Path(tmp)
        workdir.mkdir(parents=True, exist_ok=True)

        def one(run: Run) -> Run:
            done = execute(run, args.poses, args.test_poses, workdir, cp)
            print(" | ".join(row(done)), flush=True)
            return done

        with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            runs = list(pool.map(one, runs))
    lines = summary(runs)
    lines.append(f"wall time: {time.perf_counter() - started:.0f} s")
    text = table(HEADER, [row(r) for r in runs])
    print()
    print(text)
    print()
    print("\n".join(lines))
    if args.markdown:
        argv_used = list(sys.argv[1:] if argv is None else argv)
        if "--keep" in argv_used:  # a folder of this machine: not part of the command
            at = argv_used.index("--keep")
            del argv_used[at : at + 2]
        notes = (
            f"Fitted rows {args.poses}, held-out rows {args.test_poses} (later in time, a separate "
            f"`--test` CSV); noise {NOISE_MM} mm per axis; floor √3 × {NOISE_MM} = {FLOOR_MM:.4f} mm. "
            "`full / floor`: the full model (URDF + sidecar, read by the contract) against the "
            "noise-free truth over the held-out rows but the first, divided by the floor (check: "
            f"≤ {TRUTH_FACTOR}). `files gap`: the largest difference between the report's "
            "train/test `after`/`exported` and the files read by the contract (check: ≤ 1e-6 mm)."
        )
        write_page(
            args.markdown,
            command_line("several_causes.py", argv_used, {}),
            [notes, "", text, "", text_block("\n".join(lines))],
        )
        print(f"Markdown written to {args.markdown}")
    if args.json:
        args.json.write_text(json.dumps([asdict(r) for r in runs], indent=1))
    return 0 if all(r.passed for r in runs) else 1


if __name__ == "__main__":
    sys.exit(main())
