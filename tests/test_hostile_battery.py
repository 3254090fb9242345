"""The rest of issue 17's hostile battery: what a new user gets wrong, on every command.

Each case ends in exit 0 with a correct result, or exit 2 with one ``pincal: error:`` line naming
the cause, nothing on stdout, no output file and its inputs unchanged. The other families have
their own files (``test_bad_input.py``, ``test_hostile_urdf.py``, ``test_outputs.py``,
``test_stdin.py``, ``test_plausibility.py``); the cases here are those found by the battery run
for this file, each under a ``# Regression (was a bug)`` comment, and a quick pass over the
listed cases that ran in no other test. Every run is in-process, on 20 simulated poses.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from cli_run import one_error_line, run

import pincal

FAST = ("--params", "all", "--nested", "no")


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """UR5 position data, its calibration (URDF and sidecar), a joint program and TCP poses."""
    folder = tmp_path_factory.mktemp("battery")
    ur5 = pincal.load_robot("ur5")
    q = ur5.random_configurations(20, np.random.default_rng(5), 0.05)
    data = pincal.random_truth(ur5, seed=1).measure(q, 3e-5, seed=2)
    pincal.write_csv(folder / "pos.csv", data)
    cal = pincal.calibrate(ur5, data, params="all")
    urdf = folder / "cal.urdf"
    pincal.write_corrected_urdf(cal, urdf)
    (folder / "prog.csv").write_text(
        ",".join(ur5.joint_names) + "\n" + "\n".join(",".join(map(repr, row)) for row in q[:3]) + "\n"
    )
    rng = np.random.default_rng(0)
    point, tcp = np.array([0.5, 0.1, 0.2]), np.array([0.01, 0.02, 0.15])
    rows = []
    for _ in range(12):
        rot = pin.exp3(rng.normal(0, 0.5, 3))
        quat = pin.Quaternion(rot)
        rows.append([*(point - rot @ tcp), quat.x, quat.y, quat.z, quat.w])  # x,y,z,w order
    (folder / "tcp_xyzw.csv").write_text(
        "x,y,z,qw,qx,qy,qz\n" + "\n".join(",".join(f"{float(v)!r}" for v in r) for r in rows) + "\n"
    )
    names = {"pos": "pos.csv", "prog": "prog.csv", "tcp": "tcp_xyzw.csv"}
    return {"urdf": urdf, **{key: folder / name for key, name in names.items()}}


def _sidecar_copy(files: dict[str, Path], folder: Path, edit: Callable[[dict], object]) -> Path:
    """A copy of the calibration whose sidecar is ``edit``'s result (or the edited dict)."""
    urdf = folder / "edited.urdf"
    urdf.write_bytes(files["urdf"].read_bytes())
    side = json.loads(files["urdf"].with_suffix(".calibration.json").read_text())
    result = edit(side)
    text = result if isinstance(result, str) else json.dumps(side if result is None else result)
    (folder / "edited.calibration.json").write_text(text)
    return urdf


def _huge_tool(side: dict) -> None:
    side["tip_T_tool"]["matrix"][0][3] = 1e300


def _nan_matrix(side: dict) -> None:
    side["instrument_T_base"]["matrix"][1][1] = float("nan")


def _not_rotation(side: dict) -> None:
    side["instrument_T_base"]["matrix"][0][0] = 2.0


#: sidecar edit -> words of the error line
SIDECARS: dict[str, tuple[Callable[[dict], object], tuple[str, ...]]] = {
    # Regression (was a bug): a RecursionError traceback
    "deeply_nested": (lambda side: "[" * 100_000 + "]" * 100_000, ("nested too deeply",)),
    # Regression (was a bug): "bad or missing list indices must be integers or slices, not str"
    "a_list": (lambda side: [1, 2], ("not a JSON object",)),
    # Regression (was a bug): overflow warnings on stderr (five lines), then "unreachable"
    "huge_tool": (_huge_tool, ("tip_T_tool", "1e6 m")),
    "nan_matrix": (_nan_matrix, ("instrument_T_base", "finite")),
    "not_a_rotation": (_not_rotation, ("instrument_T_base", "not a rotation")),
}


@pytest.mark.parametrize("case", sorted(SIDECARS))
def test_compensate_refuses_a_broken_sidecar(
    case: str, files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    edit, words = SIDECARS[case]
    urdf = _sidecar_copy(files, tmp_path, edit)
    line = one_error_line(capsys, "compensate", "ur5", urdf, files["prog"], "-o", tmp_path / "out.csv")
    for word in words:
        assert word in line, (word, line)
    assert not (tmp_path / "out.csv").exists()


# Regression (was a bug): a refused result still printed its tables on stdout (tcp printed a
# wrong TCP, calibrate its error table) before the one error line
def test_a_refused_result_prints_nothing_on_stdout(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = run(capsys, "tcp", files["tcp"])
    assert code == 2 and "--quaternion-order xyzw" in err, err
    assert out == ""
    code, out, _ = run(capsys, "tcp", files["tcp"], "--quaternion-order", "xyzw")
    assert code == 0 and "(0.0100, 0.0200, 0.1500) m" in out, out


# Regression (was a bug): a tip before joints whose columns move (data measured on tool0,
# --tip wrist_1_link) was calibrated to 50 mm RMS and accepted
@pytest.mark.parametrize("tip", ["wrist_1_link", "forearm_link"])
def test_data_measured_after_the_tip_is_refused(
    tip: str, files: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    line = one_error_line(capsys, "calibrate", "ur5", files["pos"], "--tip", tip, *FAST)
    assert f"after the tip {tip}" in line and "pass --tip wrist_3_link" in line, line


def test_joints_after_the_tip_that_explain_nothing_are_ignored(
    get_robot: Callable[[str], pincal.Robot], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A gripper's finger columns that move, past a flange tip, are no reason to refuse."""
    hand = pincal.load_robot("panda", tip="panda_hand")
    q = hand.random_configurations(20, np.random.default_rng(1), 0.05)
    pincal.write_csv(tmp_path / "hand.csv", pincal.random_truth(hand, seed=0).measure(q, 3e-5))
    lines = (tmp_path / "hand.csv").read_text().splitlines()
    fingers = np.random.default_rng(2).uniform(0, 0.04, len(lines) - 1)
    rows = [f"{row},{f!r},{f!r}" for row, f in zip(lines[1:], fingers)]
    header = f"{lines[0]},panda_finger_joint1,panda_finger_joint2"
    (tmp_path / "fingers.csv").write_text("\n".join([header, *rows]) + "\n")
    code, _, err = run(capsys, "calibrate", "panda", tmp_path / "fingers.csv", "--tip", "panda_hand", *FAST)
    assert code == 0, err


# Regression (was a bug): without --robot, tcp ignored --degrees, --tip, --kinematics (even a
# missing file) and printed a result
@pytest.mark.parametrize(
    "options", [("--degrees",), ("--tip", "tool0"), ("--kinematics", "missing.yaml"), ("--xacro-arg", "a:=1")]
)
def test_tcp_refuses_robot_options_without_a_robot(
    options: tuple[str, ...], files: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    line = one_error_line(capsys, "tcp", files["tcp"], "--quaternion-order", "xyzw", *options)
    assert f"{options[0]}: only with --robot" in line, line


# Regression (was a bug): a RecursionError traceback
def test_a_deeply_nested_kinematics_yaml_is_refused(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    deep = tmp_path / "deep.yaml"
    deep.write_text("[" * 100_000 + "]" * 100_000)
    line = one_error_line(capsys, "calibrate", "ur5", files["pos"], "--kinematics", deep)
    assert "nested too deeply" in line


# Regression (was a bug): --params @/dev/zero read forever
def test_params_from_an_endless_file_is_refused(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    line = one_error_line(capsys, "calibrate", "ur5", files["pos"], "--params", "@/dev/zero")
    assert "larger than 1 MB" in line


# Regression (was a bug): Ctrl-C after the command had ended (while the interpreter shut down)
# killed the process with SIGINT (exit -2), its outputs written
def test_a_late_ctrl_c_does_not_kill_the_finished_command() -> None:
    script = (
        "import os, signal, sys\n"
        "from pincal.cli import main\n"
        "sys.argv = ['pincal', 'twists', 'ur5']\n"
        "code = main()\n"
        "os.kill(os.getpid(), signal.SIGINT)\n"
        "sys.exit(code)\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, (done.returncode, done.stderr)
    assert "Traceback" not in done.stderr


#: The listed cases no other test runs, as (arguments, words of the error line); FILE arguments
#: are replaced by the fixture's files.
LISTED: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "rotation_weight_nan": (("calibrate", "ur5", "POS", "--rotation-weight", "nan"), ("finite",)),
    "rotation_weight_inf": (("calibrate", "ur5", "POS", "--rotation-weight", "inf"), ("finite",)),
    "rotation_weight_huge": (("calibrate", "ur5", "POS", "--rotation-weight", "1e300"), ("at most 1000",)),
    "lock_moving": (("calibrate", "ur5", "POS", "--lock", "wrist_3_joint"), ("column moves",)),
    "instrument_base": (("calibrate", "ur5", "POS", "--instrument-frame", "base", *FAST), ("base frame",)),
    "candidates": (("plan", "ur5", "--poses", "12", "--candidates", "10000000", "-o", "OUT"), ("memory",)),
}


@pytest.mark.parametrize("case", sorted(LISTED))
def test_listed_cases_end_in_one_line(
    case: str, files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args, words = LISTED[case]
    given = {"POS": files["pos"], "OUT": tmp_path / "out.csv"}
    before = files["pos"].read_bytes()
    line = one_error_line(capsys, *(given.get(a, a) for a in args))
    for word in words:
        assert word in line, (word, line)
    assert files["pos"].read_bytes() == before
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("value", ["1e160", "1e300"])
@pytest.mark.parametrize("quaternions", [False, True], ids=["euler", "quaternion"])
def test_tcp_refuses_flange_positions_no_instrument_measures(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, value: str, quaternions: bool
) -> None:
    """A flange position of 1e160 m (a fuzzed cell) is one error line naming the columns, with
    no overflow warning on the way (it used to overflow through the fit to "scatter by inf m")."""
    import warnings

    rng = np.random.default_rng(0)
    rows = []
    for k in range(6):
        rotation = pin.exp3(rng.normal(0.0, 0.5, 3))
        position = [800.0, 100.0, 300.0] - rotation @ np.array([10.0, -20.0, 150.0])  # [mm]
        turn = pin.Quaternion(rotation)
        zyx = np.rad2deg(pin.rpy.matrixToRpy(rotation))[::-1]  # a, b, c [deg]
        angles = [turn.w, turn.x, turn.y, turn.z] if quaternions else list(zyx)
        cells = [repr(float(v)) for v in [*position, *angles]]
        rows.append([value, *cells[1:]] if k == 2 else cells)
    header = "x,y,z,qw,qx,qy,qz" if quaternions else "x,y,z,a,b,c"
    data = tmp_path / "flange.csv"
    data.write_text("\n".join([header, *(",".join(row) for row in rows)]) + "\n")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        line = one_error_line(capsys, "tcp", data, "--units", "mm")
    assert "flange positions x,y,z" in line
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)], caught


def test_huge_quaternion_entries_are_scaled_not_overflowed(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """A quaternion with an entry of 1e308 (a fuzzed cell, found with x = 1e308 by tcp's fuzz
    test) is the rotation of its direction: scaled first, its norm no longer overflows to a
    RuntimeWarning; with x = 1e308 too, tcp's one error line is the positions'."""
    import warnings

    from pincal.data.csv_table import unit_quaternions

    big = np.array([[1e308, 1e308, 0.0, 0.0], [1e308, 0.0, 0.0, 0.0], [0.5, 0.5, 0.5, 0.5]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        unit = unit_quaternions("q.csv", big)
    expected = [[2**-0.5, 2**-0.5, 0, 0], [1, 0, 0, 0], [0.5, 0.5, 0.5, 0.5]]
    np.testing.assert_allclose(unit, expected, atol=1e-15)
    with pytest.raises(pincal.DataError, match="data row 2: the quaternion"):
        unit_quaternions("q.csv", np.array([[1.0, 0, 0, 0], [0.0, 0, 0, 1e-12]]))
    rows = ["x,y,z,qw,qx,qy,qz", "1e308,171.2,166.6,1e308,0.17,0.02,-0.29"]
    rows += [f"{800 + 10 * k},{40 + 20 * k},{160 + 5 * k},0.9,{-0.2 + 0.1 * k},0.1,0.05" for k in range(5)]
    data = tmp_path / "flange.csv"
    data.write_text("\n".join(rows) + "\n")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        line = one_error_line(capsys, "tcp", data)
    assert "flange positions x,y,z" in line
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)], caught
