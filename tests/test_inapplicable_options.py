"""Options the data has no use for are refused or said, never ignored in silence.

Before, ``calibrate`` on position data took ``--pairs gao``, ``--rotation-weight``,
``--quaternion-order xyzw`` and ``--point-distance`` without a word, and ``--instrument-frame
base`` with distance data; ``-o a.csv`` wrote a URDF into a file named ``.csv``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from cli_run import one_error_line, run

import pincal

FAST = ("--params", "all", "--nested", "no")


@pytest.fixture(scope="module")
def positions(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """UR5 position data of a simulated truth (20 poses, 0.03 mm noise)."""
    ur5 = pincal.load_robot("ur5")
    q = ur5.random_configurations(20, np.random.default_rng(3), 0.05)
    path = tmp_path_factory.mktemp("inapplicable") / "pos.csv"
    pincal.write_csv(path, pincal.random_truth(ur5, seed=4).measure(q, 3e-5, seed=5))
    return path


@pytest.mark.parametrize(
    ("option", "words"),
    [
        (("--pairs", "gao"), ("--pairs gao", "--measure distance", "position data")),
        (("--point-distance", "0,1=50"), ("--point-distance", "fixed-point", "position data")),
    ],
    ids=["pairs", "point-distance"],
)
def test_options_of_another_measurement_kind_are_refused(
    capsys: pytest.CaptureFixture[str], positions: Path, tmp_path: Path, option: tuple[str, str], words: tuple
) -> None:
    out = tmp_path / "cal.urdf"
    line = one_error_line(capsys, "calibrate", "ur5", positions, *option, *FAST, "-o", out)
    for word in words:
        assert word in line, (word, line)
    assert not out.exists()


@pytest.mark.parametrize(
    ("options", "measure", "named"),
    [
        (("--rotation-weight", "0.5"), "position", ["--rotation-weight"]),
        (("--quaternion-order", "xyzw"), "position", ["--quaternion-order"]),
        (("--instrument-frame", "base"), "distance", ["--instrument-frame base"]),
        (
            ("--rotation-weight", "0.5", "--quaternion-order", "xyzw"),
            "position",
            ["--rotation-weight", "--quaternion-order"],
        ),
    ],
    ids=["rotation-weight", "quaternion-order", "instrument-frame", "both"],
)
def test_options_the_data_has_no_use_for_are_said(
    capsys: pytest.CaptureFixture[str],
    positions: Path,
    options: tuple[str, ...],
    measure: str,
    named: list[str],
) -> None:
    """The fit runs as without the option, and one warning names every option it ignored."""
    code, out, err = run(capsys, "calibrate", "ur5", positions, "--measure", measure, *options, *FAST)
    assert code == 0, err
    warnings = [line for line in err.splitlines() if line.startswith("pincal: warning: ignored")]
    assert len(warnings) == 1, err
    assert f"{measure} data" in warnings[0]
    for name in named:
        assert name in warnings[0], (name, warnings[0])
    code_plain, out_plain, _ = run(capsys, "calibrate", "ur5", positions, "--measure", measure, *FAST)
    assert code_plain == 0 and out_plain == out  # the same fit, the same tables


def test_options_that_apply_are_not_said(capsys: pytest.CaptureFixture[str], positions: Path) -> None:
    code, _, err = run(capsys, "calibrate", "ur5", positions, "--rotation-weight", "0.1", *FAST)
    assert code == 0 and "ignored" not in err, err


@pytest.mark.parametrize("name", ["a.csv", "a.JSON", "a.txt", "robot_calibrated", "a.urdf.xacro", "a.xml"])
def test_the_corrected_robot_is_not_written_as_data(
    capsys: pytest.CaptureFixture[str], positions: Path, tmp_path: Path, name: str
) -> None:
    line = one_error_line(capsys, "calibrate", "ur5", positions, *FAST, "-o", tmp_path / name)
    assert ".urdf" in line and name in line, line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name", ["a.urdf", "a.URDF"])
def test_the_corrected_robot_is_written_as_urdf(
    capsys: pytest.CaptureFixture[str], positions: Path, tmp_path: Path, name: str
) -> None:
    code, _, err = run(capsys, "calibrate", "ur5", positions, *FAST, "-o", tmp_path / name)
    assert code == 0, err
    assert len(pincal.load_robot(tmp_path / name, tip="tool0").joint_names) == 6


def test_compensate_says_it_reads_the_joints_not_the_targets(
    capsys: pytest.CaptureFixture[str], positions: Path, tmp_path: Path
) -> None:
    """A measurement file used as a program: its joint columns are the commands, and the warning
    says its x,y,z are not read (a NaN there changes nothing)."""
    ur5 = pincal.load_robot("ur5")
    cal = pincal.calibrate(ur5, pincal.read_csv(positions, ur5.joint_names), params="all")
    urdf = tmp_path / "cal.urdf"
    pincal.write_corrected_urdf(cal, urdf)
    lines = positions.read_text().splitlines()
    program = tmp_path / "program.csv"
    program.write_text("\n".join([lines[0], *lines[1:4]]) + "\n")
    code, _, err = run(capsys, "compensate", "ur5", urdf, program, "-o", tmp_path / "a.csv")
    assert code == 0, err
    said = [line for line in err.splitlines() if line.startswith("pincal: warning:")]
    assert len(said) == 1 and "x,y,z" in said[0] and "not read" in said[0], err
    joints_only = tmp_path / "joints.csv"
    n = len(ur5.joint_names)
    joints_only.write_text("\n".join(",".join(line.split(",")[:n]) for line in lines[:4]) + "\n")
    code, _, err = run(capsys, "compensate", "ur5", urdf, joints_only, "-o", tmp_path / "b.csv")
    assert code == 0 and "warning" not in err, err
    assert (tmp_path / "a.csv").read_text() == (tmp_path / "b.csv").read_text()
