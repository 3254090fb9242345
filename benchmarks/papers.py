"""Two published calibrations reproduced: Zhang et al.'s simulated protocol and Xiong et al. 2012's
tool frame, each beside the paper's own figures.

- **Zhang et al.** (the JAKA Zu3 protocol, simulated): every free MDH parameter of the bundled
  ``zu3`` off by a random sign times U(0.1, 0.5) mm (lengths) or U(0.5, 2) mrad (angles), base,
  instrument and tool exact; 50 fitted and 100 held-out poses of full-pose data with 0.02 mm /
  0.15 mrad noise; ``mdh`` (Hayati's β, redundant parameters removed by QR) on pose data. The
  held-out error before and after, mean / max / std, position [mm] and orientation [mrad], and
  the noise floor (the mean norm of the 3-D noise, σ·√(8/π)).
- **Xiong et al. 2012**: the paper's six flange poses (its Table 1), ``pincal tcp --orientation
  zx --units mm``: the TCP, its standard deviation, the fit error δ (eq. 10) and the tool axes
  n and a.

``tests/test_papers.py`` and ``tests/test_tool.py`` hold the same reproductions to the papers'
figures.

Usage::

    python benchmarks/papers.py [--markdown docs/results/generated/papers.md]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).parent))
from markdown_page import publish, table  # noqa: E402

import pincal  # noqa: E402
from pincal.simulation.papers import (  # noqa: E402
    XIONG_2012_POSES,
    XIONG_2012_ROTATION,
    XIONG_2012_TCP_MM,
    ZHANG_NOISE,
    ZHANG_POSITION_MM,
    ZHANG_ROTATION_MRAD,
    zhang_truth,
)
from pincal.tool.flange_poses import read_flange_poses  # noqa: E402
from pincal.tool.tcp import calibrate_tool  # noqa: E402


def zhang() -> str:
    """The Zhang et al. protocol on ``zu3``: the table beside the paper's (Markdown)."""
    robot = pincal.load_robot("zu3")
    truth = zhang_truth(robot, seed=0)
    noise, rot_noise = ZHANG_NOISE
    _, fit, test = pincal.simulate(robot, 50, 100, seed=0, noise=noise, rot_noise=rot_noise, truth=truth)
    cal = pincal.calibrate(
        robot, fit, "mdh", "pose", test=test, instrument_T_base=pin.SE3.Identity(), tool=pin.SE3.Identity()
    )
    before, after = cal.test_before, cal.test_after
    assert before is not None and after is not None

    def three(values: tuple[float | None, ...], digits: int) -> str:
        return " / ".join("-" if v is None else f"{v:.{digits}f}" for v in values)

    rows = [
        [
            "position [mm]",
            three((before.mean_mm, before.max_mm, before.std_mm), 3),
            three((after.mean_mm, after.max_mm, after.std_mm), 3),
            three(ZHANG_POSITION_MM["before"], 4),
            three(ZHANG_POSITION_MM["after"], 4),
        ],
        [
            "orientation [mrad]",
            three((before.rot_mean_mrad, before.rot_max_mrad, before.rot_std_mrad), 2),
            three((after.rot_mean_mrad, after.rot_max_mrad, after.rot_std_mrad), 2),
            three(ZHANG_ROTATION_MRAD["before"], 1),
            three(ZHANG_ROTATION_MRAD["after"], 1),
        ],
    ]
    header = ["held out, mean / max / std", "pincal before", "pincal after", "paper before", "paper after"]
    floor = np.sqrt(8 / np.pi)
    return (
        "**Zhang et al.**, JAKA Zu3, `mdh` on pose data, 50 fitted and 100 held-out poses:\n\n"
        + table(header, rows)
        + f"\n\nNoise floor (mean norm of the 3-D noise, σ·√(8/π)): {noise * floor * 1e3:.3f} mm and "
        f"{rot_noise * floor * 1e3:.2f} mrad."
    )


def xiong() -> str:
    """Xiong et al. 2012's worked example through ``pincal tcp``'s reading and fit (Markdown)."""
    with tempfile.TemporaryDirectory() as folder:
        csv = Path(folder) / "poses.csv"
        csv.write_text(
            "x,y,z,a,b,c\n" + "".join(",".join(str(v) for v in row) + "\n" for row in XIONG_2012_POSES)
        )
        rotations, positions = read_flange_poses(csv, "mm")
    tool = calibrate_tool(rotations, positions, "zx", scale=1000.0)

    def vec(values: object, digits: int) -> str:
        rounded = np.round(np.asarray(values, dtype=float), digits) + 0.0  # no "-0.000"
        return "(" + ", ".join(f"{v:.{digits}f}" for v in rounded).replace("-", "−") + ")"

    rows = [
        ["TCP [mm]", vec(tool.tcp, 2), vec(XIONG_2012_TCP_MM, 2)],
        ["TCP std σ [mm]", vec(tool.tcp_std, 2), ""],
        ["fit error δ (eq. 10) [mm]", f"{tool.fit_error:.2f}", ""],
        ["tool axis n", vec(tool.rotation[:, 0], 3), vec(XIONG_2012_ROTATION[:, 0], 3)],
        ["tool axis a", vec(tool.rotation[:, 2], 3), vec(XIONG_2012_ROTATION[:, 2], 3)],
    ]
    return (
        "**Xiong et al. 2012**, the paper's six flange poses, `pincal tcp --orientation zx --units mm`:\n\n"
        + table(["", "pincal", "paper"], rows)
    )


def main(argv: list[str] | None = None) -> None:
    """Print both reproductions (and write them as Markdown with ``--markdown``)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--markdown", type=Path, help="write the results page's figures here")
    args = parser.parse_args(argv)
    text = zhang() + "\n\n" + xiong()
    publish("papers.py", argv, text, (), None, args.markdown)


if __name__ == "__main__":
    main()
