"""The guard's extrapolation check: exported fits worse than nominal across the joint limits.

Sessions: UR5, tracker positions, Gaussian noise ``--sigma`` mm per axis, an unknown instrument
registration and an unknown reflector 5 cm from the tool flange, 30 fitted poses and 200 new poses
over the WHOLE joint range to score on. Two ranges of the fitted poses:

* ``narrow``: inside the central 6 % of each joint's range (47 % of it left out at both ends);
* ``whole``: the outer 5 % of each range avoided.

Two truths: ``exact`` (the URDF is the truth) and ``perturbed`` (0.5 mm / 0.5 mrad per axis on
every joint origin and 1 mrad on every zero; :func:`pincal.random_truth`).

Each session runs ``pincal.calibrate(robot, fit, params="auto", pull=Pull(force_fit=True))``
once: the guard's verdict and the extrapolation check's are those of a default call, and
``force_fit`` makes the fit the exported model, so that its error on the new poses is known
whatever they say. ``before``: exported by the guard alone (``z > z_min``); ``after``: by the
guard and the check (:mod:`pincal.identify.extrapolation`). "worse": the fit's RMS on the new
poses more than 5 % above the nominal model's (registration and tool fitted).

``--measure pose`` measures the tool frame's orientation too (``--sigma`` mrad per axis as well);
``--measure distance`` fits the distances between every two fitted poses (no registration) and
scores the distances between every two new poses.

``--simulator audit`` draws the sessions with the Pinocchio-only simulator of
``benchmarks/verdict_audit.py`` (through ``guard_rates.Simulators.audit_truth``) instead of
pincal's own (``own``, the default): ``exact`` is the URDF with the audit's registration and tool
point, ``perturbed`` is ``verdict_audit.Truth.draw``; the same ranges of fitted poses, new poses
uniform over the whole range. Its points are positions: ``position`` and ``distance`` measures
only.

The check's cost (``--cost K``): ``K`` default ``pincal calibrate`` runs on 100 simulated poses
(:func:`pincal.simulate`), the time spent in the check over the run's.

Usage::

    python benchmarks/extrapolation.py [--sessions 100] [--quick] [--sigma 0.05] [--cost 5]
        [--measure position|pose|distance] [--simulator own|audit]
        [--json FILE] [--markdown FILE]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, replace
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
from guard_rates import Simulators
from markdown_page import command_line, table, write_page

import pincal
from pincal.workers import parallel_map

N_FIT = 30
N_NEW = 200
WORSE = 1.05
MARGINS = {"narrow": 0.47, "whole": 0.05}
GROUPS = (("narrow", "exact"), ("narrow", "perturbed"), ("whole", "perturbed"), ("whole", "exact"))


@dataclass(frozen=True)
class Session:
    """One calibration: both verdicts and the fit's error on the new poses over the nominal's."""

    range: str
    truth: str
    seed: int
    guard: bool  # the guard alone exports the fit
    holds: bool  # the extrapolation check passes (True when the guard refused: not checked)
    ratio: float  # RMS of the fit / RMS of the nominal model, new poses over the whole range
    whole_gain_mm2: float | None
    data_gain_mm2: float | None
    seconds: float
    whole_gain_sd_mm2: float | None = None
    measure: str = "position"
    simulator: str = "own"

    @property
    def before(self) -> bool:
        """Exported by the guard alone."""
        return self.guard

    @property
    def after(self) -> bool:
        """Exported by the guard and the extrapolation check."""
        return self.guard and self.holds


@cache
def simulators() -> Simulators:
    """``guard_rates``' simulators, made once per process (before the workers fork: inherited)."""
    return Simulators()


def run(
    where: str, truth: str, seed: int, sigma: float, measure: str = "position", simulator: str = "own"
) -> Session:
    """One session (``sigma`` in metres, and radians per axis of orientation for pose data), drawn
    by pincal's simulator (``own``) or ``verdict_audit``'s (``audit``: positions only)."""
    if simulator == "audit":
        if measure == "pose":
            raise ValueError("the audit simulator measures positions only")
        robot = simulators().robot
        fit, new = simulators().audit_truth(truth, N_FIT, seed, sigma, MARGINS[where])
    else:
        robot = pincal.load_robot("ur5")
        fit, new = _own_session(robot, where, truth, seed, sigma, measure)
    start = time.perf_counter()
    forced = pincal.Pull(force_fit=True)
    cal = pincal.calibrate(robot, fit, measure=measure, params="auto", test=new, pull=forced)
    seconds = time.perf_counter() - start
    assert cal.guard is not None and cal.test_after is not None and cal.test_before is not None
    beyond = cal.guard.extrapolation
    whole = None if beyond is None else beyond.whole_gain_mm2
    own = None if beyond is None else beyond.data_gain_mm2
    ratio = cal.test_after.rms_mm / cal.test_before.rms_mm
    sd = None if beyond is None else beyond.whole_gain_sd_mm2
    verdicts = (cal.guard.reliable, cal.guard.holds)
    return Session(where, truth, seed, *verdicts, ratio, whole, own, seconds, sd, measure, simulator)


def _own_session(
    robot: pincal.Robot, where: str, truth: str, seed: int, sigma: float, measure: str
) -> tuple[pincal.Dataset, pincal.Dataset]:
    """The fitted and the new poses of a session drawn by pincal's simulator."""
    true = pincal.random_truth(robot, seed, tool_distance=(0.05, 0.05))
    if truth == "exact":
        true = replace(true, x=np.zeros_like(true.x))
    rng = np.random.default_rng([seed, N_FIT, 1])
    q_fit = robot.random_configurations(N_FIT, rng, MARGINS[where])
    q_new = robot.random_configurations(N_NEW, rng, 0.0)
    turn = sigma if measure == "pose" else None
    fit, new = (true.measure(q, sigma, turn, seed=seed + k) for q, k in ((q_fit, 7), (q_new, 8)))
    return fit, new


def _rule(group: list[Session], rule: str) -> list[object]:
    kept = [s for s in group if getattr(s, rule)]
    worse = sum(s.ratio > WORSE for s in kept)
    worst = f"{max(s.ratio for s in kept):.2f}" if kept else "-"
    return [f"{len(kept)} ({len(kept) / len(group):.0%})", f"{worse} ({worse / len(group):.1%})", worst]


def summary(sessions: list[Session]) -> list[list[object]]:
    """One row per range and truth."""
    rows: list[list[object]] = []
    for where, truth in GROUPS:
        group = [s for s in sessions if (s.range, s.truth) == (where, truth)]
        if not group:
            continue
        refused = [s for s in group if s.before and not s.after]
        better = sum(s.ratio < 1.0 for s in refused)
        row: list[object] = [where, truth, len(group), *_rule(group, "before"), *_rule(group, "after")]
        rows.append([*row, len(refused), better, f"{np.median([s.seconds for s in group]):.2f}"])
    return rows


#: Thresholds tried: the expected gain across the limits above this many of its posterior
#: standard deviations (0: above zero).
SPREADS = (0.0, 0.5, 1.0, 2.0)


def spreads(sessions: list[Session]) -> list[list[object]]:
    """Per range and truth and per threshold ``whole gain > z x its standard deviation``: the fits
    the guard and that rule export, those of them more than 5 % worse, and those refused though
    better."""
    rows: list[list[object]] = []
    for where, truth in GROUPS:
        checked = [
            s for s in sessions if (s.range, s.truth) == (where, truth) and s.whole_gain_mm2 is not None
        ]
        for z in SPREADS if checked else ():
            kept = [s for s in checked if (s.whole_gain_mm2 or 0.0) > z * (s.whole_gain_sd_mm2 or 0.0)]
            refused = [s for s in checked if s not in kept]
            worse, better = sum(s.ratio > WORSE for s in kept), sum(s.ratio < 1.0 for s in refused)
            rows.append([where, truth, len(checked), z, len(kept), worse, better])
    return rows


SPREAD_HEADER = (
    "fitted poses",
    "truth",
    "passed the guard",
    "threshold: standard deviations of the expected gain",
    "exported",
    "> 5 % worse",
    "refused, better than nominal",
)


HEADER = (
    "fitted poses",
    "truth",
    "sessions",
    "exported, guard alone",
    "> 5 % worse",
    "worst ratio",
    "exported, guard + check",
    "> 5 % worse",
    "worst ratio",
    "refused by the check",
    "of them better than nominal",
    "median s per call",
)


def cost(runs: int, folder: Path) -> str:
    """The share of ``runs`` default ``pincal calibrate`` runs on 100 poses spent in the check."""
    import pincal.identify.guard as guard
    from pincal.cli import main as command

    spent: list[float] = []
    check = guard.check

    def timed(*args: Any) -> Any:
        start = time.perf_counter()
        try:
            return check(*args)
        finally:
            spent.append(time.perf_counter() - start)

    shares = []
    guard.check = timed  # type: ignore[assignment]
    try:
        for seed in range(runs):
            data = folder / f"poses{seed}.csv"
            pincal.write_csv(
                data, pincal.simulate(pincal.load_robot("ur5"), n_fit=100, n_test=1, seed=seed)[1]
            )
            spent.clear()
            start = time.perf_counter()
            with contextlib.redirect_stdout(io.StringIO()):
                code = command(
                    ["calibrate", "ur5", str(data), "--report", str(folder / f"report{seed}.json")]
                )
            assert code == 0, f"pincal calibrate failed on {data}"
            shares.append(sum(spent) / (time.perf_counter() - start))
    finally:
        guard.check = check
    return (
        f"The check's share of a default `pincal calibrate` on 100 simulated UR5 poses, {runs} runs: "
        f"median {np.median(shares):.1%}, largest {max(shares):.1%}."
    )


def main(argv: list[str] | None = None) -> int:
    """Run the sessions, print the table, write it (``--markdown``) and the sessions (``--json``)."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--sessions", type=int, default=100)
    parser.add_argument("--quick", action="store_true", help="20 sessions per row")
    parser.add_argument("--first-seed", type=int, default=0, help="seeds run: first-seed .. + sessions - 1")
    parser.add_argument("--sigma", type=float, default=0.05, help="noise per axis [mm]")
    parser.add_argument("--cost", type=int, default=5, help="runs of the cost measurement (0: none)")
    parser.add_argument("--measure", default="position", choices=("position", "pose", "distance"))
    parser.add_argument(
        "--simulator", default="own", choices=("own", "audit"), help="audit: verdict_audit.py's"
    )
    parser.add_argument("--json")
    parser.add_argument("--markdown")
    args = parser.parse_args(argv)
    if args.simulator == "audit" and args.measure == "pose":
        parser.error("--simulator audit simulates positions only: --measure position or distance")
    if args.simulator == "audit":
        simulators()  # made before the workers fork
    n = 20 if args.quick else args.sessions
    seeds = range(args.first_seed, args.first_seed + n)
    tasks = [(where, truth, seed) for where, truth in GROUPS for seed in seeds]

    def task(k: int) -> Session:
        return run(*tasks[k], args.sigma * 1e-3, args.measure, args.simulator)

    start = time.perf_counter()
    sessions = parallel_map(task, len(tasks))
    text = table(HEADER, summary(sessions))
    print(text)
    print(f"{len(sessions)} sessions in {time.perf_counter() - start:.0f} s")
    by_spread = table(SPREAD_HEADER, spreads(sessions))
    print(by_spread)
    sections = [text, "", by_spread]
    if args.cost:
        with tempfile.TemporaryDirectory() as folder:
            said = cost(args.cost, Path(folder))
        print(said)
        sections += ["", said]
    if args.json:
        Path(args.json).write_text(json.dumps([asdict(s) for s in sessions], indent=1))
    if args.markdown:
        given = sys.argv[1:] if argv is None else argv
        write_page(Path(args.markdown), command_line("extrapolation.py", given, {}), sections)
    return 0


if __name__ == "__main__":
    sys.exit(main())
