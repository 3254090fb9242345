"""What the user loads, scored on every real dataset: the URDF alone and the URDF with its sidecar.

For each dataset the default call (:func:`pincal.calibrate` as ``pincal calibrate`` makes it:
``params="auto"``, ``extension="auto"``, except fixed points) is fitted on the training part and
its files are written, then judged on held-out poses four ways:

- ``after``: the report's figure, the model with its sidecar (URDF + effect);
- ``reloaded``: URDF + sidecar loaded back (:func:`pincal.load_calibration`), as
  ``pincal compensate`` and the API apply it; the difference to ``after`` must be below 1e-6 mm;
- ``exported``: the report's URDF-alone figure (``test.exported``);
- ``plain``: the URDF alone scored by plain Pinocchio (``buildModelFromUrdf``, the tip frame,
  the sidecar's tool and registration, nothing of pincal), which ``exported`` must equal within 1 %;
- ``none``: the ``extension=None`` fit's held-out figure, which the URDF alone must not exceed
  (within the cross-validation's noise).

Held-out parts: TIAGo's other day; a fixed 30 % of the poses (seed 0) for the others.

Usage::

    python benchmarks/deliverables.py DATASETS_DIR [--markdown docs/results/generated/deliverables.md]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).parent))
from markdown_page import command_line, table, write_page  # noqa: E402
from real_data import load_panda, load_tiago_data, load_ur10  # noqa: E402

import pincal  # noqa: E402
from pincal.data.dataset import Dataset  # noqa: E402
from pincal.export.urdf_writer import write_corrected_urdf  # noqa: E402
from pincal.report.outcome import outcome  # noqa: E402


def plain_rms_mm(urdf: Path, sidecar: dict[str, Any], test: Dataset) -> float:
    """RMS position error [mm] of the URDF alone, with Pinocchio only (see the module docstring)."""
    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    frame = model.getFrameId(sidecar["tip"])
    tool = np.array(sidecar["tip_T_tool"]["matrix"])
    reg = np.array(sidecar["instrument_T_base"]["matrix"])
    errors = []
    for q, measured in zip(test.q, test.points):
        config = pin.neutral(model)
        for name, value in zip(sidecar["joints"], q):
            joint = model.joints[model.getJointId(name)]
            if joint.nq == 2:  # a continuous joint: (cos, sin)
                config[joint.idx_q : joint.idx_q + 2] = (np.cos(value), np.sin(value))
            else:
                config[joint.idx_q] = value
        pin.framesForwardKinematics(model, data, config)
        errors.append(np.linalg.norm((reg @ data.oMf[frame].homogeneous @ tool)[:3, 3] - measured))
    return float(np.sqrt(np.mean(np.square(errors)))) * 1e3


def reloaded_rms_mm(urdf: Path, test: Dataset) -> float:
    """RMS position error [mm] of URDF + sidecar loaded back."""
    loaded = pincal.load_calibration(urdf)
    reg = loaded.instrument_T_base or pin.SE3.Identity()
    points = np.array([(reg * pose).translation for pose in loaded.tool_poses(test.q)])
    return float(np.sqrt(np.mean(np.sum((points - test.points) ** 2, axis=1)))) * 1e3


#: The table's columns: held-out RMS [mm] of each, then the checks.
HEADER = ("dataset", "cause kept", "after", "reloaded", "exported", "plain", "none", "residual", "checks")


def judge(name: str, robot: pincal.Robot, train: Dataset, test: Dataset, folder: Path) -> list[str]:
    """One dataset's row (:data:`HEADER`)."""
    import json

    cal = pincal.calibrate(robot, train, test=test, params="auto", extension="auto")
    none = pincal.calibrate(robot, train, test=test, params="auto", extension=None)
    found = outcome(cal, train, test)
    urdf, side = write_corrected_urdf(cal, folder / f"{name}.urdf")
    sidecar = json.loads(side.read_text())
    assert cal.test_after is not None and found.exported.test is not None and none.test_after is not None
    after, exported = cal.test_after.rms_mm, found.exported.test.rms_mm
    reloaded, plain = reloaded_rms_mm(urdf, test), plain_rms_mm(urdf, sidecar, test)
    cause = cal.extension.label if cal.extension else "none"
    checks = (
        f"reload {'ok' if abs(reloaded - after) < 1e-6 else 'FAIL'}",
        f"exported=plain {'ok' if abs(exported - plain) <= 0.01 * plain else 'FAIL'}",
        f"alone/none {exported / none.test_after.rms_mm:.3f}",
    )
    figures = [f"{v:.3f}" for v in (after, reloaded, exported, plain, none.test_after.rms_mm)]
    return [name, cause, *figures, found.residual.verdict, ", ".join(checks)]


def line(row: list[str]) -> str:
    """A row as the script prints it."""
    name, cause, after, reloaded, exported, plain, none, verdict, checks = row
    return (
        f"{name:18s} {cause:34s} {after:>8s} {reloaded:>9s} {exported:>9s} {plain:>8s} "
        f"{none:>8s}  {verdict:12s} {checks}"
    )


def main(argv: list[str] | None = None) -> None:
    """Print the table (and write it as Markdown with ``--markdown``)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("datasets", type=Path, metavar="DATASETS_DIR", help="the folder ../shared/datasets")
    parser.add_argument("--markdown", type=Path, help="write the results page's figures here")
    args = parser.parse_args(argv)
    legend = (
        "held-out RMS [mm]: after = URDF + sidecar (report), reloaded = the same loaded back, "
        "exported = URDF alone (report), plain = URDF alone by plain Pinocchio, none = extension=None fit; "
        "checks: reload = reloaded within 1e-6 mm of after, exported=plain within 1 %, "
        "alone/none = exported over none"
    )
    print(legend)
    print(line(list(HEADER)))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        robot, train, val = load_tiago_data(args.datasets / "tiago_qualisys")
        rows.append(judge("tiago_qualisys", robot, train, val, folder))
        print(line(rows[-1]))
        for name, loader in (("ur10_camera", load_ur10), ("panda_eye_in_hand", load_panda)):
            robot, data = loader(args.datasets / name)
            data = Dataset(data.joint_names, data.q, data.points)  # positions: the figures are distances
            fit, held = data.split(0.3, 0)
            rows.append(judge(name, robot, fit, held, folder))
            print(line(rows[-1]))
        robot, data = pincal.load_robot("mrres5"), pincal.gao2013_data()[0]
        fit, held = data.split(0.3, 0)
        rows.append(judge("gao2013", robot, fit, held, folder))
        print(line(rows[-1]))
    if args.markdown is not None:
        names = {str(args.datasets).rstrip("/"): "DATASETS_DIR"}
        command = command_line("deliverables.py", sys.argv[1:] if argv is None else argv, names)
        write_page(args.markdown, command, [table(HEADER, rows), "", legend])


if __name__ == "__main__":
    main()
