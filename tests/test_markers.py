"""Several markers per pose (issue 41): ``xK,yK,zK`` columns, one model for every marker.

- A CSV of markers with empty cells reads as one row per marker seen, the pose's row number kept;
  holding out poses keeps a pose's markers together.
- The residual Jacobian of several markers (position and distance) matches finite differences.
- Three markers on a UR5 tool, simulated without pincal's model code (60 poses, 0.03 mm noise,
  5 % of rows with one marker hidden): every marker's held-out RMS is within 1.3 × the noise floor
  (√3 × 0.03 mm), and the files, read by the contract alone, reproduce the report's ``after`` and
  ``exported`` (overall and per marker) to 1e-6 mm.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from cli_run import run
from contract_markers import rms_mm
from finite_differences import residual_jacobian_fd
from marker_simulation import simulate, write

import pincal
from pincal.data.csv_writer import write_csv
from pincal.data.dataset import read_csv
from pincal.identify.measurement import Measurement
from pincal.identify.measurements import Problem
from pincal.kinematics.mdh import make_model
from pincal.robot.robots import bundled_urdf

NOISE_M = 3e-5
FLOOR_MM = np.sqrt(3) * NOISE_M * 1e3
UR5_MARKERS = {
    "1": ("tool0", (0.05, 0.0, 0.1)),
    "2": ("tool0", (-0.05, 0.03, 0.08)),
    "A": ("tool0", (0.0, -0.06, 0.12)),
}


def test_marker_csv_reads_one_row_per_marker_seen(tmp_path: Path) -> None:
    names, q, points = simulate(bundled_urdf("ur5"), UR5_MARKERS, 20, hidden=0.2, seed=1)
    path = tmp_path / "m.csv"
    write(path, names, q, list(UR5_MARKERS), points)
    data = read_csv(path, names)
    seen = ~np.isnan(points[:, :, 0])
    assert data.marker_names == ("1", "2", "A")
    assert len(data) == seen.sum() == 20 * 3 - 4 and data.n_poses == 20
    np.testing.assert_array_equal(data.points, points[seen])
    fit, held = data.split(0.25, seed=3)
    assert not set(fit.row_numbers) & set(held.row_numbers) and held.n_poses == 5
    write_csv(tmp_path / "again.csv", data)
    again = read_csv(tmp_path / "again.csv", names)
    np.testing.assert_allclose(again.points, data.points, atol=1e-15)
    np.testing.assert_array_equal(again.row_numbers, data.row_numbers)


def test_a_marker_with_some_cells_empty_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    names, q, points = simulate(bundled_urdf("ur5"), UR5_MARKERS, 12, seed=2)
    path = tmp_path / "m.csv"
    write(path, names, q, list(UR5_MARKERS), points)
    lines = path.read_text().splitlines()
    cells = lines[3].split(",")
    cells[-2] = ""
    lines[3] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    code, _, err = run(capsys, "calibrate", "ur5", path)
    assert code == 2 and "marker A has some but not all" in err


@pytest.mark.parametrize("measure", ["position", "distance"])
def test_marker_jacobian_matches_finite_differences(get_robot, measure: str) -> None:
    robot = get_robot("ur5")
    rng = np.random.default_rng(4)
    data, meas = _two_markers(robot, measure, 5, ("a", "b"), rng)
    problem = Problem(make_model("placements", robot), meas, data)
    theta = problem.initial_theta() + rng.normal(0, 0.01, problem.n_params)
    jac = problem.jacobian(theta)
    assert np.abs(jac - residual_jacobian_fd(problem, theta)).max() <= 1e-6 * np.abs(jac).max()
    assert problem.names[-6:] == (
        "marker.a.x",
        "marker.a.y",
        "marker.a.z",
        "marker.b.x",
        "marker.b.y",
        "marker.b.z",
    )


def test_three_markers_on_a_ur5_tool(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    names, q, points = simulate(bundled_urdf("ur5"), UR5_MARKERS, 120, NOISE_M, 0.05, seed=11)
    labels = list(UR5_MARKERS)
    write(tmp_path / "fit.csv", names, q[:60], labels, points[:60])
    write(tmp_path / "test.csv", names, q[60:], labels, points[60:])
    out, report = tmp_path / "cal.urdf", tmp_path / "report.json"
    code, printed, err = run(
        capsys,
        "calibrate",
        "ur5",
        tmp_path / "fit.csv",
        "--test",
        tmp_path / "test.csv",
        "-o",
        out,
        "--report",
        report,
    )
    assert code == 0, err
    for label in labels:
        assert f"marker {label}" in printed
    rep = json.loads(report.read_text())
    side = json.loads(out.with_name("cal.calibration.json").read_text())
    assert side["tip_T_tool"] is None and side["tip"] == "tool0" and side["extension"] is None
    assert set(side["markers"]) == set(labels) and all(
        m["frame"] == "tool0" for m in side["markers"].values()
    )
    for key, q_part, p_part in (("train", q[:60], points[:60]), ("test", q[60:], points[60:])):
        overall, each = rms_mm(out.with_name("cal.calibration.json"), q_part, labels, p_part)
        assert abs(overall - rep[key]["after"]["rms_mm"]) < 1e-6
        assert abs(overall - rep[key]["exported"]["rms_mm"]) < 1e-6
        for label in labels:
            assert abs(each[label] - rep[key]["markers"][label]["rms_mm"]) < 1e-6
    for label in labels:
        assert rep["test"]["markers"][label]["rms_mm"] < 1.3 * FLOOR_MM, (label, rep["test"]["markers"])
    assert rep["n_poses"] == 60


def test_template_writes_the_header_of_several_markers(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "template", "ur5", "--markers", "3")
    assert code == 0, err
    header = [line for line in out.splitlines() if not line.startswith("#")][-1].split(",")
    assert header[-9:] == ["x1", "y1", "z1", "x2", "y2", "z2", "x3", "y3", "z3"]


def _talos() -> str:
    import importlib.metadata

    robots = importlib.metadata.distribution("example-robot-data").locate_file(
        "cmeel.prefix/share/example-robot-data/robots"
    )
    return str(robots) + "/talos_data/robots/talos_reduced.urdf"


TALOS_MARKERS = {"1": ("arm_left_7_link", (0.0, 0.02, -0.15)), "2": ("arm_right_7_link", (0.01, 0.0, -0.15))}
TALOS_TIP = "1=arm_left_7_link,2=arm_right_7_link"


def test_tree_chain_is_the_union_of_the_branches_and_matches_pinocchio() -> None:
    robot = pincal.load_robot(_talos(), tip=TALOS_TIP)
    assert robot.is_tree and robot.tips == ("arm_left_7_link", "arm_right_7_link") and robot.n_joints == 16
    assert robot.joint_names[:2] == ("torso_1_joint", "torso_2_joint")
    q = robot.random_configurations(4, np.random.default_rng(0))
    frames = pincal.kinematics.chain.forward(pincal.kinematics.chain.Chain.nominal(robot), q)
    data = robot.model.createData()
    for i, qi in enumerate(q):
        pin.framesForwardKinematics(robot.model, data, robot.configuration(qi))
        for t, name in enumerate(robot.tips):
            placement = data.oMf[robot.model.getFrameId(name)]
            np.testing.assert_allclose(
                frames.translations[2 * robot.n_joints + t, i], placement.translation, atol=1e-12
            )
    with pytest.raises(pincal.DataError, match="serial chain"):
        make_model("poe", robot)


@pytest.mark.parametrize("measure", ["position", "distance"])
def test_tree_jacobian_matches_finite_differences(measure: str) -> None:
    robot = pincal.load_robot(_talos(), tip=TALOS_TIP)
    rng = np.random.default_rng(5)
    data, meas = _two_markers(robot, measure, 4, ("1", "2"), rng, tips=(0, 1))
    for kind in ("placements", "offsets"):
        problem = Problem(make_model(kind, robot), meas, data)
        theta = problem.initial_theta() + rng.normal(0, 0.01, problem.n_params)
        jac = problem.jacobian(theta)
        assert np.abs(jac - residual_jacobian_fd(problem, theta)).max() <= 1e-6 * np.abs(jac).max()
    left = [i for i, n in enumerate(problem.names) if n.startswith("arm_left_1_joint.")]
    if measure == "position":  # a left-arm joint moves no right-hand row
        assert np.all(jac[np.repeat(data.marker == 1, 3)][:, left] == 0.0)


def _origins(path: str | Path) -> dict[str, tuple[str | None, str | None]]:
    from lxml import etree

    root = etree.parse(str(path)).getroot()
    out = {}
    for joint in root.findall("joint"):
        origin = joint.find("origin")
        out[joint.get("name")] = (None, None) if origin is None else (origin.get("xyz"), origin.get("rpy"))
    return out


def test_one_marker_on_each_hand_of_talos(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    urdf = _talos()
    names, q, points = simulate(urdf, TALOS_MARKERS, 240, NOISE_M, 0.05, seed=3)
    labels = list(TALOS_MARKERS)
    write(tmp_path / "fit.csv", names, q[:120], labels, points[:120])
    write(tmp_path / "test.csv", names, q[120:], labels, points[120:])
    out, report = tmp_path / "cal.urdf", tmp_path / "report.json"
    args = ["calibrate", urdf, tmp_path / "fit.csv", "--tip", TALOS_TIP, "--test", tmp_path / "test.csv"]
    code, printed, err = run(capsys, *args, "-o", out, "--report", report)
    assert code == 0, err
    rep = json.loads(report.read_text())
    sidecar = out.with_name("cal.calibration.json")
    side = json.loads(sidecar.read_text())
    assert side["tip"] == "arm_left_7_link" and side["tip_T_tool"] is None
    assert {k: m["frame"] for k, m in side["markers"].items()} == {
        k: f for k, (f, _) in TALOS_MARKERS.items()
    }
    for key, q_part, p_part in (("train", q[:120], points[:120]), ("test", q[120:], points[120:])):
        overall, each = rms_mm(sidecar, q_part, labels, p_part)
        assert abs(overall - rep[key]["after"]["rms_mm"]) < 1e-6
        assert abs(overall - rep[key]["exported"]["rms_mm"]) < 1e-6
        for label in labels:
            assert abs(each[label] - rep[key]["markers"][label]["rms_mm"]) < 1e-6
    for label in labels:
        assert rep["test"]["markers"][label]["rms_mm"] < 1.3 * FLOOR_MM, rep["test"]["markers"]
    from test_docs import undocumented

    assert "markers" not in undocumented(report, "report.md")
    assert "markers" not in undocumented(sidecar, "formats.md")
    program = tmp_path / "program.csv"
    program.write_text(
        ",".join(names) + "\n" + "\n".join(",".join(repr(float(v)) for v in qi) for qi in q[:3]) + "\n"
    )
    code, printed, err = run(capsys, "compensate", urdf, out, program, "-o", tmp_path / "compensated.csv")
    assert code == 0 and "compensated 3 of 3 rows" in printed, err  # the first marker's frame
    before, after = _origins(urdf), _origins(out)
    changed = {name for name in before if before[name] != after[name]}
    assert changed <= set(side["joints"]) and len(changed) >= 14  # the legs, the head: as written


@pytest.mark.parametrize("setup", ["ur5", "talos"])
def test_pincal_simulator_markers_reach_the_noise_floor(setup: str) -> None:
    from pincal.simulation.markers import simulate_markers
    from pincal.simulation.truth import random_truth

    if setup == "ur5":
        robot, markers, n = pincal.load_robot("ur5"), UR5_MARKERS, 60
    else:
        robot, markers, n = pincal.load_robot(_talos(), tip=TALOS_TIP), TALOS_MARKERS, 120
    truth = random_truth(robot, seed=4)
    q = robot.random_configurations(2 * n, np.random.default_rng(5), margin=0.05)
    points = np.array([p for _, p in markers.values()])
    fit = simulate_markers(truth, q[:n], points, list(markers), NOISE_M, 0.05, seed=6)
    held = simulate_markers(truth, q[n:], points, list(markers), NOISE_M, 0.05, seed=7)
    assert fit.n_poses == n and len(fit) == n * len(markers) - round(0.05 * n)
    cal = pincal.calibrate(robot, fit, test=held)
    for label in markers:
        assert cal.test_markers[label].rms_mm < 1.3 * FLOOR_MM, cal.test_markers
    if setup == "ur5":  # the points' layout on the tool is seen (the tool's place along the last axis is not)
        fitted = np.array(list(cal.markers().values()))
        pairs = [(0, 1), (0, 2), (1, 2)]
        found = [np.linalg.norm(fitted[a] - fitted[b]) for a, b in pairs]
        np.testing.assert_allclose(
            found, [np.linalg.norm(points[a] - points[b]) for a, b in pairs], atol=1e-4
        )


def test_template_of_a_tree_names_each_marker_frame(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "template", _talos(), "--tip", TALOS_TIP)
    assert code == 0, err
    header = [line for line in out.splitlines() if not line.startswith("#")][-1].split(",")
    assert header[:2] == ["torso_1_joint", "torso_2_joint"] and len(header) == 16 + 6
    assert header[-6:] == ["x1", "y1", "z1", "x2", "y2", "z2"] and "2 on arm_right_7_link" in out


def test_given_marker_points_are_kept(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    names, q, points = simulate(bundled_urdf("ur5"), UR5_MARKERS, 40, NOISE_M, 0.05, seed=12)
    write(tmp_path / "fit.csv", names, q, list(UR5_MARKERS), points)
    given = "1=0.05,0,0.1;2=-0.05,0.03,0.08;A=0,-0.06,0.12"
    out = tmp_path / "cal.urdf"
    code, _, err = run(capsys, "calibrate", "ur5", tmp_path / "fit.csv", "--tool-point", given, "-o", out)
    assert code == 0, err
    side = json.loads(out.with_name("cal.calibration.json").read_text())
    for label, (_, point) in UR5_MARKERS.items():
        assert side["markers"][label]["point_m"] == list(point)
    code, _, err = run(capsys, "calibrate", "ur5", tmp_path / "fit.csv", "--tool-point", "1=0,0,0.1")
    assert code == 2 and "a point for each of the data's markers" in err


def test_a_recording_with_a_topic_per_marker(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("rosbags")
    from pincal.data.marker_recordings import read_marker_recording
    from pincal.data.recordings import RecordingOptions, read_recording
    from pincal.simulation.simulated_recording import Session, write_recording
    from pincal.simulation.truth import random_truth

    robot = pincal.load_robot("ur5")
    truth = random_truth(robot, seed=3)
    poses = robot.random_configurations(6, np.random.default_rng(1), 0.05)
    path = tmp_path / "rec"
    write_recording(path, truth, poses, "mcap", Session(tcp_topic="/tcp"), seed=2)
    both = read_marker_recording(
        path, robot.joint_names, RecordingOptions(measure_topic="1=/tracker/point,2=/tcp")
    )
    data = both.data
    assert data.marker_names == ("1", "2") and data.n_poses == 6 and len(data) == 12
    for k, topic in enumerate(("/tracker/point", "/tcp")):  # each marker: its topic's static poses
        alone = read_recording(path, robot.joint_names, RecordingOptions(measure_topic=topic)).data
        np.testing.assert_allclose(data.points[data.marker == k], alone.points, atol=1e-12)
        np.testing.assert_allclose(data.q[data.marker == k], alone.q, atol=1e-12)
    out = tmp_path / "poses.csv"
    code, printed, err = run(
        capsys, "extract", "ur5", path, "-o", out, "--measure-topic", "1=/tracker/point,2=/tcp"
    )
    assert code == 0, err
    again = read_csv(out, robot.joint_names)
    np.testing.assert_allclose(again.points, data.points, atol=1e-12)


def test_a_row_with_no_marker_seen_is_left_out(tmp_path: Path) -> None:
    names, q, points = simulate(bundled_urdf("ur5"), UR5_MARKERS, 10, seed=13)
    points[4] = np.nan
    write(tmp_path / "m.csv", names, q, list(UR5_MARKERS), points)
    data = read_csv(tmp_path / "m.csv", names)
    assert data.n_poses == 9 and 5 not in set(data.row_numbers)
    assert len(data) == int((~np.isnan(points[:, :, 0])).sum())


def _two_markers(
    robot: pincal.Robot,
    measure: str,
    n: int,
    names: tuple[str, str],
    rng: np.random.Generator,
    tips: tuple[int, ...] = (),
) -> tuple[pincal.Dataset, Measurement]:
    """``n`` random poses with two markers each (random points [m]), and a measurement of
    ``measure`` with a random registration and marker points (on the frames ``tips``)."""
    q = np.repeat(robot.random_configurations(n, rng), 2, axis=0)
    data = pincal.Dataset(
        robot.joint_names,
        q,
        rng.normal(0, 1, (2 * n, 3)),
        rows=np.repeat(np.arange(1, n + 1), 2),
        marker=np.tile([0, 1], n),
        marker_names=names,
    )
    pin.seed(int(rng.integers(1 << 16)))
    meas = Measurement(
        measure,
        instrument_T_base=pin.SE3.Random(),
        markers=names,
        marker_points=rng.normal(0, 0.1, (2, 3)),
        marker_tips=tips,
    )
    return data, meas
