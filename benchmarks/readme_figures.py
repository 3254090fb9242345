"""Regenerate the README's worked diagnosis: a hidden joint compliance on a simulated UR5.

Usage: python benchmarks/readme_figures.py [--out benchmarks/figures/diagnose_compliance.png]
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import pincal
from pincal.auto.diagnose import diagnose
from pincal.kinematics.effects import Extension
from pincal.report.plots import plot_diagnosis
from pincal.simulation.truth import hide_effect


def main() -> None:
    """Simulate, hide the effect, diagnose, write the plot and print the summary."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/figures/diagnose_compliance.png"))
    args = parser.parse_args()
    robot = pincal.load_robot("ur5")
    truth, fit, _ = pincal.simulate(robot, n_fit=80, n_test=1, seed=0)
    ext = Extension.parse(robot, "joint_compliance:shoulder_lift_joint")
    truth = hide_effect(truth, ext, fit.q, 0.5e-3, seed=0)
    # a real elastic joint sags under its load: link angle = motor angle - τ/K, c = -1/K < 0
    assert truth.effect is not None  # hide_effect sets it
    sag = -abs(truth.effect)
    truth = replace(truth, effect=sag)
    fit = truth.measure(fit.q, 3e-5, None, seed=10)
    result = diagnose(robot, fit)
    print(result.summary())
    effect = float(sag[0])  # [rad/(N·m)]
    print(f"hidden compliance {effect:.4g} rad/N·m (K = {-1 / effect:.4g} N·m/rad)")
    print(f"plot written to {plot_diagnosis(result, fit, args.out)}")


if __name__ == "__main__":
    main()
