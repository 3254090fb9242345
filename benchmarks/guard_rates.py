"""The guard's error rates after ``params="auto"`` (or with every parameter given), on two simulators.

Sessions: UR5, tracker positions, Gaussian noise ``--sigma`` mm per axis, an unknown instrument
registration and an unknown reflector, random commands (the outer 5 % of each range avoided),
``--poses`` fitted poses, and 200 new poses over the WHOLE joint range to score on. Two truths:

* ``exact``: the URDF is the truth (nothing to calibrate): any exported fit is a false export;
* ``perturbed``: 0.5 mm / 0.5 mrad per axis on every joint origin and 1 mrad on every zero (the
  guard should export, and the export should beat the nominal model on the new poses).

Two simulators of the truth: ``own`` (:mod:`pincal.simulation.truth`) and ``audit`` (the
Pinocchio-only simulator of ``benchmarks/verdict_audit.py``, which never calls pincal to make
its points).

Each session runs ``pincal.calibrate(robot, fit, params="auto", pull=Pull(force_fit=True))``
(``--params all``: every parameter; ``--measure distance``: the points' pairwise distances;
``--measure pose``: the tool frame's orientation too, ``--sigma`` mrad per axis, on pincal's
simulator only) once: the fit, its guard ``z`` and the threshold are those of a normal call
(``force_fit`` only makes the fit the exported model, so its error on the new poses is known
whatever the guard says). ``before`` is the fixed threshold (``z > 2``); ``after`` the null of
selection + guard (``z > z_min``, :mod:`pincal.identify.guard_null`; with given parameters, the
null of the guard alone for distance data, the fixed threshold for positions and poses).

Usage::

    python benchmarks/guard_rates.py [--sessions 100] [--poses 15 30] [--sigma 0.05]
        [--truths exact perturbed] [--simulators own audit] [--measure position|pose|distance]
        [--params auto|all] [--json FILE] [--markdown FILE]
        [--load JSON ...] (with --sessions 0: only the table of saved sessions)
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
import pinocchio as pin
from markdown_page import command_line, table, write_page
from verdict_audit import SPECS, Truth
from verdict_audit import Robot as AuditRobot

import pincal
from pincal.data.dataset import Dataset
from pincal.identify.guard import Z_MIN
from pincal.simulation.truth import random_truth
from pincal.workers import parallel_map

N_NEW = 200  # new poses, over the whole range
WORSE = 1.05  # an exported fit more than 5 % worse than nominal on the new poses


@dataclass(frozen=True)
class Session:
    """One calibration: the guard's statistic, both thresholds, and the fit on the new poses."""

    simulator: str
    truth: str
    n_poses: int
    seed: int
    z: float
    z_min: float
    ratio: float  # RMS of the fit / RMS of the nominal model (registration fitted), new poses
    n_params: int
    seconds: float
    holds: bool = True  # the extrapolation check passes (a fit the guard kept is exported only then)

    @property
    def before(self) -> bool:
        """Exported by the fixed threshold."""
        return self.z > Z_MIN

    @property
    def after(self) -> bool:
        """Exported by the null of selection + guard."""
        return self.z > self.z_min

    @property
    def delivered(self) -> bool:
        """Exported by the command: the null's guard, then the check across the joint limits."""
        return self.after and self.holds


class Simulators:
    """Measured fit and new poses of a seeded session, by either simulator."""

    def __init__(self) -> None:
        self.robot = pincal.load_robot("ur5")
        self.audit = AuditRobot.load(SPECS["ur5"])
        order = [self.audit.joints.index(name) for name in self.robot.joint_names]
        self.order = np.array(order)

    def own(
        self, truth: str, n: int, seed: int, sigma: float, turn: float | None = None
    ) -> tuple[Dataset, Dataset]:
        """pincal's simulator: the URDF (``exact``) or a perturbed robot; ``turn``: the tool
        frame's orientation measured too, with that noise per axis [rad]."""
        true = random_truth(self.robot, seed, tool_distance=(0.05, 0.05))
        if truth == "exact":
            true = replace(true, x=np.zeros_like(true.x))
        rng = np.random.default_rng([seed, n, 1])
        q_fit = self.robot.random_configurations(n, rng, 0.05)
        q_new = self.robot.random_configurations(N_NEW, rng, 0.0)
        fit, new = (true.measure(q, sigma, turn, seed=seed + k) for q, k in ((q_fit, 7), (q_new, 8)))
        return fit, new

    def audit_truth(
        self, truth: str, n: int, seed: int, sigma: float, margin: float | None = None
    ) -> tuple[Dataset, Dataset]:
        """``verdict_audit``'s simulator (Pinocchio only); the fitted poses leave out ``margin`` of
        each joint's range at both ends (None: ``verdict_audit.Robot.sample``'s 5 %)."""
        rng = np.random.default_rng([seed, n, 2])
        drawn = Truth.draw(self.audit, rng)
        if truth == "exact":
            drawn = Truth(pin.Model(self.audit.model), np.zeros(self.audit.model.nq), *_rest(drawn))
        lo, hi = self.audit.model.lowerPositionLimit, self.audit.model.upperPositionLimit
        if margin is None:
            q_fit = self.audit.sample(rng, n)
        else:
            span = margin * (hi - lo)
            q_fit = rng.uniform(lo + span, hi - span, size=(n, self.audit.model.nq))
        q_new = rng.uniform(lo, hi, size=(N_NEW, self.audit.model.nq))
        return self.measured(drawn, q_fit, sigma, rng), self.measured(drawn, q_new, sigma, rng)

    def measured(self, truth: Truth, q: np.ndarray, sigma: float, rng: np.random.Generator) -> Dataset:
        points = truth.points(q + truth.offsets) + rng.normal(0.0, sigma, (len(q), 3))
        return Dataset(self.robot.joint_names, q[:, self.order], points)


def _rest(truth: Truth) -> tuple[pin.SE3, np.ndarray, int]:
    return truth.instrument_T_base, truth.tool, truth.tip_id


def run(
    sims: Simulators,
    key: tuple[str, str, int, int],
    sigma: float,
    measure: str = "position",
    params: str = "auto",
) -> Session:
    """One session (``key``: simulator, truth, poses, seed; ``sigma`` in metres), the points
    calibrated as ``measure`` data (``distance``: every pair of them) on the parameters ``params``
    (``auto`` or ``all``)."""
    simulator, truth, n, seed = key
    if simulator == "own":
        fit, new = sims.own(truth, n, seed, sigma, sigma if measure == "pose" else None)
    else:
        fit, new = sims.audit_truth(truth, n, seed, sigma)
    start = time.perf_counter()
    wanted = "auto" if params == "auto" else None
    force = pincal.Pull(force_fit=True)
    cal = pincal.calibrate(sims.robot, fit, measure=measure, params=wanted, test=new, pull=force)
    seconds = time.perf_counter() - start
    assert cal.guard is not None and cal.test_after is not None and cal.test_before is not None
    ratio = cal.test_after.rms_mm / cal.test_before.rms_mm
    n_params = 0 if cal.choice is None or cal.choice.params is None else len(cal.choice.params)
    guard = cal.guard
    return Session(simulator, truth, n, seed, guard.z, guard.z_min, ratio, n_params, seconds, guard.holds)


def summary(sessions: list[Session]) -> list[list[object]]:
    """One row per simulator, truth and pose count."""
    rows: list[list[object]] = []
    keys = sorted({(s.simulator, s.truth, s.n_poses) for s in sessions})
    for simulator, truth, n in keys:
        group = [s for s in sessions if (s.simulator, s.truth, s.n_poses) == (simulator, truth, n)]
        row: list[object] = [simulator, truth, n, len(group)]
        for rule in ("before", "after", "delivered"):
            kept = [s for s in group if getattr(s, rule)]
            worse = sum(s.ratio > WORSE for s in kept)
            worst = f"{max(s.ratio for s in kept):.3f}" if kept else "-"
            row += [f"{len(kept)} ({len(kept) / len(group):.0%})", worse, worst]
        row.append(f"{np.median([s.z_min for s in group]):.2f}")
        rows.append(row)
    return rows


HEADER = (
    "simulator",
    "truth",
    "poses",
    "sessions",
    "exported, z > 2",
    "of them > 5 % worse",
    "worst ratio",
    "exported, null threshold",
    "of them > 5 % worse",
    "worst ratio",
    "exported, null threshold + check across the limits",
    "of them > 5 % worse",
    "worst ratio",
    "median threshold",
)


LINE = re.compile(r"^(\w+) (\w+) (\d+) (\d+): z (\S+) > (\S+)\? ratio (\S+) \((\S+) s\)$")


def load(path: Path) -> list[Session]:
    """Sessions saved by ``--json``, or read back from the lines a run printed (``.log``: the
    number of parameters is not printed, and reads 0)."""
    if path.suffix != ".log":
        return [Session(**item) for item in json.loads(path.read_text())]
    out = []
    for line in path.read_text().splitlines():
        found = LINE.match(line.strip())
        if found:
            sim, truth, n, seed, z, z_min, ratio, seconds = found.groups()
            out.append(
                Session(
                    sim, truth, int(n), int(seed), float(z), float(z_min), float(ratio), 0, float(seconds)
                )
            )
    return out


def main(argv: list[str] | None = None) -> int:
    """Run the sessions, print the table, write it (``--markdown``) and the sessions (``--json``)."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--sessions", type=int, default=100)
    parser.add_argument("--poses", type=int, nargs="+", default=[15, 30])
    parser.add_argument("--sigma", type=float, default=0.05, help="noise per axis [mm]")
    parser.add_argument("--truths", nargs="+", default=["exact", "perturbed"])
    parser.add_argument("--simulators", nargs="+", default=["own", "audit"])
    parser.add_argument("--measure", default="position", choices=["position", "pose", "distance"])
    parser.add_argument("--params", default="auto", choices=["auto", "all"], help="chosen, or every one")
    parser.add_argument("--jobs", type=int, default=2, help="sessions run at once")
    parser.add_argument("--json", type=Path)
    parser.add_argument("--markdown", type=Path)
    parser.add_argument("--runs", default="", help="how the --load sessions were run, for the page")
    parser.add_argument(
        "--load", type=Path, nargs="*", default=[], help="saved: --json files or printed lines (.log)"
    )
    args = parser.parse_args(argv)
    if args.measure == "pose" and "audit" in args.simulators and args.sessions:
        parser.error("the audit simulator measures positions only: --measure pose needs --simulators own")
    sessions = [s for path in args.load for s in load(path)]
    sims = Simulators()
    keys = [
        (simulator, truth, n, seed)
        for simulator in (args.simulators if args.sessions else ())
        for truth in args.truths
        for n in args.poses
        for seed in range(args.sessions)
    ]

    def task(k: int) -> Session:
        return run(sims, keys[k], args.sigma * 1e-3, args.measure, args.params)

    ran: list[Session] = parallel_map(task, len(keys), args.jobs)
    for s in ran:
        said = f"{s.simulator} {s.truth} {s.n_poses} {s.seed}: z {s.z:.2f} > {s.z_min:.2f}?"
        print(f"{said} ratio {s.ratio:.3f} ({s.seconds:.1f} s)")
    sessions += ran
    rows = summary(sessions)
    text = table(HEADER, rows)
    print(text)
    if args.json:
        args.json.write_text(json.dumps([asdict(s) for s in sessions], indent=1))
    if args.markdown:
        given = sys.argv[1:] if argv is None else argv
        names = {str(path): path.name for path in args.load}
        line = command_line(
            "guard_rates.py", [a for a in given if not a.startswith("--runs") and a != args.runs], names
        )
        write_page(args.markdown, line, [args.runs, "", text] if args.runs else [text])
    return 0


if __name__ == "__main__":
    sys.exit(main())
