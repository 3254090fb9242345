"""A calibration that cannot be right says so (issue 17): :mod:`pincal.plausibility.judge` on the
silent wrong answers of a hostile battery, each built from simulated data
(:func:`pincal.random_truth` measured, written as CSV, run through :func:`pincal.cli.main`):

- each case ends in exit 2 with one ``pincal: error:`` line naming the real cause and its fix,
  and the fix it names gives a plausible calibration;
- ``--accept-implausible`` keeps the result with a warning, and the report says why;
- a correct calibration of a robot with large errors (5 mm / 5 mrad placements, a 1 m tool) is
  not refused, whatever the model;
- ``pincal tcp`` on angles given in radians or quaternions in x,y,z,w order is refused by name.

Fits use ``--params all --nested no`` where the choice of parameters is not the point: the
verdict judges whatever fit it is given, and the suite stays fast.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import pincal
from pincal.cli import main
from pincal.tool.tcp import euler_zyx

FAST = ("--params", "all", "--nested", "no")


@dataclass(frozen=True)
class Run:
    code: int
    out: str
    err: str


RunCli = Callable[..., Run]


@pytest.fixture
def run(capsys: pytest.CaptureFixture[str]) -> RunCli:
    """``run(*args)``: ``pincal ARGS`` in-process, with its exit code and output."""

    def go(*args: str | Path) -> Run:
        capsys.readouterr()
        code = main([str(a) for a in args])
        captured = capsys.readouterr()
        return Run(code, captured.out, captured.err)

    return go


def refused(result: Run, *words: str) -> str:
    """The single error line of a refused run, holding every one of ``words``."""
    assert result.code == 2, (result.code, result.out, result.err)
    assert "Traceback" not in result.err
    lines = result.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("pincal: error: "), result.err
    for word in words:
        assert word in lines[0], (word, lines[0])
    return lines[0]


@pytest.fixture(scope="module")
def ur5() -> pincal.Robot:
    return pincal.load_robot("ur5")


@pytest.fixture(scope="module")
def truth(ur5: pincal.Robot) -> pincal.simulation.truth.TrueRobot:
    return pincal.random_truth(ur5, seed=1)


@pytest.fixture(scope="module")
def poses(ur5: pincal.Robot) -> np.ndarray:
    return ur5.random_configurations(30, np.random.default_rng(5), 0.05)


def write(folder: Path, name: str, data: pincal.Dataset) -> Path:
    path = folder / name
    pincal.write_csv(path, data)
    return path


# ---------------------------------------------------------------- each silent wrong answer, named


def test_degrees_read_as_radians(
    run: RunCli, ur5: pincal.Robot, truth: pincal.simulation.truth.TrueRobot, tmp_path: Path
) -> None:
    """Small joint motions written in degrees, read as radians (within the URDF limits and the
    points' spread check): refused with "pass --degrees"; read as degrees, plausible."""
    rng = np.random.default_rng(3)
    q = rng.uniform(-1, 1, (30, 6)) * np.array([0.108, 0.108, 0.054, 0.108, 0.108, 0.108])
    data = truth.measure(q, 3e-5, seed=3)
    path = write(tmp_path, "deg.csv", replace(data, q=np.rad2deg(q)))
    refused(run("calibrate", "ur5", path, *FAST), "degrees read as radians", "pass --degrees")
    cal = pincal.calibrate(ur5, data)  # what --degrees reads
    assert pincal.judge_calibration(cal, data, degrees=True).plausible


def test_larger_degree_motions_named_before_the_fit(
    run: RunCli, get_robot: Callable[[str], pincal.Robot], tmp_path: Path
) -> None:
    """When the points' spread is far below the tip's, the units check says degrees, not units."""
    panda = get_robot("panda")
    q = np.random.default_rng(0).uniform(panda.lower, panda.upper, (30, 7)) * np.pi / 180 * 0.9
    data = pincal.random_truth(panda, seed=0).measure(q, 3e-5)
    path = write(tmp_path, "deg.csv", replace(data, q=np.rad2deg(q)))
    refused(run("calibrate", "panda", path, *FAST), "degrees read as radians: pass --degrees")


def test_x_and_y_swapped(
    run: RunCli, truth: pincal.simulation.truth.TrueRobot, poses: np.ndarray, tmp_path: Path
) -> None:
    """A mirror no registration undoes: refused with "x and y look swapped"."""
    data = truth.measure(poses, 3e-5, seed=2)
    swapped = replace(data, points=data.points[:, [1, 0, 2]])
    refused(run("calibrate", "ur5", write(tmp_path, "xy.csv", swapped), *FAST), "x and y look swapped")


def test_quaternion_in_xyzw_order(
    run: RunCli, truth: pincal.simulation.truth.TrueRobot, poses: np.ndarray, tmp_path: Path
) -> None:
    """x,y,z,w quaternions under qw,qx,qy,qz: refused by name; ``--quaternion-order xyzw`` reads
    them right and the calibration is plausible (and fits to the noise)."""
    data = truth.measure(poses, 3e-5, rot_noise=1e-4, seed=4)
    xyzw = replace(data, quaternions=data.quaternions[:, [1, 2, 3, 0]])
    path = write(tmp_path, "xyzw.csv", xyzw)
    refused(run("calibrate", "ur5", path, *FAST), "quaternion looks like x,y,z,w", "--quaternion-order xyzw")
    report = tmp_path / "r.json"
    ok = run("calibrate", "ur5", path, *FAST, "--quaternion-order", "xyzw", "--report", report)
    assert ok.code == 0, ok.err
    found = json.loads(report.read_text())
    assert found["plausibility"]["plausible"]
    assert found["train"]["after"]["rot_rms_mrad"] < 1.0


def test_noise_as_large_as_the_robot(
    run: RunCli, truth: pincal.simulation.truth.TrueRobot, poses: np.ndarray, tmp_path: Path
) -> None:
    """1 m of noise on a 1.3 m arm: refused, naming the scatter (noise)."""
    path = write(tmp_path, "noise.csv", truth.measure(poses, 1.0, seed=5))
    refused(run("calibrate", "ur5", path, *FAST), "scatter", "noise")


@pytest.mark.parametrize("size", [0.005, 0.05])
def test_thirty_percent_outliers(
    run: RunCli, truth: pincal.simulation.truth.TrueRobot, poses: np.ndarray, tmp_path: Path, size: float
) -> None:
    """A third of the poses off by millimetres or centimetres: more than the screen leaves out,
    refused as outliers; a robust loss fits the rest and is not refused."""
    data = truth.measure(poses, 3e-5, seed=2)
    rng = np.random.default_rng(7)
    bad = rng.choice(len(data), 9, replace=False)
    points = data.points.copy()
    points[bad] += rng.normal(0.0, size, (9, 3))
    path = write(tmp_path, "out.csv", replace(data, points=points))
    refused(run("calibrate", "ur5", path, *FAST), "outliers", "--loss soft_l1")
    assert run("calibrate", "ur5", path, *FAST, "--loss", "soft_l1").code == 0


def test_instrument_frame_base_for_data_in_another_frame(
    run: RunCli, truth: pincal.simulation.truth.TrueRobot, poses: np.ndarray, tmp_path: Path
) -> None:
    """The tracker's frame claimed to be the base (a 3 m correction follows): refused with
    "drop --instrument-frame base"; without it, plausible."""
    path = write(tmp_path, "tracker.csv", truth.measure(poses, 3e-5, seed=2))
    refused(
        run("calibrate", "ur5", path, *FAST, "--instrument-frame", "base"),
        "not in the base frame: drop --instrument-frame base",
    )
    assert run("calibrate", "ur5", path, *FAST).code == 0


def test_lock_of_a_moving_joint(
    run: RunCli, truth: pincal.simulation.truth.TrueRobot, poses: np.ndarray, tmp_path: Path
) -> None:
    """``--lock`` of a joint whose column is there and moves: refused before any fit."""
    path = write(tmp_path, "all.csv", truth.measure(poses, 3e-5, seed=2))
    refused(run("calibrate", "ur5", path, *FAST, "--lock", "wrist_3_joint"), "--lock wrist_3_joint", "moves")


@pytest.mark.parametrize("keep", [("qw", "qx", "qy"), ("qx",)])
def test_partial_quaternion(
    run: RunCli,
    truth: pincal.simulation.truth.TrueRobot,
    poses: np.ndarray,
    tmp_path: Path,
    keep: tuple[str, ...],
) -> None:
    """Some but not all of qw,qx,qy,qz: an error naming the missing ones, never position data."""
    full = write(tmp_path, "pose.csv", truth.measure(poses, 3e-5, rot_noise=1e-4, seed=4))
    lines = [line.split(",") for line in full.read_text().splitlines()]
    drop = [k for k, name in enumerate(lines[0]) if name.startswith("q") and name not in keep]
    path = tmp_path / "partial.csv"
    path.write_text("\n".join(",".join(c for k, c in enumerate(r) if k not in drop) for r in lines) + "\n")
    missing = [c for c in ("qw", "qx", "qy", "qz") if c not in keep]
    refused(run("calibrate", "ur5", path, *FAST), "quaternion", *missing)


def test_accept_implausible_keeps_it_with_a_warning(
    run: RunCli, truth: pincal.simulation.truth.TrueRobot, poses: np.ndarray, tmp_path: Path
) -> None:
    """``--accept-implausible``: exit 0, one warning naming the cause, the report's verdict says
    why, and the contract's keys are all there."""
    data = truth.measure(poses, 3e-5, seed=2)
    path = write(tmp_path, "xy.csv", replace(data, points=data.points[:, [1, 0, 2]]))
    report = tmp_path / "r.json"
    result = run("calibrate", "ur5", path, *FAST, "--accept-implausible", "--report", report)
    assert result.code == 0
    assert [line for line in result.err.splitlines() if "warning" in line and "x and y look swapped" in line]
    found = json.loads(report.read_text())
    assert {"robot", "tip", "model", "measure", "n_poses", "train", "test", "parameters"} <= set(found)
    verdict = found["plausibility"]
    assert not verdict["plausible"] and verdict["cause"] == "swapped_xy"
    assert any(not c["passed"] and c["value"] > c["limit"] for c in verdict["checks"])


def test_the_library_gives_the_command_s_verdict(
    run: RunCli, truth: pincal.simulation.truth.TrueRobot, poses: np.ndarray, tmp_path: Path
) -> None:
    """``pincal.calibrate`` judges its own result as the command does: the same verdict in the
    calibration and its report, and the writers refuse what the command refuses, unless
    ``accept_implausible=True``; a plausible fit is written as it is."""
    ur5 = truth.robot
    data = truth.measure(poses, 3e-5, seed=2)
    swapped = replace(data, points=data.points[:, [1, 0, 2]])
    refused(run("calibrate", "ur5", write(tmp_path, "xy.csv", swapped), *FAST), "x and y look swapped")
    cal = pincal.calibrate(ur5, swapped, params="all", nested=False)
    assert cal.plausibility is not None and not cal.plausibility.plausible
    assert "x and y look swapped" in (cal.plausibility.hint or "")
    assert pincal.report_dict(cal, swapped)["plausibility"]["cause"] == "swapped_xy"
    assert "cannot be right: x and y look swapped" in pincal.summary(cal, swapped)
    with pytest.raises(pincal.ImplausibleError, match="accept_implausible=True"):
        pincal.write_corrected_urdf(cal, tmp_path / "wrong.urdf")
    assert not (tmp_path / "wrong.urdf").exists()
    urdf, _ = pincal.write_corrected_urdf(cal, tmp_path / "kept.urdf", accept_implausible=True)
    assert urdf.exists()
    good = pincal.calibrate(ur5, data, params="all", nested=False)
    assert good.plausibility is not None and good.plausibility.plausible
    assert pincal.write_corrected_urdf(good, tmp_path / "good.urdf")[0].exists()


# ---------------------------------------------------------------- never a false refusal


@pytest.mark.parametrize(
    ("name", "model", "rot_noise"),
    [("ur5", "placements", None), ("ur5", "mdh", 2e-4), ("panda", "poe", None), ("zu3", "offsets", None)],
)
def test_large_real_errors_are_not_refused(
    get_robot: Callable[[str], pincal.Robot], name: str, model: str, rot_noise: float | None
) -> None:
    """A robot with large errors (5 mm and 5 mrad on every joint origin, 5 mrad offsets), a 1 m
    tool and 0.1 mm noise, fitted correctly: every check passes, with room to spare on the
    checks the wrong readings fail."""
    robot = get_robot(name)
    big = pincal.random_truth(robot, seed=2, translation_std=5e-3, rotation_std=5e-3, offset_std=5e-3)
    big = replace(big, tool=pin.SE3(big.tool.rotation, np.array([0.6, 0.0, 0.8])))
    q = robot.random_configurations(40, np.random.default_rng(2), 0.05)
    data = big.measure(q, 1e-4, rot_noise, seed=3)
    verdict = pincal.judge_calibration(pincal.calibrate(robot, data, model), data)
    assert verdict.plausible, verdict.hint
    margins = {c.name: c.margin for c in verdict.checks}
    assert min(margins[k] for k in ("before", "correction", "tool")) > 1.5, margins
    assert margins["outliers"] > 1.0 and margins["gain"] > 1.0


def test_verdict_in_the_report_of_a_plausible_fit(
    run: RunCli, truth: pincal.simulation.truth.TrueRobot, poses: np.ndarray, tmp_path: Path
) -> None:
    """A clean fit's report holds the verdict: every check passed, each with its margin (null:
    infinite, a value of 0)."""
    path = write(tmp_path, "ok.csv", truth.measure(poses, 3e-5, seed=2))
    report = tmp_path / "r.json"
    assert run("calibrate", "ur5", path, *FAST, "--report", report).code == 0
    verdict = json.loads(report.read_text())["plausibility"]
    assert verdict["plausible"] and verdict["cause"] is None
    assert all(c["passed"] and (c["margin"] is None or c["margin"] >= 1.0) for c in verdict["checks"])


# ---------------------------------------------------------------- pincal tcp


@pytest.fixture(scope="module")
def flange() -> tuple[np.ndarray, np.ndarray]:
    """Eight flange poses [mm] touching one point with a 0.3 m tool, rotations within ±30 degrees
    of pointing down, 0.05 mm teaching noise."""
    rng = np.random.default_rng(0)
    tcp = np.array([60.0, -20.0, 300.0])
    down = pin.exp3(np.array([np.pi, 0.0, 0.0]))
    rotations = np.array([down @ pin.exp3(rng.uniform(-0.5, 0.5, 3)) for _ in range(8)])
    positions = np.array([800.0, 100.0, 300.0]) - rotations @ tcp + rng.normal(0.0, 0.05, (8, 3))
    return rotations, positions


def _zyx_degrees(rotations: np.ndarray) -> np.ndarray:
    """a, b, c [deg] with R = Rz(a) Ry(b) Rx(c)."""
    a = np.arctan2(rotations[:, 1, 0], rotations[:, 0, 0])
    b = -np.arcsin(np.clip(rotations[:, 2, 0], -1, 1))
    c = np.arctan2(rotations[:, 2, 1], rotations[:, 2, 2])
    return np.rad2deg(np.stack([a, b, c], axis=1))


def _table(path: Path, header: str, rows: np.ndarray) -> Path:
    path.write_text(header + "\n" + "\n".join(",".join(repr(float(v)) for v in r) for r in rows) + "\n")
    return path


def test_tcp_verdict(run: RunCli, flange: tuple[np.ndarray, np.ndarray], tmp_path: Path) -> None:
    """Good poses pass (the JSON holds the verdict); angles written in radians and quaternions
    in x,y,z,w order are refused by name, and ``--quaternion-order xyzw`` reads them right."""
    rotations, positions = flange
    abc = _zyx_degrees(rotations)
    assert np.allclose(euler_zyx(*np.deg2rad(abc).T), rotations)
    good = _table(tmp_path / "good.csv", "x,y,z,a,b,c", np.hstack([positions, abc]))
    out = tmp_path / "tcp.json"
    assert run("tcp", good, "--units", "mm", "--json", out).code == 0
    assert json.loads(out.read_text())["plausibility"]["plausible"]
    radians = _table(tmp_path / "rad.csv", "x,y,z,a,b,c", np.hstack([positions, np.deg2rad(abc)]))
    refused(run("tcp", radians, "--units", "mm"), "TCP cannot be right", "radians", "convert them to degrees")
    xyzw = np.array([pin.Quaternion(r).coeffs() for r in rotations])  # x, y, z, w
    quats = _table(tmp_path / "q.csv", "x,y,z,qw,qx,qy,qz", np.hstack([positions, xyzw]))
    refused(run("tcp", quats, "--units", "mm"), "--quaternion-order xyzw")
    right = run("tcp", quats, "--units", "mm", "--quaternion-order", "xyzw", "--json", out, "--force")
    assert right.code == 0, right.err
    assert np.allclose(json.loads(out.read_text())["tcp"], [60.0, -20.0, 300.0], atol=0.3)
