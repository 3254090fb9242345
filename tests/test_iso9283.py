"""ISO 9283 pose accuracy and repeatability (issue 34): ``pincal accuracy`` against an independent
computation written here in plain NumPy, on simulated repeated visits (10 and 30 cycles); a
calibration from separate data lowers AP and leaves RP as it is."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from cli_run import one_error_line, run

from pincal.data.csv_writer import write_csv
from pincal.simulation.simulated_recording import write_recording
from pincal.simulation.truth import TrueRobot, random_truth

#: The robot's own scatter between visits: joint angles [rad] and the tracker's noise [m].
JOINT_SCATTER, NOISE = 2e-5, 1e-5


def visits(
    truth: TrueRobot, poses: np.ndarray, cycles: int, seed: int
) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
    """Labels, commanded joints, attained positions [m] and rotations of ``cycles`` rounds of the poses."""
    rng = np.random.default_rng(seed)
    labels = [f"P{k + 1}" for _ in range(cycles) for k in range(len(poses))]
    q = np.tile(poses, (cycles, 1))
    reached = q + rng.normal(0.0, JOINT_SCATTER, q.shape)
    positions, rotations = truth.target(reached)
    return labels, q, positions + rng.normal(0.0, NOISE, positions.shape), rotations


def write_visits(
    path: Path,
    names: tuple[str, ...],
    labels: list[str],
    q: np.ndarray,
    points: np.ndarray,
    extra: dict[str, np.ndarray],
) -> None:
    """A visits CSV: pose, joints [rad], x,y,z [mm], and the ``extra`` columns as given."""
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(["pose", *names, "x", "y", "z", *extra])
        for i, label in enumerate(labels):
            writer.writerow([label, *q[i], *(points[i] * 1e3), *(col[i] for col in extra.values())])


def reference(labels: list[str], commanded: np.ndarray, attained: np.ndarray) -> dict[str, dict[str, float]]:
    """ISO 9283's AP, its components and RP per pose [mm], computed from the definitions."""
    out = {}
    for name in dict.fromkeys(labels):
        rows = [i for i, label in enumerate(labels) if label == name]
        barycentre = attained[rows].mean(axis=0)
        deviation = (barycentre - commanded[rows[0]]) * 1e3
        distances = np.sqrt(((attained[rows] - barycentre) ** 2).sum(axis=1)) * 1e3
        spread = np.sqrt(((distances - distances.mean()) ** 2).sum() / (len(rows) - 1))
        out[name] = {
            "AP_mm": float(np.sqrt((deviation**2).sum())),
            "APx_mm": deviation[0],
            "APy_mm": deviation[1],
            "APz_mm": deviation[2],
            "RP_mm": float(distances.mean() + 3 * spread),
        }
    return out


def angles_abc(rotation: np.ndarray) -> np.ndarray:
    """a, b, c [rad] of R = Rz(c) Ry(b) Rx(a), from the matrix's entries."""
    return np.array(
        [
            np.arctan2(rotation[2, 1], rotation[2, 2]),
            -np.arcsin(rotation[2, 0]),
            np.arctan2(rotation[1, 0], rotation[0, 0]),
        ]
    )


@pytest.fixture(scope="module")
def setting(get_robot):  # type: ignore[no-untyped-def]
    """UR5 with geometric errors, measured in its base frame; five poses in the workspace."""
    robot = get_robot("ur5")
    truth = random_truth(robot, seed=4, instrument=False)
    poses = robot.random_configurations(5, np.random.default_rng(11), 0.1)
    return robot, truth, poses


def _tool_point_mm(truth: TrueRobot) -> str:
    return ",".join(f"{v:.12g}" for v in truth.tool.translation * 1e3)


@pytest.mark.parametrize("cycles", [10, 30])
def test_figures_match_an_independent_computation(setting, cycles: int, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    """AP, APx..APz and RP of every pose within 1 % of the definitions; with fewer than 30 cycles
    the figures come with a warning that they are not ISO-conformant."""
    robot, truth, poses = setting
    labels, q, attained, _ = visits(truth, poses, cycles, seed=cycles)
    data, report = tmp_path / "visits.csv", tmp_path / "iso.json"
    write_visits(data, robot.joint_names, labels, q, attained, {})
    tool = _tool_point_mm(truth)
    code, out, err = run(
        capsys, "accuracy", "ur5", data, "--units", "mm", "--tool-point", tool, "--report", report
    )
    assert code == 0, err
    iso = json.loads(report.read_text())["iso9283"]
    assert iso["command"] == "nominal_model"
    commanded = np.array(
        [(robot.frame_placement(row) * pin.SE3(np.eye(3), truth.tool.translation)).translation for row in q]
    )
    expected = reference(labels, commanded, attained)
    assert [p["pose"] for p in iso["poses"]] == list(expected)
    for pose in iso["poses"]:
        assert pose["n"] == cycles
        for key, value in expected[pose["pose"]].items():
            assert abs(pose[key] - value) <= 0.01 * abs(value) + 1e-9, (pose["pose"], key, pose[key], value)
    assert iso["AP_mm_max"] == max(p["AP_mm"] for p in iso["poses"])
    assert iso["RP_mm_max"] == max(p["RP_mm"] for p in iso["poses"])
    assert ("not ISO-conformant" in err) == (cycles < 30)
    assert "P5" in out and "RP" in out  # the table


def test_orientation_figures(setting, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    """APa..APc are the mean and RPa..RPc three sample standard deviations of the attained
    orientation's angles about the base axes, relative to the commanded one."""
    robot, truth, poses = setting
    labels, q, attained, rotations = visits(truth, poses, 10, seed=3)
    quats = np.array([[*(lambda qt: (qt.w, qt.x, qt.y, qt.z))(pin.Quaternion(r))] for r in rotations])
    data, report = tmp_path / "posed.csv", tmp_path / "iso.json"
    write_visits(data, robot.joint_names, labels, q, attained, dict(zip(("qw", "qx", "qy", "qz"), quats.T)))
    code, _, err = run(capsys, "accuracy", "ur5", data, "--units", "mm", "--report", report)
    assert code == 0, err
    iso = json.loads(report.read_text())["iso9283"]
    assert "Rz(c) Ry(b) Rx(a)" in iso["angle_convention"]
    for pose in iso["poses"]:
        rows = [i for i, label in enumerate(labels) if label == pose["pose"]]
        command = robot.frame_placement(q[rows[0]]).rotation
        abc = np.rad2deg([angles_abc(rotations[i] @ command.T) for i in rows])
        for k, axis in enumerate("abc"):
            assert abs(pose[f"AP{axis}_deg"] - abc[:, k].mean()) <= 1e-6
            assert abs(pose[f"RP{axis}_deg"] - 3 * abc[:, k].std(ddof=1)) <= 0.01 * 3 * abc[:, k].std(ddof=1)


def test_programmed_positions(setting, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    robot, truth, poses = setting
    labels, q, attained, _ = visits(truth, poses, 3, seed=5)
    programmed = truth.target(q)[0] + 2e-4  # 0.2 mm off on each axis: AP = 0.2 sqrt(3) mm, less the scatter
    data, report = tmp_path / "prog.csv", tmp_path / "iso.json"
    columns = {f"{a}_cmd": programmed[:, k] * 1e3 for k, a in enumerate("xyz")}
    write_visits(data, robot.joint_names, labels, q, attained, columns)
    plot = tmp_path / "iso.png"
    code, _, err = run(capsys, "accuracy", "ur5", data, "--units", "mm", "--report", report, "--plot", plot)
    assert code == 0, err
    assert plot.read_bytes().startswith(b"\x89PNG")
    iso = json.loads(report.read_text())["iso9283"]
    assert iso["command"] == "programmed"
    expected = reference(labels, programmed, attained)
    for pose in iso["poses"]:
        assert abs(pose["AP_mm"] - expected[pose["pose"]]["AP_mm"]) <= 1e-9


def test_calibration_lowers_ap_and_keeps_rp(setting, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    """A calibration from 60 separate poses: AP falls 5 times or more on every pose, RP stays."""
    robot, truth, poses = setting
    fit = truth.measure(robot.random_configurations(60, np.random.default_rng(21), 0.05), 3e-5, seed=22)
    write_csv(tmp_path / "fit.csv", fit)
    code, _, err = run(capsys, "calibrate", "ur5", tmp_path / "fit.csv", "-o", tmp_path / "cal.urdf")
    assert code == 0, err
    labels, q, attained, _ = visits(truth, poses, 30, seed=7)
    write_visits(tmp_path / "visits.csv", robot.joint_names, labels, q, attained, {})
    figures = {}
    for name, extra in (
        ("nominal", ["--tool-point", _tool_point_mm(truth)]),
        ("calibrated", ["--calibration", tmp_path / "cal.calibration.json"]),
    ):
        report = tmp_path / f"{name}.json"
        code, _, err = run(
            capsys, "accuracy", "ur5", tmp_path / "visits.csv", "--units", "mm", *extra, "--report", report
        )
        assert code == 0, err
        figures[name] = json.loads(report.read_text())["iso9283"]
    assert figures["calibrated"]["command"] == "calibrated_model"
    for nominal, calibrated in zip(figures["nominal"]["poses"], figures["calibrated"]["poses"]):
        assert nominal["AP_mm"] >= 5 * calibrated["AP_mm"], (nominal, calibrated)
        assert abs(nominal["RP_mm"] - calibrated["RP_mm"]) <= 1e-3 * nominal["RP_mm"]


def test_a_pose_visited_once_is_refused(setting, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    robot, truth, poses = setting
    labels, q, attained, _ = visits(truth, poses, 2, seed=1)
    labels[-1] = "P6"  # the last row alone
    write_visits(tmp_path / "once.csv", robot.joint_names, labels, q, attained, {})
    report = tmp_path / "iso.json"
    line = one_error_line(
        capsys, "accuracy", "ur5", tmp_path / "once.csv", "--units", "mm", "--report", report
    )
    assert "P6" in line and "2 visits" in line
    assert not report.exists()


def test_recording_of_repeated_visits(setting, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    """A recording's static poses are grouped into the poses visited; its AP is the truth's."""
    robot, truth, poses = setting
    path = tmp_path / "cycles"
    write_recording(path, truth, np.tile(poses, (3, 1)), "mcap", seed=4)
    report = tmp_path / "iso.json"
    code, _, err = run(
        capsys,
        "accuracy",
        "ur5",
        path,
        "--tool-point",
        ",".join(f"{v:.12g}" for v in truth.tool.translation),
        "--report",
        report,
    )
    assert code == 0, err
    iso = json.loads(report.read_text())["iso9283"]
    assert [(p["pose"], p["n"]) for p in iso["poses"]] == [(f"P{k + 1}", 3) for k in range(5)]
    nominal = np.array(
        [
            (robot.frame_placement(row) * pin.SE3(np.eye(3), truth.tool.translation)).translation
            for row in poses
        ]
    )
    true_ap = np.linalg.norm(truth.target(poses)[0] - nominal, axis=1) * 1e3
    np.testing.assert_allclose([p["AP_mm"] for p in iso["poses"]], true_ap, atol=0.01)
