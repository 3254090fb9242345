"""The documentation says what every key means: each key of the JSON files the commands write
(report, sidecar, diagnosis, TCP) is named on the pages that describe them."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from cli_run import run

import pincal
from pincal.kinematics.effects import Extension
from pincal.simulation.truth import hide_effect

DOCS = Path(__file__).resolve().parents[1] / "docs"
#: Objects whose keys are names from the data (parameters, joints), not keys to document.
NAMED_KEYS = ("held", "parameters")


def keys(obj: Any) -> set[str]:
    """Every key of a JSON value, but the names inside :data:`NAMED_KEYS` objects."""
    found: set[str] = set()
    if isinstance(obj, dict):
        for key, value in obj.items():
            found.add(key)
            if not (key in NAMED_KEYS and isinstance(value, dict)):
                found |= keys(value)
    elif isinstance(obj, list):
        for value in obj:
            found |= keys(value)
    return found


def undocumented(path: Path, *pages: str) -> list[str]:
    """The keys of the JSON file ``path`` that no page of ``pages`` names (as `key` or "key")."""
    text = "".join((DOCS / page).read_text(encoding="utf-8") for page in pages)
    written = keys(json.loads(path.read_text(encoding="utf-8")))
    return sorted(k for k in written if not re.search(rf"[`\"]{re.escape(k)}[`\"]", text))


@pytest.fixture(scope="module")
def ur5_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """60 simulated UR5 poses with a hidden shoulder compliance (0.5 mm at the tip; position data, metres)."""
    robot = pincal.load_robot("ur5")
    truth, fit, _ = pincal.simulate(robot, n_fit=60, n_test=1, seed=2)
    ext = Extension.parse(robot, "joint_compliance:shoulder_lift_joint")
    data = hide_effect(truth, ext, fit.q, 0.5e-3, seed=2).measure(fit.q, noise=3e-5, rot_noise=None, seed=3)
    path = tmp_path_factory.mktemp("docs") / "ur5.csv"
    pincal.write_csv(path, data)
    return path


@pytest.mark.parametrize(
    "options",
    [
        ["--holdout", "0.3"],
        ["--extend", "joint_compliance:shoulder_lift_joint", "--holdout", "0.3"],
        ["--model", "poe", "--measure", "distance", "--extend", "none"],
    ],
    ids=["position", "compliance", "poe-distance"],
)
def test_every_key_of_the_report_and_sidecar_is_documented(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, ur5_csv: Path, options: list[str]
) -> None:
    report, urdf = tmp_path / "report.json", tmp_path / "ur5_calibrated.urdf"
    code, _, err = run(capsys, "calibrate", "ur5", ur5_csv, *options, "--report", report, "-o", urdf)
    assert code == 0, err
    assert undocumented(report, "report.md") == []
    assert undocumented(tmp_path / "ur5_calibrated.calibration.json", "formats.md") == []


def test_every_key_of_the_diagnosis_is_documented(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, ur5_csv: Path
) -> None:
    report = tmp_path / "diagnosis.json"
    code, _, err = run(capsys, "diagnose", "ur5", ur5_csv, "--report", report)
    assert code == 0, err
    assert json.loads(report.read_text(encoding="utf-8"))["cause"]["effect"] == "joint_compliance"
    assert undocumented(report, "report.md") == []


def test_every_key_of_the_tcp_report_is_documented(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    rng = np.random.default_rng(0)
    tcp, point = np.array([0.1, 0.0, 0.2]), np.array([0.5, 0.1, 0.3])
    rows = ["x,y,z,qw,qx,qy,qz"]
    for _ in range(8):
        rot = pin.exp3(rng.normal(0.0, 0.6, 3))
        quat = pin.Quaternion(rot)
        rows.append(",".join(repr(float(v)) for v in [*(point - rot @ tcp), quat.w, quat.x, quat.y, quat.z]))
    poses, report = tmp_path / "poses.csv", tmp_path / "tcp.json"
    poses.write_text("\n".join(rows) + "\n", encoding="utf-8")
    code, _, err = run(capsys, "tcp", poses, "--report", report)
    assert code == 0, err
    assert undocumented(report, "report.md") == []
