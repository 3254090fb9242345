"""The diagnosis' error rates: false causes on a rigid robot, and causes found, before and after the
null of the whole screen, in the same run, on two simulators.

Sessions: UR5, tracker positions, Gaussian noise ``--sigma`` mm per axis, an unknown instrument
registration and reflector, a geometry off by 0.5 mm / 0.5 mrad per axis on every joint origin,
random commands, ``--poses`` poses. Truths:

* ``rigid``: nothing else: any named cause is a false cause (both simulators: pincal's own and the
  Pinocchio-only one of ``benchmarks/verdict_audit.py``);
* ``harmonic``: a gear harmonic of order 1 hidden on the elbow at ``--effect`` mm RMS at the tool
  (pincal's simulator): the right answer is ``gear_harmonic:elbow_joint``.

Each session runs :func:`pincal.auto.diagnose.diagnose` once. ``after`` is its answer (a gain of
1.1 and a family-wise p-value under 0.01 from the null of the screen, :mod:`pincal.auto.screen_null`).
``before`` is the rule it replaced, recomputed here on the same fits: a gain of 1.1 and an F-test of
the finalist's fit against the baseline at p < 0.01 / (number of candidates).

Usage::

    python benchmarks/diagnosis_rates.py [--sessions 100] [--poses 30 80] [--sigma 0.05]
        [--effect 0.1] [--jobs 2] [--json FILE] [--markdown FILE]
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from guard_rates import Simulators
from markdown_page import publish, table

from pincal.auto.diagnose import diagnose
from pincal.auto.diagnosis import MIN_GAIN, Diagnosis
from pincal.data.dataset import Dataset
from pincal.identify.calibration import Calibration
from pincal.kinematics.effects import Extension
from pincal.simulation.truth import hide_effect, random_truth
from pincal.workers import parallel_map

HIDDEN = "gear_harmonic:elbow_joint"
F_ALPHA = 0.01  # the replaced rule's family-wise level


@dataclass(frozen=True)
class Session:
    """One diagnosis: what each rule names (``none`` for nothing)."""

    simulator: str
    truth: str
    n_poses: int
    seed: int
    before: str
    after: str
    p_value: float  # family-wise p of the best finalist (after)
    seconds: float


def _rss(cal: Calibration, data: Dataset) -> tuple[float, int]:
    """Residual sum of squares and its number of equations (position data)."""
    res = cal.problem(data).residuals(cal.theta)
    return float(res @ res), len(res)


def f_rule(d: Diagnosis, data: Dataset) -> str:
    """The replaced rule on the same fits: the best finalist with a gain of 1.1 and an F-test
    p < 0.01 / (number of candidates), plausible."""
    from scipy.special import fdtrc

    rss0, n_eq = _rss(d.baseline, data)
    for c in d.candidates:
        if c.calibration is None or d.baseline_cv_rms_mm / c.cv_rms_mm < MIN_GAIN:
            continue
        rss1, _ = _rss(c.calibration, data)
        extra = c.calibration.identifiability.n_identifiable - d.baseline.identifiability.n_identifiable
        dof = n_eq - c.calibration.identifiability.n_identifiable
        p = (
            float(fdtrc(extra, dof, ((rss0 - rss1) / extra) / (rss1 / dof)))
            if extra > 0 and rss1 > 0
            else 1.0
        )
        if p < F_ALPHA / len(d.candidates) and c.implausible is None:
            return c.extension.label
    return "none"


def measured(
    sims: Simulators, simulator: str, truth: str, n: int, seed: int, args: argparse.Namespace
) -> Dataset:
    """The session's data (``sigma``, ``effect`` in mm)."""
    sigma = args.sigma * 1e-3
    if simulator == "audit":
        return sims.audit_truth("perturbed", n, seed, sigma)[0]
    true = random_truth(sims.robot, seed, tool_distance=(0.05, 0.05))
    q = sims.robot.random_configurations(n, np.random.default_rng([seed, n, 1]), 0.05)
    if truth == "harmonic":
        true = hide_effect(true, Extension.parse(sims.robot, HIDDEN), q, args.effect * 1e-3, seed=seed)
    return true.measure(q, sigma, seed=seed + 7)


def run(sims: Simulators, key: tuple[str, str, int, int], args: argparse.Namespace) -> Session:
    """One session."""
    simulator, truth, n, seed = key
    data = measured(sims, simulator, truth, n, seed, args)
    start = time.perf_counter()
    d = diagnose(sims.robot, data)
    seconds = time.perf_counter() - start
    after = d.cause.extension.label if d.cause else "none"
    finalist = next((c for c in d.candidates if not c.screened), None)
    p = finalist.p_value if finalist is not None else 1.0
    return Session(simulator, truth, n, seed, f_rule(d, data), after, p, seconds)


def summary(sessions: list[Session]) -> list[list[object]]:
    """One row per simulator, truth and pose count: the share of sessions each rule names a cause
    (false causes on a rigid truth; the hidden one found, and a wrong one named, on the harmonic)."""
    rows: list[list[object]] = []
    for key in sorted({(s.simulator, s.truth, s.n_poses) for s in sessions}):
        group = [s for s in sessions if (s.simulator, s.truth, s.n_poses) == key]
        row: list[object] = [*key, len(group)]
        for rule in ("before", "after"):
            named = [getattr(s, rule) for s in group]
            if key[1] == "rigid":
                row += [_share(sum(c != "none" for c in named), len(group)), "-"]
            else:
                right = sum(c == HIDDEN for c in named)
                row += [
                    _share(sum(c not in ("none", HIDDEN) for c in named), len(group)),
                    _share(right, len(group)),
                ]
        row.append(f"{np.median([s.seconds for s in group]):.2f}")
        rows.append(row)
    return rows


def _share(k: int, n: int) -> str:
    return f"{k} ({k / n:.0%})"


HEADER = (
    "simulator",
    "truth",
    "poses",
    "sessions",
    "false cause, F-test",
    "hidden found, F-test",
    "false cause, null",
    "hidden found, null",
    "median diagnosis [s]",
)


def main(argv: list[str] | None = None) -> int:
    """Run the sessions, print the table, write it (``--markdown``) and the sessions (``--json``)."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--sessions", type=int, default=100)
    parser.add_argument("--poses", type=int, nargs="+", default=[30, 80])
    parser.add_argument("--sigma", type=float, default=0.05, help="noise per axis [mm]")
    parser.add_argument(
        "--effect", type=float, default=0.1, help="the hidden harmonic's RMS at the tool [mm]"
    )
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--json", type=Path)
    parser.add_argument("--markdown", type=Path)
    args = parser.parse_args(argv)
    sims = Simulators()
    cases = [("own", "rigid"), ("audit", "rigid"), ("own", "harmonic")]
    keys = [
        (sim, truth, n, seed) for sim, truth in cases for n in args.poses for seed in range(args.sessions)
    ]

    def done(k: int) -> None:
        if (k + 1) % 20 == 0:
            print(f"{k + 1} of {len(keys)} sessions", flush=True)

    sessions = parallel_map(lambda k: run(sims, keys[k], args), len(keys), args.jobs, done)
    publish("diagnosis_rates.py", argv, table(HEADER, summary(sessions)), sessions, args.json, args.markdown)
    return 0


if __name__ == "__main__":
    sys.exit(main())
