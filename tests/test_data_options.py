"""``tcp`` and ``compensate`` take ``calibrate``'s data options where they apply
(:mod:`pincal.cli.data_options`): ``tcp --robot R --lock J`` and ``compensate
--quaternion-order``; they refuse the ones that do not apply, in one line, exit 2."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import pincal
from pincal.cli import main
from pincal.data.program import Targets, read_program


def _write(path: Path, header: list[str], rows: np.ndarray) -> Path:
    path.write_text(
        ",".join(header) + "\n" + "\n".join(",".join(repr(float(v)) for v in r) for r in rows) + "\n"
    )
    return path


def _targets(robot: pincal.Robot, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Tip positions (n, 3) [m] and quaternions (n, 4) as x, y, z, w of random configurations."""
    q = robot.random_configurations(n, np.random.default_rng(seed), 0.2)
    poses = [robot.frame_placement(qi) for qi in q]
    return np.array([p.translation for p in poses]), np.array(
        [pin.Quaternion(p.rotation).coeffs() for p in poses]
    )


def test_program_quaternions_in_either_order_read_alike(tmp_path: Path) -> None:
    """The same targets written w,x,y,z and x,y,z,w under the header qw,qx,qy,qz: read with the
    matching order, the rotations agree to round-off; read with the wrong one, they do not."""
    robot = pincal.load_robot("ur5")
    xyz, xyzw = _targets(robot, 4, 1)
    header = ["x", "y", "z", "qw", "qx", "qy", "qz"]
    wxyz_file = _write(tmp_path / "wxyz.csv", header, np.hstack([xyz, xyzw[:, [3, 0, 1, 2]]]))
    xyzw_file = _write(tmp_path / "xyzw.csv", header, np.hstack([xyz, xyzw]))
    plain = read_program(wxyz_file, robot)
    other = read_program(xyzw_file, robot, quaternion_order="xyzw")
    wrong = read_program(xyzw_file, robot)
    assert isinstance(plain, Targets) and isinstance(other, Targets) and isinstance(wrong, Targets)
    assert plain.rotations is not None and other.rotations is not None and wrong.rotations is not None
    np.testing.assert_allclose(other.rotations, plain.rotations, atol=1e-12)
    assert np.abs(wrong.rotations - plain.rotations).max() > 0.1


def test_compensate_takes_the_quaternion_order(tmp_path: Path) -> None:
    """``compensate --quaternion-order xyzw`` on the x,y,z,w file writes what the w,x,y,z file
    gives without it."""
    robot = pincal.load_robot("ur5")
    _, fit, _ = pincal.simulate(robot, 40, 1, seed=4)
    urdf = pincal.write_corrected_urdf(pincal.calibrate(robot, fit, "placements"), tmp_path / "cal.urdf")[0]
    xyz, xyzw = _targets(robot, 3, 2)
    header = ["x", "y", "z", "qw", "qx", "qy", "qz"]
    wxyz_file = _write(tmp_path / "wxyz.csv", header, np.hstack([xyz, xyzw[:, [3, 0, 1, 2]]]))
    xyzw_file = _write(tmp_path / "xyzw.csv", header, np.hstack([xyz, xyzw]))
    out_a, out_b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main(["compensate", "ur5", str(urdf), str(wxyz_file), "-o", str(out_a)]) == 0
    args = ["compensate", "ur5", str(urdf), str(xyzw_file), "-o", str(out_b), "--quaternion-order", "xyzw"]
    assert main(args) == 0
    assert out_a.read_text() == out_b.read_text()


def _tcp(capsys: pytest.CaptureFixture[str], tmp_path: Path, csv: Path, *extra: str) -> dict[str, object]:
    out = tmp_path / f"{csv.stem}.json"
    assert main(["tcp", str(csv), "--robot", "ur5", "--accept-implausible", "--json", str(out), *extra]) == 0
    capsys.readouterr()
    return dict(json.loads(out.read_text()))


def test_tcp_locks_a_joint_as_calibrate_does(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """``tcp --robot ur5 --lock wrist_3_joint`` on rows without that column gives the TCP of the
    same rows with the column at 0 (the joint's neutral value)."""
    robot = pincal.load_robot("ur5")
    q = robot.random_configurations(6, np.random.default_rng(3), 0.1)
    q[:, -1] = 0.0
    names = list(robot.joint_names)
    full = _tcp(capsys, tmp_path, _write(tmp_path / "full.csv", names, q))
    locked = _tcp(
        capsys, tmp_path, _write(tmp_path / "locked.csv", names[:-1], q[:, :-1]), "--lock", names[-1]
    )
    # the same poses through two reduced models: equal to rounding (1e-12 of a tool's length)
    assert np.allclose(locked["tcp"], full["tcp"], rtol=0, atol=1e-12)
    assert abs(locked["fit_error"] - full["fit_error"]) <= 1e-12


@pytest.mark.parametrize(
    "args",
    [
        ["tcp", "poses.csv", "--lock", "wrist_3_joint"],  # no --robot: no joint columns to lock
        ["tcp", "poses.csv", "--measure", "points"],
        ["tcp", "poses.csv", "--point-distance", "0,1=50"],
        ["compensate", "ur5", "cal.urdf", "program.csv", "-o", "out.csv", "--model", "poe"],
        ["compensate", "ur5", "cal.urdf", "program.csv", "-o", "out.csv", "--point-distance", "0,1=50"],
    ],
)
def test_options_that_do_not_apply_are_refused(
    args: list[str], capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """One ``pincal: error:`` line naming the option, exit 2, nothing written."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "poses.csv").write_text("x,y,z,a,b,c\n" + "0,0,0,0,0,0\n" * 4)
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("pincal: error:") and args[-2].split("=")[0] in err[0]
    assert not (tmp_path / "out.csv").exists()
