"""The residual verdict's false "unexplained" rate with an estimated noise, on two simulators.

Sessions: UR5, tracker positions, a geometry off by 0.5 mm / 0.5 mrad per axis on every joint
origin, an unknown instrument registration and reflector, Gaussian noise ``--sigma`` mm per axis,
``--poses`` random poses, of which the first three are measured twice more (``--repeats 6``: 18
degrees of freedom for the noise) or the first two once more each (``--repeats 2``: 6, too few for a
noise figure). The model is right (nothing but geometry), so ``unexplained`` is a false verdict.
No noise figure is given: the verdict estimates it from the repeated poses, with its uncertainty.

Each session runs :func:`pincal.calibrate` with the command's defaults (``params="auto"``,
``extension="auto"``) and :func:`pincal.auto.residual.residual_verdict` on what it delivers.

Usage::

    python benchmarks/verdict_rates.py [--sessions 100] [--poses 25 40] [--repeats 6 2]
        [--sigma 0.05] [--jobs 2] [--json FILE] [--markdown FILE]
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from guard_rates import Simulators
from markdown_page import publish, table

import pincal
from pincal.auto.residual import residual_verdict
from pincal.data.dataset import Dataset
from pincal.workers import parallel_map

#: The rows measured again, by ``--repeats``.
EXTRA = {6: (0, 0, 1, 1, 2, 2), 2: (0, 1)}


@dataclass(frozen=True)
class Session:
    """One calibration's verdict."""

    simulator: str
    n_poses: int
    repeats: int
    seed: int
    verdict: str
    noise_source: str


def run(sims: Simulators, key: tuple[str, int, int, int], sigma: float) -> Session:
    """One session (``sigma`` in metres)."""
    simulator, n, repeats, seed = key
    make = sims.own if simulator == "own" else sims.audit_truth
    clean, _ = make("perturbed", n, seed, 0.0)
    noisy = Dataset(
        clean.joint_names,
        clean.q,
        clean.points + np.random.default_rng([seed, 4]).normal(0, sigma, clean.points.shape),
    )
    extra = EXTRA[repeats]
    again = clean.points[list(extra)] + np.random.default_rng([seed, 5]).normal(0, sigma, (len(extra), 3))
    data = Dataset(noisy.joint_names, np.r_[noisy.q, noisy.q[list(extra)]], np.r_[noisy.points, again])
    cal = pincal.calibrate(sims.robot, data, params="auto", extension="auto")
    verdict = residual_verdict(cal, data)
    return Session(simulator, n, repeats, seed, verdict.verdict, verdict.noise_source)


def summary(sessions: list[Session]) -> list[list[object]]:
    """One row per simulator, pose count and repeats: the share of each verdict."""
    rows: list[list[object]] = []
    for key in sorted({(s.simulator, s.n_poses, s.repeats) for s in sessions}):
        group = [s for s in sessions if (s.simulator, s.n_poses, s.repeats) == key]
        counts = {v: sum(s.verdict == v for s in group) for v in ("explained", "unexplained", "undetermined")}
        sources = sorted({s.noise_source for s in group})
        row: list[object] = [*key, len(group)]
        row += [f"{c} ({c / len(group):.0%})" for c in counts.values()]
        rows.append([*row, ", ".join(sources)])
    return rows


HEADER = (
    "simulator",
    "poses",
    "repeated rows",
    "sessions",
    "explained",
    "unexplained (false)",
    "undetermined",
    "noise from",
)


def main(argv: list[str] | None = None) -> int:
    """Run the sessions, print the table, write it (``--markdown``) and the sessions (``--json``)."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--sessions", type=int, default=100)
    parser.add_argument("--poses", type=int, nargs="+", default=[25, 40])
    parser.add_argument("--repeats", type=int, nargs="+", choices=sorted(EXTRA), default=[6, 2])
    parser.add_argument("--sigma", type=float, default=0.05, help="noise per axis [mm]")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--json", type=Path)
    parser.add_argument("--markdown", type=Path)
    args = parser.parse_args(argv)
    sims = Simulators()
    keys = [
        (sim, n, r, seed)
        for sim in ("own", "audit")
        for n in args.poses
        for r in args.repeats
        for seed in range(args.sessions)
    ]
    sessions = parallel_map(lambda k: run(sims, keys[k], args.sigma * 1e-3), len(keys), args.jobs)
    publish("verdict_rates.py", argv, table(HEADER, summary(sessions)), sessions, args.json, args.markdown)
    return 0


if __name__ == "__main__":
    sys.exit(main())
