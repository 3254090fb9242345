"""ROS recordings as data (issue 34): a simulated session recorded as MCAP, sqlite3 and ROS 1 bags
is read back as the static poses it holds, calibrates as the same poses given as a CSV, and a
recording that cannot be read unambiguously is refused with one line and no output."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from cli_run import one_error_line, run

from pincal.data.csv_writer import write_csv
from pincal.data.dataset import Dataset
from pincal.data.recordings import RecordingOptions, read_recording, static_segments
from pincal.simulation.simulated_recording import Session, write_recording
from pincal.simulation.truth import TrueRobot, random_truth

pytest.importorskip("rosbags")

N_POSES = 40
STORAGES = {"mcap": "rec_mcap", "sqlite3": "rec_sqlite3", "ros1": "rec.bag"}


class Recorded:
    """The simulated session: truth, poses, the recordings and the reference CSVs."""

    def __init__(self, folder: Path, robot) -> None:  # type: ignore[no-untyped-def]
        self.folder = folder
        self.robot = robot
        self.truth: TrueRobot = random_truth(robot, seed=3)
        self.poses = robot.random_configurations(N_POSES, np.random.default_rng(1), 0.05)
        self.paths = {kind: folder / name for kind, name in STORAGES.items()}
        for kind, path in self.paths.items():
            self.reference: Dataset = write_recording(path, self.truth, self.poses, kind, seed=2)
        self.csv = folder / "same_poses.csv"
        write_csv(self.csv, self.reference)
        held_out = robot.random_configurations(100, np.random.default_rng(5), 0.05)
        self.test = folder / "held_out.csv"
        write_csv(self.test, self.truth.measure(held_out, 3e-5, seed=7))


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory, get_robot) -> Recorded:  # type: ignore[no-untyped-def]
    return Recorded(tmp_path_factory.mktemp("recordings"), get_robot("ur5"))


def _rows(path: Path) -> tuple[list[str], np.ndarray]:
    with open(path) as fh:
        rows = list(csv.reader(fh))
    return rows[0], np.array(rows[1:], dtype=float)


@pytest.mark.parametrize("kind", list(STORAGES))
def test_extract_returns_the_poses(session: Recorded, kind: str, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    """Exactly the 40 static poses, in order, joints within 1e-4 rad, only the chain's joints,
    the measurement within the tracker's averaged noise and its spread near the 0.03 mm it has."""
    out = tmp_path / "poses.csv"
    code, _, err = run(capsys, "extract", "ur5", session.paths[kind], "-o", out)
    assert code == 0, err
    header, values = _rows(out)
    n = session.robot.n_joints
    assert header == [*session.robot.joint_names, "x", "y", "z", "spread_mm"]
    assert values.shape == (N_POSES, n + 4)
    assert np.abs(values[:, :n] - session.poses).max() < 1e-4
    true_points = session.truth.target(session.poses)[0]
    assert np.abs(values[:, n : n + 3] - true_points).max() < 3e-5  # 0.03 mm noise, averaged
    assert 0.02 < np.median(values[:, -1]) < 0.04


def test_extract_without_robot_keeps_every_joint(session: Recorded, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "all.csv"
    code, _, err = run(capsys, "extract", session.paths["mcap"], "-o", out)
    assert code == 0, err
    header, values = _rows(out)
    assert set(header[:7]) == {*session.robot.joint_names, "gripper_finger_joint"}
    assert len(values) == N_POSES


@pytest.mark.parametrize("kind", list(STORAGES))
def test_calibration_from_a_recording_matches_the_csv(
    session: Recorded, kind: str, tmp_path: Path, capsys
) -> None:  # type: ignore[no-untyped-def]
    """The held-out RMS of a calibration from each recording is within 2 % of the same poses' CSV."""
    rms = {}
    for name, data in (("csv", session.csv), (kind, session.paths[kind])):
        report = tmp_path / f"{name}.json"
        code, _, err = run(capsys, "calibrate", "ur5", data, "--test", session.test, "--report", report)
        assert code == 0, err
        rms[name] = json.loads(report.read_text())["test"]["after"]["rms_mm"]
    assert abs(rms[kind] - rms["csv"]) <= 0.02 * rms["csv"], rms
    assert rms["csv"] < 0.06  # at the held-out noise floor (0.052 mm): the comparison is of good fits


def test_bare_storage_files_read_as_their_folder(session: Recorded) -> None:
    """A bare .mcap or .db3 file gives the poses its rosbag2 folder gives."""
    joints = session.robot.joint_names
    for kind, suffix in (("mcap", ".mcap"), ("sqlite3", ".db3")):
        folder = read_recording(session.paths[kind], joints, RecordingOptions()).data
        (bare,) = session.paths[kind].glob(f"*{suffix}")
        alone = read_recording(bare, joints, RecordingOptions()).data
        np.testing.assert_array_equal(alone.q, folder.q)
        np.testing.assert_array_equal(alone.points, folder.points)


@pytest.mark.parametrize("compression", ["file", "message"])
def test_compressed_recordings(session: Recorded, compression: str, tmp_path: Path) -> None:
    """A zstd-compressed rosbag2 (per file or per message) gives the poses of an uncompressed one."""
    path = tmp_path / f"zstd_{compression}"
    reference = write_recording(
        path, session.truth, session.poses[:6], "sqlite3", Session(compression=compression), seed=2
    )
    data = read_recording(path, session.robot.joint_names, RecordingOptions()).data
    assert np.abs(data.q - session.poses[:6]).max() < 1e-4
    assert np.abs(data.points - reference.points).max() < 3e-5


def test_no_joint_states_is_refused(session: Recorded, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "no_joints"
    write_recording(path, session.truth, session.poses[:5], "mcap", Session(joint_topic=None), seed=2)
    report = tmp_path / "r.json"
    line = one_error_line(capsys, "calibrate", "ur5", path, "--report", report)
    assert "JointState" in line and "/joint_states" in line and "--joint-topic" in line
    assert not report.exists()


def test_two_measurement_topics_are_refused_then_chosen(session: Recorded, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    """A tracker beside the controller's own TCP pose: refused, naming both, until one is named;
    the PoseStamped gives orientations with --measure pose only."""
    path = tmp_path / "two"
    write_recording(
        path, session.truth, session.poses[:6], "sqlite3", Session(tcp_topic="/tcp_pose/pose"), seed=2
    )
    report = tmp_path / "r.json"
    line = one_error_line(capsys, "calibrate", "ur5", path, "--report", report)
    assert "/tcp_pose/pose" in line and "/tracker/point" in line and "--measure-topic" in line
    assert not report.exists()
    options = RecordingOptions(measure_topic="/tcp_pose/pose")
    assert read_recording(path, None, options).data.quaternions is None
    posed = read_recording(
        path, session.robot.joint_names, RecordingOptions("/joint_states", "/tcp_pose/pose", orientation=True)
    ).data
    nominal = [session.robot.frame_placement(q) for q in session.poses[:6]]
    np.testing.assert_allclose(posed.points, [p.translation for p in nominal], atol=1e-9)
    np.testing.assert_allclose(posed.rotations(), [p.rotation for p in nominal], atol=1e-9)


def test_tf_transform_and_clock_offset(session: Recorded, tmp_path: Path) -> None:
    """A /tf transform is the measurement with --measure-frame; a tracker clock 3 s off is warned
    of, and --time-offset puts the measurement back on the poses."""
    path = tmp_path / "tf.bag"
    reference = write_recording(
        path, session.truth, session.poses[:8], "ros1", Session(tf_child="ball", tracker_clock=3.0), seed=2
    )
    joints = session.robot.joint_names
    off = read_recording(path, joints, RecordingOptions(measure_frame="tracker:ball"))
    assert any("time_offset=-3" in w for w in off.warnings), off.warnings
    fixed = read_recording(path, joints, RecordingOptions(measure_frame="tracker:ball", time_offset=-3.0))
    assert not fixed.warnings
    assert len(fixed.data) == 8
    assert np.abs(fixed.data.points - reference.points).max() < 3e-5


def test_static_segments_of_a_known_series() -> None:
    """Rests of known length are found with their edges, moves and short rests are not."""
    t = np.arange(0.0, 10.0, 0.01)
    q = np.where(t < 2.0, 0.0, np.where(t < 3.0, t - 2.0, np.where(t < 3.3, 1.0, 1.0 + (t - 3.3))))
    q = np.where(t >= 6.0, 3.7, q)[:, None]
    found = static_segments(t, q, 1e-4, 0.5)
    assert len(found) == 2
    assert found[0][0] == 0.0 and abs(found[0][1] - 2.0) <= 0.011
    assert abs(found[1][0] - 6.0) <= 0.011 and abs(found[1][1] - 9.99) < 1e-9


def test_subset_keeps_the_spread() -> None:
    data = Dataset(("j",), np.arange(4.0)[:, None], np.zeros((4, 3)), spread=np.array([1.0, 2.0, 3.0, 4.0]))
    picked = data.subset([3, 1])
    assert picked.spread is not None
    np.testing.assert_array_equal(picked.spread, [4.0, 2.0])
    assert Dataset(("j",), np.zeros((2, 1)), np.zeros((2, 3))).subset([1]).spread is None


CALIBRATION_MSGS = {
    "robot_calibration_msgs/msg/CameraParameter": "string name\nfloat64 value\n",
    "robot_calibration_msgs/msg/ExtendedCameraInfo": (
        "sensor_msgs/CameraInfo camera_info\nrobot_calibration_msgs/CameraParameter[] parameters\n"
    ),
    "robot_calibration_msgs/msg/Observation": (
        "string sensor_name\ngeometry_msgs/PointStamped[] features\n"
        "robot_calibration_msgs/ExtendedCameraInfo ext_camera_info\n"
        "sensor_msgs/PointCloud2 cloud\nsensor_msgs/Image image\n"
    ),
    "robot_calibration_msgs/msg/CalibrationData": (
        "sensor_msgs/JointState joint_states\nrobot_calibration_msgs/Observation[] observations\n"
    ),
}


def _write_calibration_data(path: Path, names: tuple[str, ...], q: np.ndarray, points: np.ndarray) -> None:
    """robot_calibration's snapshots, one per pose, each with one observation of one point."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    for name, text in CALIBRATION_MSGS.items():
        store.register(get_types_from_msg(text, name))
    t = store.types
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection(
            "/calibration_data", "robot_calibration_msgs/msg/CalibrationData", typestore=store
        )
        for k, (row, p) in enumerate(zip(q, points)):
            header = t["std_msgs/msg/Header"](
                stamp=t["builtin_interfaces/msg/Time"](sec=k, nanosec=0), frame_id=""
            )
            state = t["sensor_msgs/msg/JointState"](
                header=header,
                name=list(names[::-1]),
                position=row[::-1].copy(),
                velocity=np.zeros(0),
                effort=np.zeros(0),
            )
            point = t["geometry_msgs/msg/PointStamped"](header=header, point=t["geometry_msgs/msg/Point"](*p))
            observation = t["robot_calibration_msgs/msg/Observation"](
                sensor_name="tracker",
                features=[point],
                ext_camera_info=t["robot_calibration_msgs/msg/ExtendedCameraInfo"](
                    camera_info=_empty(store, "sensor_msgs/msg/CameraInfo"), parameters=[]
                ),
                cloud=_empty(store, "sensor_msgs/msg/PointCloud2"),
                image=_empty(store, "sensor_msgs/msg/Image"),
            )
            message = t["robot_calibration_msgs/msg/CalibrationData"](
                joint_states=state, observations=[observation]
            )
            raw = store.serialize_cdr(message, "robot_calibration_msgs/msg/CalibrationData")
            writer.write(conn, (k + 1) * 1_000_000_000, raw)


def _empty(store, kind: str):  # type: ignore[no-untyped-def]
    """A message of ``kind`` with every field empty or zero (from the typestore's field definitions)."""
    from rosbags.interfaces import Nodetype

    values = {}
    for name, (node, detail) in store.fielddefs[kind][1]:
        if node == Nodetype.NAME:
            values[name] = _empty(store, detail)
        elif node == Nodetype.BASE:
            values[name] = "" if detail[0] == "string" else False if detail[0] == "bool" else 0
        else:
            (sub, subdetail), size = detail
            numeric = sub == Nodetype.BASE and subdetail[0] not in ("string", "bool")
            values[name] = np.zeros(size, dtype=np.dtype(subdetail[0])) if numeric else []
    return store.types[kind](**values)


def test_calibration_data_snapshots_are_one_pose_each(session: Recorded, tmp_path: Path) -> None:
    """robot_calibration's CalibrationData: each message is a pose, joints by name, no segmenting."""
    q = session.poses[:7]
    points = session.truth.target(q)[0]
    path = tmp_path / "capture"
    _write_calibration_data(path, session.robot.joint_names, q, points)
    data = read_recording(path, session.robot.joint_names, RecordingOptions()).data
    np.testing.assert_array_equal(data.q, q)
    np.testing.assert_array_equal(data.points, points)


def test_compensate_a_recorded_program(session: Recorded, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    """A program run and recorded compensates as the CSV of its commands does."""
    fit = tmp_path / "cal.urdf"
    code, _, err = run(
        capsys, "calibrate", "ur5", session.csv, "-o", fit, "--extend", "none", "--nested", "no"
    )
    assert code == 0, err
    program = tmp_path / "program.csv"
    with open(program, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(session.robot.joint_names)
        writer.writerows(session.poses[:10].tolist())
    outputs = {}
    for name, source in (("csv", program), ("recording", session.paths["mcap"])):
        outputs[name] = tmp_path / f"{name}_compensated.csv"
        code, _, err = run(capsys, "compensate", "ur5", fit, source, "-o", outputs[name])
        assert code == 0, err
    _, from_csv = _rows_of(outputs["csv"])
    _, from_recording = _rows_of(outputs["recording"])
    assert len(from_recording) == N_POSES
    assert np.abs(from_recording[:10] - from_csv).max() < 1e-6


def _rows_of(path: Path) -> tuple[list[str], np.ndarray]:
    """A compensated program's joint columns (its status column dropped)."""
    with open(path) as fh:
        rows = list(csv.reader(fh))
    keep = [k for k, name in enumerate(rows[0]) if name != "status"]
    return [rows[0][k] for k in keep], np.array([[float(r[k]) for k in keep] for r in rows[1:]])


def test_recording_options_with_a_csv_are_said_ignored(session: Recorded, capsys) -> None:  # type: ignore[no-untyped-def]
    code, _, err = run(
        capsys,
        "calibrate",
        "ur5",
        session.csv,
        "--joint-topic",
        "/arm/joint_states",
        "--extend",
        "none",
        "--nested",
        "no",
    )
    assert code == 0, err
    assert "ignored" in err and "--joint-topic (ROS recordings only)" in err
    code, _, err = run(capsys, "calibrate", "ur5", session.csv, "--extend", "none", "--nested", "no")
    assert code == 0 and "ROS recordings only" not in err


def test_poses_without_a_measurement_are_left_out_and_said(session: Recorded, tmp_path: Path) -> None:
    """The tracker loses the reflector at two poses: the others are read, the two are warned of."""
    path = tmp_path / "dropouts"
    write_recording(path, session.truth, session.poses[:8], "mcap", Session(dropouts=(2, 5)), seed=2)
    recording = read_recording(path, session.robot.joint_names, RecordingOptions())
    kept = [k for k in range(8) if k not in (2, 5)]
    assert np.abs(recording.data.q - session.poses[kept]).max() < 1e-4
    assert any("2 static segment(s) without a measurement" in w for w in recording.warnings), (
        recording.warnings
    )
