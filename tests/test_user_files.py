"""Files as users have them, and options that would do nothing.

A URDF saved with blank lines before ``<?xml`` (as xacro output often is), a table separated by
semicolons or tabs, another robot's radians, options that change nothing in the run, ``tcp``
data in metres read as millimetres, an output that is the file standard input reads, and a
standard output closed before the run: each is read, or refused in one line that says what to
fix, never a silent wrong answer or misleading advice.
"""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from cli_run import one_error_line, run
from test_tool import PAPER_POSES as TCP_POSES

import pincal
import pincal.plausibility.readings as readings
from pincal.identify.evaluation import ErrorStats
from pincal.robot.robots import bundled_urdf

FAST = ("--params", "all", "--nested", "no", "--extend", "none")


@pytest.fixture(scope="module")
def ur5() -> pincal.Robot:
    return pincal.load_robot("ur5")


@pytest.fixture(scope="module")
def positions(tmp_path_factory: pytest.TempPathFactory, ur5: pincal.Robot) -> Path:
    """UR5 position data of a simulated truth (20 poses, 0.03 mm noise), radians and metres."""
    q = ur5.random_configurations(20, np.random.default_rng(3), 0.05)
    path = tmp_path_factory.mktemp("files") / "pos.csv"
    pincal.write_csv(path, pincal.random_truth(ur5, seed=4).measure(q, 3e-5, seed=5))
    return path


# ---------------------------------------------------------------- a URDF with a blank first line


@pytest.mark.parametrize("lead", ["\n", "\n  \n", "\r\n", "\t", "\ufeff\n", " "], ids=repr)
def test_a_urdf_with_white_space_before_its_declaration_loads(tmp_path: Path, lead: str) -> None:
    """Pinocchio (urdfdom) reads such a file; pincal did not ("not well-formed")."""
    text = bundled_urdf("ur5").read_text(encoding="utf-8")
    assert text.startswith("<?xml")
    path = tmp_path / "blank.urdf"
    path.write_text(lead + text, encoding="utf-8")
    robot = pincal.load_robot(path, tip="tool0")
    nominal = pincal.load_robot("ur5")
    q = nominal.random_configurations(3, np.random.default_rng(0))
    for row in q:
        assert np.allclose(robot.frame_placement(row).homogeneous, nominal.frame_placement(row).homogeneous)


def test_a_calibration_of_such_a_urdf_writes_a_urdf_that_loads(
    capsys: pytest.CaptureFixture[str], positions: Path, tmp_path: Path
) -> None:
    path = tmp_path / "blank.urdf"
    path.write_text("\n\n" + bundled_urdf("ur5").read_text(encoding="utf-8"), encoding="utf-8")
    out = tmp_path / "c.urdf"
    code, _, err = run(capsys, "calibrate", path, positions, "--tip", "tool0", *FAST, "-o", out)
    assert code == 0, err
    assert pincal.load_robot(out, tip="tool0").n_joints == 6


def test_a_xacro_with_a_blank_first_line_is_processed(tmp_path: Path) -> None:
    text = (
        '<?xml version="1.0"?>\n<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro">\n'
        '<xacro:property name="l" value="0.3"/>\n<link name="a"/><link name="b"/>\n'
        '<joint name="j" type="revolute"><parent link="a"/><child link="b"/>'
        '<origin xyz="0 0 ${l}"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/>'
        "</joint>\n</robot>\n"
    )
    path = tmp_path / "arm.urdf.xacro"
    path.write_text("\n  \n" + text, encoding="utf-8")
    robot = pincal.load_robot(path, tip="b")
    assert robot.joint_names == ("j",)
    assert np.isclose(robot.frame_placement(np.zeros(1)).translation[2], 0.3)


# ---------------------------------------------------------------- separators


@pytest.mark.parametrize(("sep", "name"), [(";", "semicolons"), ("\t", "tabs"), ("|", "vertical bars")])
@pytest.mark.parametrize("command", ["calibrate", "tcp"])
def test_a_table_with_another_separator_is_named(
    capsys: pytest.CaptureFixture[str], positions: Path, tmp_path: Path, sep: str, name: str, command: str
) -> None:
    """The message names the separator; it used to advise locking every joint."""
    path = tmp_path / "sep.csv"
    path.write_text(positions.read_text().replace(",", sep))
    args = ("calibrate", "ur5", path, *FAST) if command == "calibrate" else ("tcp", path)
    line = one_error_line(capsys, *args)
    assert name in line and "comma" in line, line
    assert "--lock" not in line


def test_rows_with_another_separator_than_the_header_are_named(
    capsys: pytest.CaptureFixture[str], positions: Path, tmp_path: Path
) -> None:
    lines = positions.read_text().splitlines()
    path = tmp_path / "rows.csv"
    path.write_text("\n".join([lines[0], *(line.replace(",", ";") for line in lines[1:])]) + "\n")
    line = one_error_line(capsys, "calibrate", "ur5", path, *FAST)
    assert "data row 1" in line and "semicolons" in line, line


def test_decimal_commas_with_semicolons_are_named(
    capsys: pytest.CaptureFixture[str], positions: Path, tmp_path: Path
) -> None:
    text = positions.read_text().replace(",", ";").replace(".", ",")
    path = tmp_path / "locale.csv"
    path.write_text(text)
    line = one_error_line(capsys, "calibrate", "ur5", path, *FAST)
    assert "semicolons" in line and "decimal" in line, line


# ---------------------------------------------------------------- another robot's radians


def test_a_reading_that_keeps_the_robot_still_names_no_unit(
    monkeypatch: pytest.MonkeyPatch, ur5: pincal.Robot, positions: Path
) -> None:
    """Another robot's radians read as degrees keep the tip nearly still, and a still robot fits
    fixed points about as well as any: such a reading is not named as the cause ("pass --degrees"
    for a Panda's data on an iiwa), however well it fits; one that moves the tip still is."""
    data = pincal.read_csv(positions, ur5.joint_names)
    cal = pincal.calibrate(ur5, data, params="all", extension="none")
    wrong = replace(cal, train_before=replace(cal.train_before, rms_mm=500.0))  # as another robot's data
    fitted = ErrorStats(rms_mm=5.0, mean_mm=5.0, max_mm=5.0, std_mm=0.0, n=len(data))
    worse = replace(fitted, rms_mm=1e4, mean_mm=1e4, max_mm=1e4)

    def registration(_cal: object, alt: pincal.Dataset, _options: object) -> tuple[ErrorStats, float]:
        return (fitted if not np.array_equal(alt.q, data.q) else worse), 1.0

    monkeypatch.setattr(readings, "_registration_only", registration)
    still = readings.tip_motion(cal, replace(data, q=np.deg2rad(data.q)))
    assert still < 0.05  # [m]: the degrees reading of radians barely moves the tip
    assert readings.other_reading(wrong, data, False, "wxyz") is None
    moved = replace(fitted, rms_mm=0.05 * still * 1e3, mean_mm=0.05 * still * 1e3)

    def small(_cal: object, alt: pincal.Dataset, _options: object) -> tuple[ErrorStats, float]:
        return (moved if not np.array_equal(alt.q, data.q) else worse), 1.0

    monkeypatch.setattr(readings, "_registration_only", small)
    found = readings.other_reading(wrong, data, False, "wxyz")
    assert found is not None and found[0] == "degrees"


# ---------------------------------------------------------------- options that would do nothing


@pytest.mark.parametrize(
    ("options", "named"),
    [
        (("--payload", "2,0,0,0.1", "--extend", "none"), "--payload"),
        (("--payload", "2,0,0,0.1", "--extend", "gear_harmonic:elbow_joint"), "--payload"),
        (("--payload", "2,0,0,0.1", "--extend", "encoder_scale:elbow_joint"), "--payload"),
        (
            ("--payload", "2,0,0,0.1", "--extend", "encoder_scale:elbow_joint+lost_motion:wrist_1_joint"),
            "--payload",
        ),
    ],
    ids=["none", "harmonic", "scale", "several"],
)
def test_gravity_options_without_a_gravity_effect_are_refused(
    capsys: pytest.CaptureFixture[str], positions: Path, tmp_path: Path, options: tuple[str, ...], named: str
) -> None:
    fast = FAST[:4]  # --extend is the option under test
    out = tmp_path / "c.urdf"
    line = one_error_line(capsys, "calibrate", "ur5", positions, *fast, *options, "-o", out)
    assert named in line and "joint_compliance" in line, line
    assert not out.exists()


def test_a_payload_the_kept_model_does_not_use_is_said(
    capsys: pytest.CaptureFixture[str], positions: Path
) -> None:
    """With --extend auto the payload shapes the candidates; when none is kept, a warning says
    that it changed nothing written."""
    code, _, err = run(capsys, "calibrate", "ur5", positions, *FAST[:4], "--payload", "2,0,0,0.1")
    assert code == 0, err
    said = [line for line in err.splitlines() if "--payload" in line]
    assert len(said) == 1 and said[0].startswith("pincal: warning:"), err


def test_a_payload_for_compliance_is_not_said(capsys: pytest.CaptureFixture[str], positions: Path) -> None:
    extend = ("--extend", "joint_compliance:shoulder_lift_joint")
    code, _, err = run(capsys, "calibrate", "ur5", positions, *FAST[:4], *extend, "--payload", "2,0,0,0.1")
    assert code == 0 and "--payload" not in err, err


def _tcp_file(path: Path, header: str = "x,y,z,a,b,c", factor: float = 1.0, rows: int = 6) -> Path:
    lines = [header] + [
        ",".join([*(repr(v * factor) for v in row[:3]), *(repr(v) for v in row[3:])])
        for row in TCP_POSES[:rows]
    ]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize(
    "columns",
    ["x=X_mm,qw=QW", "x=X_mm,w=X_mm", "x=Xmm", "x=X_mm,y=y,q=y"],
    ids=["absent", "key", "typo", "both"],
)
def test_a_column_list_naming_what_is_not_there_is_refused(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, columns: str
) -> None:
    path = _tcp_file(tmp_path / "p.csv", "X_mm,y,z,a,b,c", rows=4)
    line = one_error_line(capsys, "tcp", path, "--units", "mm", "--columns", columns)
    assert "--columns" in line, line


def test_a_column_list_that_applies_is_read(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = _tcp_file(tmp_path / "p.csv", "X_mm,y,z,a,b,c", rows=4)
    code, out, err = run(capsys, "tcp", path, "--units", "mm", "--columns", "x=X_mm")
    assert code == 0, err


@pytest.mark.parametrize(("rows", "orientation"), [(4, "default"), (6, "zx"), (5, "z")])
def test_tcp_data_in_metres_read_as_millimetres_is_refused(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, rows: int, orientation: str
) -> None:
    """It gave a tool of 0.37 mm without a word."""
    poses = TCP_POSES if orientation != "z" else (*TCP_POSES[:4], TCP_POSES[5])
    path = tmp_path / "m.csv"
    header = "x,y,z,a,b,c"
    path.write_text(
        "\n".join(
            [
                header,
                *(
                    ",".join(repr(v / 1e3) for v in p[:3]) + "," + ",".join(map(repr, p[3:]))
                    for p in poses[:rows]
                ),
            ]
        )
        + "\n"
    )
    line = one_error_line(capsys, "tcp", path, "--units", "mm", "--orientation", orientation)
    assert "metres" in line and "drop --units mm" in line, line
    code, _, err = run(capsys, "tcp", path, "--orientation", orientation)
    assert code == 0, err


# ---------------------------------------------------------------- standard streams


def _cli(args: list[str | Path], **kwargs: object) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(Path(pincal.__file__).parents[1])}
    return subprocess.run(  # type: ignore[call-overload, no-any-return]
        [sys.executable, "-m", "pincal", *map(str, args)], text=True, timeout=300, env=env, **kwargs
    )


def test_an_output_that_is_the_file_standard_input_reads_is_refused(positions: Path, tmp_path: Path) -> None:
    data = tmp_path / "data.csv"
    data.write_bytes(positions.read_bytes())
    before = data.read_bytes()
    for output in (["--report", data], ["-o", tmp_path / "c.urdf", "--report", data]):
        with open(data, "rb") as stdin:
            done = _cli(
                ["calibrate", "ur5", "-", *FAST, *output, "--force"], stdin=stdin, capture_output=True
            )
        assert done.returncode == 2, done.stderr
        assert "standard input" in done.stderr and done.stderr.count("\n") == 1, done.stderr
        assert data.read_bytes() == before
        assert not (tmp_path / "c.urdf").exists()


@pytest.mark.parametrize("command", [["twists", "ur5"], ["template", "ur5", "-o", "t.csv"]])
def test_a_standard_output_closed_before_the_run_is_said(tmp_path: Path, command: list[str]) -> None:
    done = _cli(
        command,
        cwd=tmp_path,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        preexec_fn=lambda: os.close(1),
    )
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and "standard output is closed" in done.stderr, done.stderr
    assert list(tmp_path.iterdir()) == []


def test_a_reader_gone_stays_quiet() -> None:
    """``| head -0``: the broken pipe ends quietly with 141, as before."""
    done = subprocess.run(
        f"{sys.executable} -m pincal twists ur5 | head -c 0",
        shell=True,
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(Path(pincal.__file__).parents[1])},
        executable="/bin/bash",
        timeout=300,
    )
    assert "error" not in done.stderr, done.stderr


# ---------------------------------------------------------------- write_csv as read_csv reads


@pytest.mark.parametrize("degrees", [False, True])
@pytest.mark.parametrize("units", ["m", "mm"])
def test_write_csv_writes_what_read_csv_reads_back(tmp_path: Path, degrees: bool, units: str) -> None:
    """With the same ``degrees``, ``units`` and ``prismatic``, reading the file back gives the
    dataset; the file holds degrees when asked (revolute joints only), prismatic joints in ``units``."""
    names = ("j1", "slide", "j3")
    prismatic = (False, True, False)
    rng = np.random.default_rng(7)
    q = rng.uniform(-2.5, 2.5, (8, 3))
    q[:, 1] = rng.uniform(0.0, 0.4, 8)  # [m]
    data = pincal.Dataset(names, q, rng.normal(0.0, 0.5, (8, 3)))
    path = tmp_path / "d.csv"
    pincal.write_csv(path, data, units=units, degrees=degrees, prismatic=prismatic)
    back = pincal.read_csv(path, names, degrees=degrees, units=units, prismatic=prismatic)
    assert np.allclose(back.q, data.q, rtol=0, atol=1e-12)
    assert np.allclose(back.points, data.points, rtol=0, atol=1e-12)
    written = np.loadtxt(path, delimiter=",", skiprows=1)
    assert np.allclose(written[:, 0], np.rad2deg(q[:, 0]) if degrees else q[:, 0])
    assert np.allclose(written[:, 1], q[:, 1] * (1e3 if units == "mm" else 1.0))


def test_socket_files_with_another_separator_are_named(
    capsys: pytest.CaptureFixture[str], ur5: pincal.Robot, tmp_path: Path
) -> None:
    q = ur5.random_configurations(6, np.random.default_rng(1), 0.05)
    folder = tmp_path / "holes"
    folder.mkdir()
    for k in range(2):
        rows = q[3 * k : 3 * k + 3]
        text = "\n".join(";".join(repr(float(v)) for v in row) for row in rows)
        (folder / f"hole_{k}.csv").write_text(text + "\n")
    line = one_error_line(capsys, "calibrate", "ur5", folder, "--point-distance", "0,1=0.05")
    assert "semicolons" in line and "hole_0.csv" in line, line


def test_program_targets_in_metres_read_as_millimetres_are_refused(
    capsys: pytest.CaptureFixture[str], ur5: pincal.Robot, positions: Path, tmp_path: Path
) -> None:
    """Read as millimetres, metres put every target inside the robot's base: it compensated them
    without a word."""
    cal = pincal.calibrate(ur5, pincal.read_csv(positions, ur5.joint_names), params="all", extension="none")
    urdf = tmp_path / "cal.urdf"
    pincal.write_corrected_urdf(cal, urdf)
    q = ur5.random_configurations(4, np.random.default_rng(5), 0.1)
    tips = np.array([ur5.frame_placement(row).translation for row in q])  # [m], within reach
    program = tmp_path / "targets.csv"
    program.write_text("x,y,z\n" + "\n".join(",".join(repr(float(v)) for v in tip) for tip in tips) + "\n")
    out = tmp_path / "comp.csv"
    args = ("compensate", "ur5", urdf, program, "--task", "position", "-o", out)
    line = one_error_line(capsys, *args, "--units", "mm")
    assert "drop --units mm" in line, line
    assert not out.exists()
    code, _, err = run(capsys, *args)
    assert code == 0, err


def test_recording_options_with_a_csv_program_or_visits_are_said(
    capsys: pytest.CaptureFixture[str], ur5: pincal.Robot, positions: Path, tmp_path: Path
) -> None:
    """``compensate`` and ``accuracy`` read recordings too; given a CSV, their recording options
    change nothing: a warning names them (they passed in silence)."""
    cal = pincal.calibrate(ur5, pincal.read_csv(positions, ur5.joint_names), params="all", extension="none")
    urdf = tmp_path / "cal.urdf"
    pincal.write_corrected_urdf(cal, urdf)
    lines = positions.read_text().splitlines()
    program = tmp_path / "program.csv"
    program.write_text("\n".join(",".join(line.split(",")[:6]) for line in lines[:4]) + "\n")
    args = ("compensate", "ur5", urdf, program, "-o", tmp_path / "c.csv", "--task", "position")
    code, _, err = run(capsys, *args, "--joint-topic", "/js")
    assert code == 0 and "--joint-topic" in err and "warning" in err, err
    visits = tmp_path / "visits.csv"
    rows = [f"{line},{k % 3}" for k, line in enumerate(lines[1:10])]
    visits.write_text("\n".join([f"{lines[0]},pose", *rows]) + "\n")
    code, _, err = run(capsys, "accuracy", "ur5", visits, "--pose-tolerance", "0.01", "--static-time", "2")
    said = [line for line in err.splitlines() if "ROS recordings only" in line]
    assert code == 0 and len(said) == 1 and "--pose-tolerance" in said[0] and "--static-time" in said[0], err
