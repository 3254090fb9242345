"""The corrected URDF reads as a reviewer needs: each origin's rpy the triple nearest the input's,
no digits below 1e-12, untouched origins as written, and each joint's change in mm and mrad
(printed and in the report), while the file reproduces the fit."""

from __future__ import annotations

import contextlib
import io
import json
import math
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import pincal
from pincal.cli import main
from pincal.export.origins import DECIMALS, nearest_rpy, origin_attributes
from pincal.robot.robots import bundled_urdf

FAST = ("--params", "all", "--nested", "no", "--extend", "none")


def _equivalents(rpy: np.ndarray) -> list[np.ndarray]:
    """Exact rpy triples of the same rotation: both branches, each angle within a turn or two."""
    r, p, y = rpy
    out = []
    for base in (np.array([r, p, y]), np.array([r + math.pi, math.pi - p, y + math.pi])):
        for k in np.ndindex(5, 5, 5):
            out.append(base + 2 * math.pi * (np.array(k) - 2))
    return out


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(pin.log3(a.T @ b)))


REFERENCES = [
    (0.0, 1.57079632679, 0.0),  # a UR origin, a hair below gimbal lock
    (0.0, math.pi / 2, 0.0),  # at it
    (0.3, -math.pi / 2, -1.2),
    (math.pi, 0.0, 0.0),
    (-3.14159, 0.0, 3.14159),
    (0.0, 0.0, 4.0),  # beyond a half turn, as written
    (3.5, 2.0, -0.5),  # the other branch, as written
    (1.5708, 0.0, -1.5708),
]


@pytest.mark.parametrize("reference", REFERENCES)
@pytest.mark.parametrize("size", [0.0, 1e-7, 3e-4, 2e-2])
def test_the_nearest_exact_triple_is_chosen(reference: tuple[float, float, float], size: float) -> None:
    ref = np.array(reference)
    rng = np.random.default_rng(int(size * 1e9) % 97)
    for _ in range(5):
        rotation = pin.rpy.rpyToMatrix(*ref) @ pin.exp3(rng.normal(0.0, 1.0, 3) * size)
        chosen = nearest_rpy(rotation, ref)
        assert _angle(pin.rpy.rpyToMatrix(*chosen), rotation) <= 1e-12
        raw = pin.rpy.matrixToRpy(rotation)
        others = [c for c in _equivalents(raw) if _angle(pin.rpy.rpyToMatrix(*c), rotation) <= 1e-12]
        assert np.linalg.norm(chosen - ref) <= min(np.linalg.norm(c - ref) for c in others) + 1e-9
        if size == 0.0:
            assert np.allclose(chosen, ref, atol=1e-9), (chosen, ref)  # the same rotation: as written


def test_an_unmoved_origin_keeps_its_text() -> None:
    placement = pin.SE3(pin.rpy.rpyToMatrix(0.0, 1.57079632679, 0.0), np.array([0.0, 0.13585, 0.0]))
    noisy = pin.SE3(
        placement.rotation @ pin.exp3(np.array([1e-15, -2e-15, 0.0])), placement.translation - 1e-16
    )
    assert origin_attributes(noisy, "0.0 0.13585 0.0", "0.0 1.57079632679 0.0") == (
        "0.0 0.13585 0.0",
        "0.0 1.57079632679 0.0",
    )


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, dict, str]:
    """A UR5 calibration written by the command: URDF, data, report, printed text."""
    folder = tmp_path_factory.mktemp("origins")
    ur5 = pincal.load_robot("ur5")
    q = ur5.random_configurations(30, np.random.default_rng(2), 0.05)
    data = folder / "pos.csv"
    pincal.write_csv(data, pincal.random_truth(ur5, seed=2).measure(q, 3e-5, seed=3))
    printed = io.StringIO()
    out, report = folder / "c.urdf", folder / "r.json"
    with contextlib.redirect_stdout(printed):
        code = main(["calibrate", "ur5", str(data), *FAST, "-o", str(out), "--report", str(report)])
    assert code == 0
    return folder / "c.urdf", data, json.loads((folder / "r.json").read_text()), printed.getvalue()


def _origins(text: str) -> dict[str, tuple[str, str]]:
    found = re.findall(r'<joint name="([^"]+)"[^>]*>.*?<origin rpy="([^"]*)" xyz="([^"]*)"', text, re.S)
    return {name: (rpy, xyz) for name, rpy, xyz in found}


def test_written_origins_have_no_digits_below_the_fit(calibrated: tuple[Path, Path, dict, str]) -> None:
    urdf, _, _, _ = calibrated
    before = _origins(bundled_urdf("ur5").read_text())
    after = _origins(urdf.read_text())
    for name, (rpy, xyz) in after.items():
        for token in f"{rpy} {xyz}".split():
            assert round(float(token), DECIMALS) == float(token), (name, token)
            assert "e-1" not in token or abs(float(token)) >= 10.0**-DECIMALS, (name, token)
        rpy_in = np.array([float(v) for v in before[name][0].split()])
        rpy_out = np.array([float(v) for v in rpy.split()])
        raw = pin.rpy.matrixToRpy(pin.rpy.rpyToMatrix(*rpy_out))
        best = min(np.linalg.norm(c - rpy_in) for c in _equivalents(raw))
        assert np.linalg.norm(rpy_out - rpy_in) <= best + 1e-9, name
    unchanged = [n for n in before if n not in pincal.load_robot("ur5").joint_names]
    for name in unchanged:  # fixed joints: as written
        assert after[name] == before[name], name


def test_the_file_reproduces_the_fit(calibrated: tuple[Path, Path, dict, str]) -> None:
    """Rounded, the URDF still gives the report's figure (the URDF alone with the sidecar's
    registration and tool) to 1e-6 mm."""
    urdf, data, report, _ = calibrated
    side = json.loads(urdf.with_name("c.calibration.json").read_text())
    robot = pincal.load_robot(urdf, tip="tool0")
    poses = pincal.read_csv(data, robot.joint_names)
    reg = np.array(side["instrument_T_base"]["matrix"])
    tool = np.array(side["tip_T_tool"]["matrix"])
    errors = []
    for q, point in zip(poses.q, poses.points):
        tip = robot.frame_placement(q).homogeneous @ tool
        errors.append(np.linalg.norm((reg @ tip)[:3, 3] - point))
    rms = float(np.sqrt(np.mean(np.square(errors)))) * 1e3
    assert rms == pytest.approx(report["train"]["exported"]["rms_mm"], abs=1e-6)


def test_each_joint_change_is_printed_and_reported(calibrated: tuple[Path, Path, dict, str]) -> None:
    urdf, _, report, printed = calibrated
    before = pincal.load_robot("ur5")
    after = pincal.load_robot(urdf, tip="tool0")
    changes = {c["joint"]: c for c in report["joint_changes"]}
    assert set(changes) == set(before.joint_names)
    for k, name in enumerate(before.joint_names):
        moved = after.placements[k].translation - before.placements[k].translation
        turned = pin.log3(before.placements[k].rotation.T @ after.placements[k].rotation)
        assert changes[name]["translation_mm"] == pytest.approx(np.linalg.norm(moved) * 1e3, abs=1e-6)
        assert changes[name]["rotation_mrad"] == pytest.approx(np.linalg.norm(turned) * 1e3, abs=1e-6)
        line = next(line for line in printed.splitlines() if line.strip().startswith(f"{name}:"))
        assert f"{changes[name]['translation_mm']:.4f} mm" in line and "mrad" in line
