"""A simulated ROS recording of a calibration session, for tests, the notebooks and the docs.

The robot holds each pose for ``hold`` seconds and moves to the next in 1 to 3 s (a quintic
profile); its driver publishes ``sensor_msgs/JointState`` at 100 Hz, naming the joints in a
new random order every message, and a gripper driver publishes the gripper joint on the same topic
(it moves while the arm moves). A tracker publishes ``geometry_msgs/PointStamped`` at 50 Hz with
Gaussian noise, stamped by its own clock, a few ms off the robot's. Written with ``rosbags`` as a
rosbag2 folder (MCAP or sqlite3 storage) or a ROS 1 ``.bag``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pincal.data.dataset import Dataset
from pincal.simulation.truth import TrueRobot

STORAGES = ("mcap", "sqlite3", "ros1")


@dataclass(frozen=True)
class Session:
    """How the simulated session is recorded.

    Attributes:
        hold: how long the robot rests at each pose [s].
        move: shortest and longest move between poses [s].
        joint_rate, tracker_rate: publishing rates [Hz].
        noise: the tracker's noise, 1σ per axis [m].
        tracker_clock: how far the tracker's stamps run ahead of the robot's clock [s].
        gripper: the gripper joint's name, or None for no gripper.
        joint_topic, measure_topic: where the joint states and the tracker publish (None: not at all).
        tcp_topic: where the controller's own TCP pose is published (``PoseStamped``), or None.
        tf_child: the tracker publishes its point on ``/tf`` instead, as the transform from
            ``tracker`` to this frame (rotation identity), or None.
        compression: a rosbag2's zstd compression, ``file`` or ``message``, or None.
        dropouts: the poses (indices) at which the tracker loses the reflector and publishes nothing.
    """

    hold: float = 1.0
    move: tuple[float, float] = (1.0, 3.0)
    joint_rate: float = 100.0
    tracker_rate: float = 50.0
    noise: float = 3e-5
    tracker_clock: float = 0.004
    gripper: str | None = "gripper_finger_joint"
    joint_topic: str | None = "/joint_states"
    measure_topic: str | None = "/tracker/point"
    tcp_topic: str | None = None
    tf_child: str | None = None
    compression: str | None = None
    dropouts: tuple[int, ...] = ()


class Trajectory:
    """Joint values over time: rest at each pose, quintic moves between them."""

    def __init__(self, poses: np.ndarray, hold: float, moves: np.ndarray) -> None:
        self.poses = poses
        spans = np.empty(2 * len(poses) - 1)
        spans[0::2], spans[1::2] = hold, moves
        self.edges = np.concatenate([[0.0], np.cumsum(spans)])  # rest k: edges[2k] .. edges[2k+1]

    @property
    def end(self) -> float:
        """When the last rest ends [s]."""
        return float(self.edges[-1])

    def at(self, t: np.ndarray) -> np.ndarray:
        """Joint values (len(t), n) at times ``t`` [s]."""
        span = np.clip(np.searchsorted(self.edges, t, side="right") - 1, 0, len(self.edges) - 2)
        k = span // 2
        tau = np.clip((t - self.edges[span]) / (self.edges[span + 1] - self.edges[span]), 0.0, 1.0)
        s = np.where(span % 2 == 1, tau**3 * (10 - 15 * tau + 6 * tau**2), 0.0)
        after = self.poses[np.minimum(k + 1, len(self.poses) - 1)]
        return self.poses[k] + s[:, None] * (after - self.poses[k])

    def moving(self, t: np.ndarray) -> np.ndarray:
        """Between 0 (resting) and 1 (mid-move) at times ``t``."""
        span = np.clip(np.searchsorted(self.edges, t, side="right") - 1, 0, len(self.edges) - 2)
        tau = (t - self.edges[span]) / (self.edges[span + 1] - self.edges[span])
        return np.where(span % 2 == 1, np.sin(np.pi * np.clip(tau, 0, 1)), 0.0)


class _Bag:
    """A recording being written: connections by topic, messages serialized for its format."""

    def __init__(self, path: Path, storage: str, compression: str | None = None) -> None:
        from rosbags.typesys import Stores, get_typestore

        self.ros1 = storage == "ros1"
        self.store = get_typestore(Stores.ROS1_NOETIC if self.ros1 else Stores.ROS2_HUMBLE)
        if "tf2_msgs/msg/TFMessage" not in self.store.types:  # ROS 1's store lacks it
            from rosbags.typesys import get_types_from_msg

            tf = get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage")
            self.store.register(tf)
        if self.ros1:
            from rosbags.rosbag1 import Writer as Writer1

            self.writer: Any = Writer1(path)
        else:
            from rosbags.rosbag2 import StoragePlugin, Writer

            plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
            self.writer = Writer(path, version=9, storage_plugin=plugin)
            if compression is not None:
                from rosbags.rosbag2 import CompressionFormat, CompressionMode

                self.writer.set_compression(CompressionMode[compression.upper()], CompressionFormat.ZSTD)
        self.connections: dict[str, Any] = {}
        self.messages: list[tuple[int, str, Any]] = []

    def header(self, t: float, frame: str) -> Any:
        sec, nanosec = int(np.floor(t)), int(round((t - np.floor(t)) * 1e9)) % 1_000_000_000
        stamp = self.store.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)
        extra = {"seq": 0} if self.ros1 else {}
        return self.store.types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame, **extra)

    def add(self, received: float, topic: str, message: Any) -> None:
        self.messages.append((int(round(received * 1e9)), topic, message))

    def write(self) -> None:
        self.writer.open()
        try:
            for stamp, topic, message in sorted(self.messages, key=lambda m: m[0]):
                kind = message.__msgtype__
                if topic not in self.connections:
                    self.connections[topic] = self.writer.add_connection(topic, kind, typestore=self.store)
                raw = (
                    self.store.serialize_ros1(message, kind)
                    if self.ros1
                    else self.store.serialize_cdr(message, kind)
                )
                self.writer.write(self.connections[topic], stamp, raw)
        finally:
            self.writer.close()


def _joint_messages(
    bag: _Bag, path: Trajectory, names: tuple[str, ...], session: Session, rng: np.random.Generator
) -> None:
    """The arm's joint states (names shuffled) and the gripper's, on the joint topic."""
    types, topic = bag.store.types, session.joint_topic
    assert topic is not None
    times = np.arange(0.0, path.end, 1.0 / session.joint_rate)
    for t, q in zip(times, path.at(times)):
        order = rng.permutation(len(names))
        msg = types["sensor_msgs/msg/JointState"](
            header=bag.header(t, ""),
            name=[names[i] for i in order],
            position=q[order] + rng.normal(0.0, 1e-7, len(names)),
            velocity=np.zeros(0),
            effort=np.zeros(0),
        )
        bag.add(t + 0.001, topic, msg)
    if session.gripper is not None:
        slow = np.arange(0.0, path.end, 0.1)
        for t, opening in zip(slow, 0.04 * path.moving(slow)):
            msg = types["sensor_msgs/msg/JointState"](
                header=bag.header(t, ""),
                name=[session.gripper],
                position=np.array([opening]),
                velocity=np.zeros(0),
                effort=np.zeros(0),
            )
            bag.add(t + 0.002, topic, msg)


def _tracker_messages(
    bag: _Bag, path: Trajectory, truth: TrueRobot, session: Session, rng: np.random.Generator
) -> np.ndarray:
    """The tracker's points; returns the noise drawn at each of its times (K, 3) [m]."""
    times = np.arange(0.0, path.end, 1.0 / session.tracker_rate)
    noise = rng.normal(0.0, session.noise, (len(times), 3))
    points = truth.target(path.at(times))[0] + noise
    types = bag.store.types
    rest = np.searchsorted(path.edges, times, side="right") - 1
    lost = np.isin(rest, [2 * k for k in session.dropouts])
    for t, p in zip(times[~lost], points[~lost]):
        header = bag.header(t + session.tracker_clock, "tracker")
        if session.tf_child is not None:
            bag.add(t + 0.002, "/tf", _tf_message(bag, header, session.tf_child, p))
        elif session.measure_topic is not None:
            point = types["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=p[2])
            msg = types["geometry_msgs/msg/PointStamped"](header=header, point=point)
            bag.add(t + 0.002, session.measure_topic, msg)
    return noise


def _tf_message(bag: _Bag, header: Any, child: str, p: np.ndarray) -> Any:
    """A ``/tf`` message holding one transform ``header.frame_id`` -> ``child`` at ``p`` [m]."""
    types = bag.store.types
    transform = types["geometry_msgs/msg/Transform"](
        translation=types["geometry_msgs/msg/Vector3"](x=p[0], y=p[1], z=p[2]),
        rotation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
    )
    stamped = types["geometry_msgs/msg/TransformStamped"](
        header=header, child_frame_id=child, transform=transform
    )
    return types["tf2_msgs/msg/TFMessage"](transforms=[stamped])


def _tcp_messages(bag: _Bag, path: Trajectory, truth: TrueRobot, topic: str) -> None:
    """The controller's own TCP pose (the nominal model's, in the base frame) at 10 Hz."""
    import pinocchio as pin

    types = bag.store.types
    for t, q in zip(np.arange(0.0, path.end, 0.1), path.at(np.arange(0.0, path.end, 0.1))):
        pose = truth.robot.frame_placement(q)
        quat = pin.Quaternion(pose.rotation)
        msg = types["geometry_msgs/msg/PoseStamped"](
            header=bag.header(t, "base"),
            pose=types["geometry_msgs/msg/Pose"](
                position=types["geometry_msgs/msg/Point"](*pose.translation),
                orientation=types["geometry_msgs/msg/Quaternion"](x=quat.x, y=quat.y, z=quat.z, w=quat.w),
            ),
        )
        bag.add(t + 0.003, topic, msg)


def write_recording(
    path: str | Path,
    truth: TrueRobot,
    poses: np.ndarray,
    storage: str = "mcap",
    session: Session | None = None,
    seed: int = 0,
) -> Dataset:
    """Record a simulated session at ``path`` (a new folder, or a ``.bag`` file for ``ros1``).

    Args:
        path: where to write (must not exist).
        truth: the simulated robot and instrument.
        poses: (N, n) the static poses, in the order visited [rad or m].
        storage: ``mcap`` or ``sqlite3`` (rosbag2 folders) or ``ros1``.
        session: timing, rates, noise and topics (default :class:`Session`).
        seed: seed of the moves' durations, the names' order and the noise.

    Returns:
        The poses as a perfect reader would give them: the exact joint values, and the true
        position plus the mean of the tracker noise drawn while the robot rested there [m].
    """
    session = session or Session()
    rng = np.random.default_rng(seed)
    path_t = Trajectory(
        np.asarray(poses, dtype=float), session.hold, rng.uniform(*session.move, len(poses) - 1)
    )
    bag = _Bag(Path(path), storage, session.compression)
    if session.joint_topic is not None:
        _joint_messages(bag, path_t, truth.robot.joint_names, session, rng)
    noise = _tracker_messages(bag, path_t, truth, session, rng)
    if session.tcp_topic is not None:
        _tcp_messages(bag, path_t, truth, session.tcp_topic)
    bag.write()
    times = np.arange(0.0, path_t.end, 1.0 / session.tracker_rate)
    rest = np.searchsorted(path_t.edges, times, side="right") - 1
    mean_noise = np.array([noise[rest == 2 * k].mean(axis=0) for k in range(len(poses))])
    q = np.asarray(poses, dtype=float)
    return Dataset(truth.robot.joint_names, q, truth.target(q)[0] + mean_noise)
