"""Time series from a ROS recording, read with the ``rosbags`` library (no ROS install).

A recording is a rosbag2 folder (``metadata.yaml``; sqlite3 or MCAP storage, split or
compressed), a bare ``.mcap`` or ``.db3`` file, or a ROS 1 ``.bag``. What is read from it:

- the joint states (``sensor_msgs/JointState`` on one topic, from any number of publishers,
  each message naming its joints in any order): :class:`JointSeries`, merged by name over time;
- the measurement: ``geometry_msgs`` ``PointStamped``, ``PoseStamped`` or ``TransformStamped``
  on one topic, or one ``PARENT:CHILD`` transform of ``/tf``: :class:`MeasureSeries`;
- robot_calibration's ``CalibrationData`` snapshots (one pose each): :func:`calibration_snapshots`.

Times are seconds: the message's ``header.stamp``, or the recording time where a stamp is zero.
Lengths are metres and angles radians, as ROS holds them (REP 103).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pincal.errors import DataError

#: Suffixes of the files that are recordings (a rosbag2 folder holds ``metadata.yaml``).
RECORDING_SUFFIXES = (".mcap", ".db3", ".bag")
JOINT_STATE = "sensor_msgs/msg/JointState"
POINT, POSE, TRANSFORM = (
    f"geometry_msgs/msg/{t}" for t in ("PointStamped", "PoseStamped", "TransformStamped")
)
TF = "tf2_msgs/msg/TFMessage"
CALIBRATION_DATA = "robot_calibration_msgs/msg/CalibrationData"
#: Message types that carry a measurement, one per message.
MEASURE_TYPES = (POINT, POSE, TRANSFORM, CALIBRATION_DATA)
#: robot_calibration's messages (robot_calibration_msgs), for recordings that hold no definitions.
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
    CALIBRATION_DATA: (
        "sensor_msgs/JointState joint_states\nrobot_calibration_msgs/Observation[] observations\n"
    ),
}


def is_recording(path: str | Path) -> bool:
    """Whether ``path`` is a ROS recording (by its suffix, or a folder with ``metadata.yaml``)."""
    path = Path(path)
    return path.suffix.lower() in RECORDING_SUFFIXES or (path / "metadata.yaml").is_file()


@dataclass(frozen=True)
class JointSeries:
    """Joint positions over time, merged by name from every message of the joint topic.

    Attributes:
        names: every joint named in the messages, in order of first appearance.
        times: (M,) message times [s], increasing.
        positions: (M, len(names)) the last position of each joint at that time [rad or m]
            (NaN before the joint's first message).
        received: (M,) recording times of the same messages [s].
    """

    names: tuple[str, ...]
    times: np.ndarray
    positions: np.ndarray
    received: np.ndarray

    def columns(self, joints: tuple[str, ...]) -> np.ndarray:
        """The positions (M, len(joints)) of the named joints."""
        return self.positions[:, [self.names.index(j) for j in joints]]


@dataclass(frozen=True)
class MeasureSeries:
    """Measured positions (and orientations) over time, in the instrument's frame.

    Attributes:
        source: the topic (or ``/tf PARENT:CHILD``) it came from.
        times: (K,) measurement times [s], increasing.
        points: (K, 3) positions [m].
        quaternions: (K, 4) orientations (w, x, y, z), or None (points carry none).
        received: (K,) recording times [s].
    """

    source: str
    times: np.ndarray
    points: np.ndarray
    quaternions: np.ndarray | None
    received: np.ndarray


@contextmanager
def open_recording(path: Path) -> Iterator[Any]:
    """An open ``rosbags`` reader of any recording kind (message types from the recording, else
    ROS 2 Humble's and robot_calibration's).

    Raises:
        DataError: the path is missing or not a readable recording.
    """
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    if not path.exists():
        raise DataError(f"{path}: no such recording")
    store = get_typestore(Stores.ROS2_HUMBLE)
    for name, text in CALIBRATION_MSGS.items():
        store.register(get_types_from_msg(text, name))
    try:
        reader = AnyReader([path], default_typestore=store)
        reader.open()
    except (AnyReaderError, OSError, ValueError, KeyError) as exc:
        raise DataError(f"{path}: not a readable ROS recording ({exc})") from None
    try:
        yield reader
    finally:
        reader.close()


def topic_types(reader: Any) -> dict[str, str]:
    """Topic name -> message type of a recording."""
    return {name: str(info.msgtype) for name, info in reader.topics.items()}


def _messages(reader: Any, topic: str) -> Iterator[tuple[float, Any]]:
    """(recording time [s], message) of a topic, in recording order."""
    from rosbags.highlevel import AnyReaderError

    connections = [c for c in reader.connections if c.topic == topic]
    try:
        for connection, stamp, raw in reader.messages(connections=connections):
            yield stamp * 1e-9, reader.deserialize(raw, connection.msgtype)
    except (AnyReaderError, ValueError, KeyError) as exc:
        raise DataError(f"{topic}: a message cannot be read ({exc})") from None


def _stamp(header: Any, received: float) -> float:
    """A header's stamp [s], or the recording time where it is zero."""
    t = header.stamp.sec + header.stamp.nanosec * 1e-9
    return float(t) if t != 0 else received


def read_joints(reader: Any, topic: str) -> JointSeries:
    """The joint states of ``topic``, merged by name (see :class:`JointSeries`).

    Raises:
        DataError: the topic holds no joint states.
    """
    msgs = [
        (_stamp(m.header, r), r, list(m.name), np.asarray(m.position, dtype=float))
        for r, m in _messages(reader, topic)
    ]
    msgs = [m for m in msgs if len(m[2]) and len(m[2]) == len(m[3])]
    if not msgs:
        raise DataError(
            f"the recording holds no joint positions on {topic}: name the topic with joint_topic="
        )
    msgs.sort(key=lambda m: m[0])
    names: dict[str, int] = {}
    for _, _, joint_names, _ in msgs:
        for name in joint_names:
            names.setdefault(name, len(names))
    positions = np.full((len(msgs), len(names)), np.nan)
    last = np.full(len(names), np.nan)
    for k, (_, _, joint_names, values) in enumerate(msgs):
        last[[names[n] for n in joint_names]] = values
        positions[k] = last
    times = np.array([m[0] for m in msgs])
    return JointSeries(tuple(names), times, positions, np.array([m[1] for m in msgs]))


def _point_of(message: Any, msgtype: str) -> tuple[np.ndarray, np.ndarray | None]:
    """Position [m] and orientation (w, x, y, z) of one measurement message."""
    if msgtype == POINT:
        p = message.point
        return np.array([p.x, p.y, p.z]), None
    if msgtype == POSE:
        p, o = message.pose.position, message.pose.orientation
        return np.array([p.x, p.y, p.z]), np.array([o.w, o.x, o.y, o.z])
    t, o = message.transform.translation, message.transform.rotation
    return np.array([t.x, t.y, t.z]), np.array([o.w, o.x, o.y, o.z])


def _series(source: str, rows: list[tuple[float, float, np.ndarray, np.ndarray | None]]) -> MeasureSeries:
    """A :class:`MeasureSeries` from (time, received, point, quaternion) rows, sorted by time."""
    if not rows:
        raise DataError(f"the recording holds no measurement on {source}")
    rows.sort(key=lambda r: r[0])
    quats = None if rows[0][3] is None else np.array([r[3] for r in rows])
    return MeasureSeries(
        source,
        np.array([r[0] for r in rows]),
        np.array([r[2] for r in rows]),
        quats,
        np.array([r[1] for r in rows]),
    )


def read_measure(reader: Any, topic: str, msgtype: str) -> MeasureSeries:
    """The measurements of one ``PointStamped``, ``PoseStamped`` or ``TransformStamped`` topic."""
    rows = []
    for received, message in _messages(reader, topic):
        point, quat = _point_of(message, msgtype)
        rows.append((_stamp(message.header, received), received, point, quat))
    return _series(topic, rows)


def read_tf(reader: Any, topics: list[str], parent: str, child: str) -> MeasureSeries:
    """The transforms ``parent`` -> ``child`` of ``/tf`` (and ``/tf_static``) messages."""
    rows = []
    for topic in topics:
        for received, message in _messages(reader, topic):
            for tf in message.transforms:
                if tf.header.frame_id.lstrip("/") == parent and tf.child_frame_id.lstrip("/") == child:
                    point, quat = _point_of(tf, TRANSFORM)
                    rows.append((_stamp(tf.header, received), received, point, quat))
    return _series(f"/tf {parent}:{child}", rows)


def calibration_snapshots(reader: Any, topic: str) -> tuple[JointSeries, MeasureSeries]:
    """robot_calibration's ``CalibrationData`` messages, one pose each: the joint states of the
    message and the one feature point its observation holds.

    Raises:
        DataError: a message has no observation with exactly one feature point, or several.
    """
    joints: list[tuple[float, float, list[str], np.ndarray]] = []
    points: list[tuple[float, float, np.ndarray, np.ndarray | None]] = []
    for k, (received, message) in enumerate(_messages(reader, topic)):
        observed = [o for o in message.observations if len(o.features) == 1]
        if len(observed) != 1:
            sensors = ", ".join(o.sensor_name for o in message.observations) or "none"
            raise DataError(
                f"{topic}: message {k + 1} must hold one observation of one feature point "
                f"(sensors: {sensors}): pincal reads a tracked point, not a camera's features"
            )
        state, feature = message.joint_states, observed[0].features[0]
        joints.append((float(k), received, list(state.name), np.asarray(state.position, dtype=float)))
        points.append((float(k), received, _point_of(feature, POINT)[0], None))
    names = tuple(dict.fromkeys(n for _, _, names_k, _ in joints for n in names_k))
    positions = np.full((len(joints), len(names)), np.nan)
    for k, (_, _, names_k, values) in enumerate(joints):
        positions[k, [names.index(n) for n in names_k]] = values
    times = np.arange(len(joints), dtype=float)
    return JointSeries(names, times, positions, np.array([j[1] for j in joints])), _series(topic, points)
