"""Reported standard deviations against the spread of the estimates over noise draws, per
measurement kind, the pull off (a weight of 1e-9 per natural unit).

One UR5 truth (random joint-origin errors, instrument and tool), fixed poses, ``--draws`` draws
of the noise (0.05 mm per axis; 0.2 mrad per axis on orientations for pose data), on pincal's
simulator and on the Pinocchio-only one of ``verdict_audit.py`` (positions and the distances
between them; its points have no orientation). Each draw is
fitted on the identifiable placement parameters; the reported standard deviation of each
parameter (RMS over the draws) is divided by the spread of its estimates. A ratio of 1 is an
honest figure; the target is within 20 % (0.8 to 1.25) for the median and for every
parameter.

Usage::

    python benchmarks/std_spread.py [--draws 100] [--markdown FILE]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
from guard_rates import Simulators
from markdown_page import command_line, table, write_page
from verdict_audit import Truth

import pincal
from pincal.identify.solver import identifiable_set, register, set_up, solve
from pincal.identify.uncertainty import posterior_std

#: Simulators, kinds and their pose counts (the audit's simulator measures positions only).
CASES = (
    ("own", "position", 25),
    ("own", "pose", 20),
    ("own", "distance", 20),
    ("audit", "position", 25),
    ("audit", "distance", 20),
)
#: Noise per axis [m].
NOISE = 5e-5


Draws = Callable[[int], pincal.Dataset]


def own_draws(robot: pincal.Robot, measure: str, n: int) -> Draws:
    """Noise draw ``seed`` of ``n`` fixed poses of one truth of pincal's simulator."""
    rot = 2e-4 if measure == "pose" else None
    truth, _, _ = pincal.simulate(robot, n_fit=n, n_test=1, seed=2, rot_noise=rot)
    q = robot.random_configurations(n, np.random.default_rng(5), 0.05)
    return lambda seed: truth.measure(q, NOISE, rot, seed=seed)


def audit_draws(measure: str, n: int) -> Draws:
    """The same of one truth of ``verdict_audit.py``'s simulator (Pinocchio only; positions)."""
    if measure == "pose":
        raise ValueError("the audit simulator measures positions only")
    sims = Simulators()
    rng = np.random.default_rng(2)
    truth = Truth.draw(sims.audit, rng)
    q = sims.audit.sample(rng, n)
    return lambda seed: sims.measured(truth, q, NOISE, np.random.default_rng(seed))


def ratios(measure: str, n: int, draws: int, first_seed: int = 1000, simulator: str = "own") -> np.ndarray:
    """Per identifiable placement parameter: reported std (RMS over the draws) / spread of the
    estimates over the draws (noise seeds ``first_seed`` onwards; ``tests/test_std_spread.py``
    checks the same on fewer draws), on pincal's simulator (``own``) or the audit's (``audit``)."""
    robot = pincal.load_robot("ur5")
    measured = own_draws(robot, measure, n) if simulator == "own" else audit_draws(measure, n)
    estimates, stds, free = [], [], None
    for draw in range(draws):
        data = measured(first_seed + draw)
        setup = replace(set_up(robot, data, "placements", measure), prior_weight=1e-9)
        nominal = register(setup)
        if free is None:
            free = identifiable_set(setup, nominal).identifiable
        theta, _ = solve(setup, nominal, free)
        estimates.append(theta)
        stds.append(posterior_std(setup.problem, setup.scale, setup.prior_weight, theta, free))
    assert free is not None
    model = np.flatnonzero(free[: robot.n_joints * 6])
    spread = np.std(np.array(estimates)[:, model], axis=0, ddof=1)
    return np.sqrt(np.mean(np.array(stds)[:, model] ** 2, axis=0)) / spread


def main(argv: list[str] | None = None) -> int:
    """Print the table; write it with ``--markdown``."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--draws", type=int, default=100)
    parser.add_argument("--markdown", type=Path)
    args = parser.parse_args(argv)
    rows: list[list[object]] = []
    for simulator, measure, n in CASES:
        found = ratios(measure, n, args.draws, simulator=simulator)
        within = "yes" if 0.8 <= np.median(found) <= 1.25 else "NO"
        every = "yes" if np.all((found >= 0.8) & (found <= 1.25)) else "NO"
        rows.append(
            [
                simulator,
                measure,
                n,
                args.draws,
                len(found),
                f"{np.median(found):.2f}",
                f"{found.min():.2f}",
                f"{found.max():.2f}",
                within,
                every,
            ]
        )
    header = (
        "simulator",
        "measure",
        "poses",
        "draws",
        "parameters",
        "median ratio",
        "smallest",
        "largest",
        "median within 20 %",
        "every one within 20 %",
    )
    text = table(header, rows)
    print(text)
    if args.markdown:
        given = sys.argv[1:] if argv is None else argv
        write_page(args.markdown, command_line("std_spread.py", given, {}), [text])
    return 0


if __name__ == "__main__":
    sys.exit(main())
