"""Xacro input: the project's small xacro (``tests/data/xacro``: an argument and a ``$(find ...)``
include of a macro from another package) loads through the Python API and every command that
takes a robot, calibrates end to end from a CSV, and a package that cannot be found, an unknown
argument or a broken xacro is one ``pincal: error:`` line naming what to fix.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from cli_run import one_error_line, run

import pincal
from pincal.robot.descriptions import PackageNotFoundError, find_package

DATA = Path(__file__).resolve().parent / "data" / "xacro"
XACRO = DATA / "arm.urdf.xacro"
PARTS = DATA / "pincal_test_parts"
PACKAGE = f"pincal_test_parts={PARTS}"
UPPER = 0.32  # [m] the upper arm's length given as --xacro-arg (the xacro's default is 0.30)


@pytest.fixture(autouse=True)
def _no_ros_paths(monkeypatch: pytest.MonkeyPatch) -> None:
    """No ROS search path unless a test sets one."""
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)
    monkeypatch.delenv("AMENT_PREFIX_PATH", raising=False)


def _robot(**args: str) -> pincal.Robot:
    return pincal.load_robot(XACRO, xacro_args=args, package_paths={"pincal_test_parts": PARTS})


def test_the_argument_and_the_included_macro_make_the_chain() -> None:
    """The default and a given upper-arm length land in joint_3's origin; the macro's joints are
    the chain; the processed URDF is what the robot keeps."""
    default, given = _robot(), _robot(upper_length=str(UPPER))
    assert default.joint_names == tuple(f"joint_{k}" for k in range(1, 7)) and default.tip == "tool0"
    assert default.placements[2].translation[0] == pytest.approx(0.30, abs=1e-12)
    assert given.placements[2].translation[0] == pytest.approx(UPPER, abs=1e-12)
    for a, b in zip(default.placements[3:], given.placements[3:]):
        assert np.allclose(a.homogeneous, b.homogeneous, atol=1e-12)
    assert "<xacro:" not in given.urdf_text and 'name="joint_6"' in given.urdf_text


def test_ros_package_path_finds_the_package(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """Without --package-path, a folder on ROS_PACKAGE_PATH (the package below it, or a package
    whose package.xml names it) answers $(find)."""
    monkeypatch.setenv("ROS_PACKAGE_PATH", os.pathsep.join([str(tmp_path), str(DATA.parent)]))
    robot = pincal.load_robot(XACRO)
    assert robot.placements[2].translation[0] == pytest.approx(0.30, abs=1e-12)
    assert find_package("pincal_test_parts") == PARTS
    with pytest.raises(PackageNotFoundError, match="'no_such_package'"):
        find_package("no_such_package")


def test_calibrates_end_to_end(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """Simulated tracker data of the xacro's arm, written as a CSV: `calibrate ARM.xacro` with the
    argument and the package fits it (held-out error 10x down), writes a URDF that loads as is,
    and that URDF with its sidecar predicts held-out measurements to the noise."""
    robot = _robot(upper_length=str(UPPER))
    truth, fit, test = pincal.simulate(robot, 60, 30, seed=3)
    pincal.write_csv(tmp_path / "fit.csv", fit, units="mm")
    pincal.write_csv(tmp_path / "test.csv", test, units="mm")
    out, report = tmp_path / "arm_calibrated.urdf", tmp_path / "report.json"
    code, text, err = run(
        capsys, "calibrate", XACRO, tmp_path / "fit.csv", "--units", "mm", "--test", tmp_path / "test.csv",
        "--xacro-arg", f"upper_length:={UPPER}", "--package-path", PACKAGE, "--params", "all",
        "-o", out, "--report", report,
    )  # fmt: skip
    assert code == 0, err
    result = json.loads(report.read_text())
    assert result["test"]["after"]["rms_mm"] < result["test"]["before"]["rms_mm"] / 10
    assert result["test"]["after"]["rms_mm"] < 0.2
    assert "<xacro:" not in out.read_text()
    calibrated = pincal.load_calibration(out)
    assert calibrated.instrument_T_base is not None
    predicted = np.array(
        [calibrated.instrument_T_base.act(calibrated.tool_pose(q).translation) for q in test.q]
    )
    assert np.sqrt(np.mean(np.sum((predicted - test.points) ** 2, axis=1))) < 2e-4
    assert calibrated.robot.joint_names == robot.joint_names


def test_every_robot_command_takes_the_xacro(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """twists, plan and diagnose read the xacro with the same options."""
    options = ("--package-path", PACKAGE, "--xacro-arg", f"upper_length:={UPPER}")
    code, out, err = run(capsys, "twists", XACRO, *options)
    assert code == 0 and "joint_6" in out, err
    code, _, err = run(
        capsys, "plan", XACRO, "--poses", "12", "--candidates", "200", "-o", tmp_path / "p.csv", *options
    )
    assert code == 0, err
    lines = (tmp_path / "p.csv").read_text().splitlines()
    assert [ln for ln in lines if not ln.startswith("#")][0].split(",")[:6] == [
        f"joint_{k}" for k in range(1, 7)
    ]


def test_a_missing_package_is_one_line_naming_it(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """No --package-path and no search path: one line that names the package and what to give."""
    data = tmp_path / "d.csv"
    data.write_text("joint_1,joint_2,joint_3,joint_4,joint_5,joint_6,x,y,z\n" + "0,0,0,0,0,0,0,0,0\n" * 10)
    line = one_error_line(capsys, "calibrate", XACRO, data)
    assert "'pincal_test_parts'" in line and "--package-path pincal_test_parts=DIR" in line
    assert "arm.urdf.xacro" in line
    line = one_error_line(capsys, "twists", XACRO, "--package-path", f"other={PARTS}")
    assert "'pincal_test_parts'" in line


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        (["--xacro-arg", "upper_lenght:=0.3"], "declares no such argument (it has: upper_length)"),
        (["--xacro-arg", "upper_length=0.3"], "expected NAME:=VALUE"),
        (["--package-path", "pincal_test_parts"], "expected PKG=DIR"),
        (["--package-path", "pincal_test_parts=/no/such/folder"], "is not a folder"),
    ],
)
def test_bad_xacro_options_are_one_line(
    capsys: pytest.CaptureFixture[str], options: list[str], expected: str
) -> None:
    """A misspelt argument, a malformed option or a missing folder: one line saying which."""
    full = ["--package-path", PACKAGE] if "--package-path" not in options else []
    assert expected in one_error_line(capsys, "twists", XACRO, *full, *options)


def test_a_broken_xacro_is_one_line(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """An undefined property, malformed XML, or --xacro-arg on a plain URDF: one line each."""
    broken = tmp_path / "broken.urdf.xacro"
    broken.write_text(XACRO.read_text().replace("${upper}", "${no_such_property}"))
    assert "no_such_property" in one_error_line(capsys, "twists", broken, "--package-path", PACKAGE)
    broken.write_text(XACRO.read_text().replace("</robot>", ""))
    assert "cannot process xacro" in one_error_line(capsys, "twists", broken, "--package-path", PACKAGE)
    assert "is not one" in one_error_line(capsys, "twists", "ur5", "--xacro-arg", "a:=1")
    entity = tmp_path / "entity.urdf.xacro"
    entity.write_text(
        '<?xml version="1.0"?>\n<!DOCTYPE r [<!ENTITY e SYSTEM "file:///etc/passwd">]>\n<robot/>'
    )
    assert "DOCTYPE" in one_error_line(capsys, "twists", entity)


@pytest.mark.parametrize(
    ("expression", "expected"),
    [("9**9**9", "did not finish in 1 s"), ("len('a' * 10**10)", "cannot process xacro")],
    ids=["endless", "memory"],
)
def test_a_hostile_expression_is_stopped(
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    tmp_path: Path,
    expression: str,
    expected: str,
) -> None:
    """A xacro whose expression computes without end, or asks for 10 GB: one line naming the file,
    within the time limit (1 s here), and the command stays usable after it."""
    import time

    import pincal.robot.descriptions

    monkeypatch.setattr(pincal.robot.descriptions, "XACRO_SECONDS", 1.0)
    hostile = tmp_path / "hostile.urdf.xacro"
    hostile.write_text(
        '<?xml version="1.0"?>\n<robot xmlns:xacro="http://www.ros.org/wiki/xacro" '
        f'name="${{{expression}}}"><link name="base"/></robot>'
    )
    start = time.monotonic()
    line = one_error_line(capsys, "twists", hostile)
    assert time.monotonic() - start < 10.0  # [s]: the limit and a fork, not the computation
    assert expected in line and "hostile.urdf.xacro" in line
    robot = pincal.load_robot(XACRO, package_paths={"pincal_test_parts": PARTS})
    assert robot.n_joints == 6
