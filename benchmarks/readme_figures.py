"""Regenerate the figures the README, getting started, the diagnosis page and the Gao page quote.

Usage: python benchmarks/readme_figures.py [--out benchmarks/figures/diagnose_compliance.png]
    [--markdown docs/results/generated]

Writes, in the ``--markdown`` folder (each a page the documentation includes, and the source a
test checks every figure quoted elsewhere against, ``tests/test_docs.py``):

- ``demo.md``: what ``pincal demo`` prints, and how long it took;
- ``diagnose_compliance.md``: the worked diagnosis: a hidden joint compliance on a simulated UR5
  (also the plot ``--out``);
- ``gao_diagnose.md``: ``pincal diagnose`` on the real data of Gao et al. (2013).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from markdown_page import command_line, text_block, write_page  # noqa: E402

import pincal  # noqa: E402
from pincal.auto.diagnose import diagnose  # noqa: E402
from pincal.cli import main as pincal_main  # noqa: E402
from pincal.demo import gao2013_data  # noqa: E402
from pincal.demo import run as run_demo  # noqa: E402
from pincal.kinematics.effects import Extension  # noqa: E402
from pincal.report.plots import plot_diagnosis  # noqa: E402
from pincal.simulation.truth import hide_effect  # noqa: E402

#: ``pincal diagnose``'s options on Gao's data (the demo's: distance model, POE, 7 folds).
GAO_OPTIONS = ("--model", "poe", "--measure", "distance", "--folds", "7")


def compliance_case(out: Path) -> str:
    """Simulate a UR5 with a hidden shoulder compliance, diagnose it, write the plot; the printout."""
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
    effect = float(sag[0])  # [rad/(N·m)]
    return "\n".join(
        [
            result.summary(),
            f"hidden compliance {effect:.3g} rad/N·m (K = {-1 / effect:.3g} N·m/rad)",
            f"plot written to {plot_diagnosis(result, fit, out)}",
        ]
    )


def demo() -> tuple[str, float]:
    """What ``pincal demo`` prints, and its wall time [s]."""
    start = time.perf_counter()
    text = run_demo(seed=0)
    return text, time.perf_counter() - start


def gao_diagnose() -> str:
    """What ``pincal diagnose mrres5 gao.csv ...`` prints on Gao's bundled data."""
    data, _ = gao2013_data()
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "gao.csv"
        pincal.write_csv(path, data)
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            code = pincal_main(["diagnose", "mrres5", str(path), *GAO_OPTIONS])
    assert code == 0, code
    return out.getvalue().replace(str(path), "gao.csv")


def main() -> None:
    """Run the three cases; print them, and write their pages with ``--markdown``."""
    raw = argparse.RawDescriptionHelpFormatter
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=raw)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/figures/diagnose_compliance.png"))
    parser.add_argument("--markdown", type=Path, help="the folder to write demo.md, ... in")
    args = parser.parse_args()
    command = command_line("readme_figures.py", sys.argv[1:], {})
    case = compliance_case(args.out)
    print(case)
    shown, seconds = demo()
    print(shown)
    gao = gao_diagnose()
    print(gao)
    if args.markdown is None:
        return
    write_page(
        args.markdown / "demo.md",
        command,
        [f"`pincal demo` printed, in {seconds:.0f} s on this machine:", "", text_block(shown)],
    )
    write_page(
        args.markdown / "diagnose_compliance.md",
        command,
        [
            "The diagnosis of a UR5 simulated with a hidden compliance of the shoulder-lift joint printed:",
            "",
            text_block(case.replace(str(args.out), args.out.name)),
        ],
    )
    write_page(
        args.markdown / "gao_diagnose.md",
        command,
        [
            f"`pincal diagnose mrres5 gao.csv {' '.join(GAO_OPTIONS)}` (`gao.csv`: the 28 poses of Gao's "
            "Table 2 that `pincal demo` uses) printed:",
            "",
            text_block(gao),
        ],
    )


if __name__ == "__main__":
    main()
