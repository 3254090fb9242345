"""``pincal plan`` and ``pincal compensate`` on the command line (issue 8).

Properties: the planned poses are within the joint limits and as many as asked; a compensated
program makes the calibrated model reach what the nominal model reached with the original
commands; rows that cannot be compensated are named by row number, with exit 0 while any row
succeeds and exit 2 (one error line, no output) when none does.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import pincal
from pincal.cli import main
from pincal.data.dataset import read_table


def _run(capsys: pytest.CaptureFixture[str], *args: str | Path) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


def _write_joints(path: Path, names: tuple[str, ...], q: np.ndarray) -> Path:
    lines = [",".join(names)] + [",".join(repr(float(v)) for v in row) for row in q]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_plan_writes_poses_within_limits(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    robot = pincal.load_robot("ur5")
    out = tmp_path / "poses.csv"
    code, text, err = _run(capsys, "plan", "ur5", "--poses", "25", "--candidates", "300", "-o", out)
    assert code == 0, err
    assert "planned" in text and "random" in text
    q = read_table(out, robot.joint_names, "joints")
    assert q.shape == (25, robot.n_joints)
    assert np.all(q >= robot.lower) and np.all(q <= robot.upper)
    before = out.read_bytes()
    code, _, err = _run(capsys, "plan", "ur5", "--poses", "25", "-o", out, "--seed", "3")
    assert code == 2 and "--force" in err and len(err.splitlines()) == 1
    assert out.read_bytes() == before


def test_plan_too_few_poses_is_refused(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    out = tmp_path / "poses.csv"
    code, _, err = _run(capsys, "plan", "ur5", "--poses", "4", "-o", out)
    assert code == 2 and err.startswith("pincal: error:") and len(err.splitlines()) == 1
    assert not out.exists()


@pytest.fixture(scope="module")
def calibration(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, pincal.simulation.truth.TrueRobot]:
    """A ur5 calibrated from 60 simulated poses through the CLI, and its simulated truth."""
    folder = tmp_path_factory.mktemp("cal")
    robot = pincal.load_robot("ur5")
    truth, fit, _ = pincal.simulate(robot, n_fit=60, n_test=10, seed=4)
    pincal.write_csv(folder / "fit.csv", fit)
    assert main(["calibrate", "ur5", str(folder / "fit.csv"), "-o", str(folder / "cal.urdf")]) == 0
    return folder / "cal.urdf", truth


def test_compensate_reaches_nominal_targets_and_names_failed_rows(
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    calibration: tuple[Path, pincal.simulation.truth.TrueRobot],
) -> None:
    urdf, _ = calibration
    nominal = pincal.load_robot("ur5")
    q = nominal.random_configurations(12, np.random.default_rng(0), 0.1)
    q[4, 1] = 9.0  # beyond shoulder_lift_joint's limit: data row 5
    program = _write_joints(tmp_path / "program.csv", nominal.joint_names, q)
    out = tmp_path / "compensated.csv"
    code, text, err = _run(capsys, "compensate", "ur5", urdf, program, "-o", out)
    assert code == 0, err
    assert "row 5: unreachable" in text
    assert "compensated 11 of 12 rows (pose task): the tool within " in text  # issue 43
    assert "mrad of the pose the nominal URDF gave it; largest joint change" in text

    compensated = read_table(out, nominal.joint_names, "joints")
    cal = pincal.load_calibration(urdf)
    for i in range(len(q)):
        if i == 4:
            np.testing.assert_array_equal(compensated[i], q[i])  # a failed row keeps its commands
            continue
        wanted = nominal.frame_placement(q[i]) * cal.tool
        reached = cal.tool_pose(compensated[i])
        assert np.linalg.norm(reached.translation - wanted.translation) < 1e-6  # [m]
        assert np.linalg.norm(pin.log3(wanted.rotation.T @ reached.rotation)) < 1e-5  # [rad], issue 43
        assert np.abs(compensated[i] - q[i]).max() > 1e-6  # the calibration changed something


def test_compensate_position_task_says_how_far_the_orientation_turned(
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    calibration: tuple[Path, pincal.simulation.truth.TrueRobot],
) -> None:
    """Issue 43: ``--task position`` keeps the point only, and the summary gives the orientation's
    largest turn, the one the written commands make."""
    urdf, _ = calibration
    nominal = pincal.load_robot("ur5")
    q = nominal.random_configurations(8, np.random.default_rng(1), 0.1)
    program = _write_joints(tmp_path / "program.csv", nominal.joint_names, np.rad2deg(q))
    out = tmp_path / "compensated.csv"
    code, text, err = _run(
        capsys, "compensate", "ur5", urdf, program, "-o", out, "--degrees", "--task", "position"
    )
    assert code == 0, err
    cal = pincal.load_calibration(urdf)
    compensated = np.deg2rad(read_table(out, nominal.joint_names, "joints"))
    turns = []
    for q0, qc in zip(q, compensated):
        wanted, reached = nominal.frame_placement(q0) * cal.tool, cal.tool_pose(qc)
        assert np.linalg.norm(reached.translation - wanted.translation) < 1e-6
        turns.append(np.linalg.norm(pin.log3(wanted.rotation.T @ reached.rotation)))
    assert max(turns) > 1e-4  # the calibration turned the tool, and the position task let it turn
    assert f"the orientation is not kept: it turned by up to {max(turns) * 1e3:.3f} mrad" in text


def test_compensate_exits_2_when_no_row_can_be(
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    calibration: tuple[Path, pincal.simulation.truth.TrueRobot],
) -> None:
    urdf, _ = calibration
    nominal = pincal.load_robot("ur5")
    q = np.full((3, nominal.n_joints), 9.0)
    program = _write_joints(tmp_path / "program.csv", nominal.joint_names, q)
    out = tmp_path / "compensated.csv"
    code, _, err = _run(capsys, "compensate", "ur5", urdf, program, "-o", out)
    assert code == 2 and len(err.splitlines()) == 1 and "row 1" in err
    assert not out.exists()


def test_compensate_refuses_to_overwrite_its_inputs(
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    calibration: tuple[Path, pincal.simulation.truth.TrueRobot],
) -> None:
    urdf, _ = calibration
    nominal = pincal.load_robot("ur5")
    program = _write_joints(tmp_path / "program.csv", nominal.joint_names, np.zeros((2, 6)))
    before = {p: p.read_bytes() for p in (urdf, program)}
    for target in (urdf, program):
        code, _, err = _run(capsys, "compensate", "ur5", urdf, program, "-o", target, "--force")
        assert code == 2 and "write the output to another file" in err
    assert {p: p.read_bytes() for p in before} == before
