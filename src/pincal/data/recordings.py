"""Poses from a ROS recording: the static segments of the joint states, averaged.

A pose is kept where every joint of the chain stays within ``band`` (rad, or m for a prismatic
joint) for at least ``duration`` seconds. A quarter of ``duration`` is trimmed off each end of the
segment (the end of the move before it, the start of the next), and the joint values and the
measurement are averaged over what is left. The measurement's spread over the segment is kept per
pose (:attr:`pincal.data.dataset.Dataset.spread`): the instrument's noise, RMS per axis [m].

robot_calibration's ``CalibrationData`` snapshots are one pose each, without segmenting.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pincal.data.dataset import Dataset
from pincal.data.recording_reader import (
    CALIBRATION_DATA,
    JOINT_STATE,
    MEASURE_TYPES,
    TF,
    JointSeries,
    MeasureSeries,
    calibration_snapshots,
    open_recording,
    read_joints,
    read_measure,
    read_tf,
    topic_types,
)
from pincal.errors import DataError

#: Fraction of the static duration trimmed off each end of a segment.
TRIM = 0.25


@dataclass(frozen=True)
class RecordingOptions:
    """How a recording is read.

    Attributes:
        joint_topic: the ``sensor_msgs/JointState`` topic.
        measure_topic: the measurement topic (default: the only candidate).
        measure_frame: ``PARENT:CHILD``, the ``/tf`` transform that is the measurement.
        time_offset: added to the measurement's times to put them on the joint states' clock [s].
        band: how far each joint may move within a static segment [rad or m].
        duration: how long a static segment lasts at least [s].
        orientation: read the measured orientation (pose data) where the messages carry one.
    """

    joint_topic: str = "/joint_states"
    measure_topic: str | None = None
    measure_frame: str | None = None
    time_offset: float = 0.0
    band: float = 1e-4
    duration: float = 0.5
    orientation: bool = False


@dataclass(frozen=True)
class Recording:
    """The static poses of a recording.

    Attributes:
        data: the poses (joint values averaged, measurement averaged, ``spread`` per pose).
        times: (N,) the middle of each pose's segment on the joint states' clock [s].
        source: where the measurement came from (topic, or ``/tf PARENT:CHILD``).
        warnings: what the reader noticed and the user should know.
    """

    data: Dataset
    times: np.ndarray
    source: str
    warnings: tuple[str, ...] = ()


def static_segments(
    times: np.ndarray, q: np.ndarray, band: float, duration: float
) -> list[tuple[float, float]]:
    """The (start, end) times [s] of the runs where every column of ``q`` stays within ``band``
    for ``duration`` seconds or more."""
    segments = []
    start, lo, hi = 0, q[0].copy(), q[0].copy()
    for k in range(1, len(times) + 1):
        if k < len(times):
            lo_k, hi_k = np.minimum(lo, q[k]), np.maximum(hi, q[k])
            if np.all(hi_k - lo_k <= band):
                lo, hi = lo_k, hi_k
                continue
        if times[k - 1] - times[start] >= duration:
            segments.append((float(times[start]), float(times[k - 1])))
        if k < len(times):
            start, lo, hi = k, q[k].copy(), q[k].copy()
    return segments


def mean_quaternion(quats: np.ndarray) -> np.ndarray:
    """The average (w, x, y, z) of unit quaternions (signs aligned to the first)."""
    signs = np.where(quats @ quats[0] < 0, -1.0, 1.0)
    mean = (quats * signs[:, None]).mean(axis=0)
    return mean / np.linalg.norm(mean)


def spread_per_axis(points: np.ndarray) -> float:
    """RMS over the axes of the sample standard deviation of ``points`` (K, 3) [m]; NaN for one."""
    if len(points) < 2:
        return float("nan")
    return float(np.sqrt(np.mean(np.var(points, axis=0, ddof=1))))


def _clock_offset(times: np.ndarray, received: np.ndarray) -> float:
    """How far the stamps lag the recording time, median [s]."""
    return float(np.median(received - times))


def segment_poses(
    joints: JointSeries, chain: tuple[str, ...], measure: MeasureSeries, options: RecordingOptions
) -> tuple[Dataset, np.ndarray, int]:
    """The static poses of the joint states, with the measurement averaged over each; their
    times [s] (the middle of each segment), and how many static segments had no measurement.

    Raises:
        DataError: no static segment, or no measurement in any.
    """
    q_all = joints.columns(chain)
    known = ~np.isnan(q_all).any(axis=1)
    times, q = joints.times[known], q_all[known]
    segments = static_segments(times, q, options.band, options.duration) if len(times) else []
    measured_at = measure.times + options.time_offset
    rows: list[tuple[np.ndarray, np.ndarray, np.ndarray | None, float, float]] = []
    for start, end in segments:
        trim = TRIM * options.duration
        inside = (times >= start + trim) & (times <= end - trim)
        seen = (measured_at >= start + trim) & (measured_at <= end - trim)
        if not seen.any() or not inside.any():
            continue
        quat = None if measure.quaternions is None else mean_quaternion(measure.quaternions[seen])
        points = measure.points[seen]
        rows.append(
            (q[inside].mean(axis=0), points.mean(axis=0), quat, spread_per_axis(points), (start + end) / 2)
        )
    if not rows:
        what = "no static segment" if not segments else f"no measurement on {measure.source} during any"
        raise DataError(
            f"{what} of {options.duration:g} s with the joints within {options.band:g}: "
            "check band=, duration= and time_offset="
        )
    quats = None if rows[0][2] is None else np.array([r[2] for r in rows])
    spread = np.array([r[3] for r in rows])
    data = Dataset(
        chain, np.array([r[0] for r in rows]), np.array([r[1] for r in rows]), quats, spread=spread
    )
    return data, np.array([r[4] for r in rows]), len(segments) - len(rows)


def _measure_source(types: dict[str, str], options: RecordingOptions) -> tuple[str, str]:
    """The measurement topic and its message type.

    Raises:
        DataError: none, or several candidates and no ``measure_topic``.
    """
    wanted = [f"geometry_msgs/{t}Stamped" for t in ("Point", "Pose", "Transform")]
    if options.measure_topic is not None:
        kind = types.get(options.measure_topic)
        if kind not in MEASURE_TYPES:
            found = "not in the recording" if kind is None else f"a {kind}"
            raise DataError(
                f"measure_topic={options.measure_topic} is {found}: give a {', '.join(wanted)} topic"
            )
        return options.measure_topic, kind
    candidates = sorted(t for t, kind in types.items() if kind in MEASURE_TYPES)
    if len(candidates) > 1:
        raise DataError(
            f"the recording has {len(candidates)} candidate measurement topics ({', '.join(candidates)}): "
            "name the one to use with measure_topic="
        )
    if not candidates:
        raise DataError(
            f"the recording has no measurement topic ({', '.join(wanted)}): for a /tf transform, "
            "give measure_frame=PARENT:CHILD"
        )
    return candidates[0], types[candidates[0]]


def _read_series(
    reader: Any, types: dict[str, str], options: RecordingOptions
) -> tuple[JointSeries, MeasureSeries]:
    """The joint states and the measurement of an open recording."""
    if options.measure_frame is not None:
        parent, _, child = options.measure_frame.partition(":")
        tf_topics = [t for t, kind in types.items() if kind == TF]
        if not parent or not child or not tf_topics:
            why = "PARENT:CHILD" if not parent or not child else "a recording with /tf"
            raise DataError(f"measure_frame={options.measure_frame}: needs {why}")
        measure = read_tf(reader, tf_topics, parent.lstrip("/"), child.lstrip("/"))
    else:
        topic, kind = _measure_source(types, options)
        if kind == CALIBRATION_DATA:
            return calibration_snapshots(reader, topic)
        measure = read_measure(reader, topic, kind)
    if types.get(options.joint_topic) != JOINT_STATE:
        states = sorted(t for t, kind in types.items() if kind == JOINT_STATE)
        found = f"joint states are on {', '.join(states)}" if states else "it holds no joint states"
        raise DataError(
            f"the recording has no sensor_msgs/JointState on {options.joint_topic} ({found}): "
            "give joint_topic="
        )
    return read_joints(reader, options.joint_topic), measure


def _clock_warning(joints: JointSeries, measure: MeasureSeries, options: RecordingOptions) -> list[str]:
    """A warning when the two clocks disagree by more than a static segment lasts."""
    lag = _clock_offset(measure.times + options.time_offset, measure.received)
    gap = lag - _clock_offset(joints.times, joints.received)  # what --time-offset should add
    if abs(gap) <= options.duration:
        return []
    return [
        f"the stamps of {measure.source} and of the joint states disagree by {gap:.3g} s against the "
        f"recording time, more than duration={options.duration:g} s: if the measurement's clock is "
        f"off, pass time_offset={options.time_offset + gap:.3g}"
    ]


def read_recording(path: str | Path, joints: Sequence[str] | None, options: RecordingOptions) -> Recording:
    """The static poses of a recording (see the module docstring).

    Args:
        path: a rosbag2 folder, a ``.mcap`` or ``.db3`` file, or a ROS 1 ``.bag``.
        joints: the chain's joints (each must be in the joint states); None: every joint found.
        options: topics, time offset and the static segments' band and duration.

    Raises:
        DataError: no joint states or measurement, several candidate measurement topics, a chain
            joint that the joint states never name, no static pose.
    """
    path = Path(path)
    with open_recording(path) as reader:
        types = topic_types(reader)
        try:
            joint_series, measure = _read_series(reader, types, options)
        except DataError as exc:
            raise DataError(f"{path}: {exc}") from None
    if not options.orientation and measure.quaternions is not None:
        measure = MeasureSeries(measure.source, measure.times, measure.points, None, measure.received)
    chain = tuple(joint_series.names if joints is None else joints)
    missing = [j for j in chain if j not in joint_series.names]
    if missing:
        raise DataError(
            f"{path}: the joint states never name {', '.join(missing)} "
            f"(they name {', '.join(joint_series.names)})"
        )
    if types.get(measure.source) == CALIBRATION_DATA:
        q = joint_series.columns(chain)
        if np.isnan(q).any():
            row = int(np.flatnonzero(np.isnan(q).any(axis=1))[0])
            joints = ", ".join(chain)
            raise DataError(f"{path}: CalibrationData message {row + 1} lacks a chain joint ({joints})")
        data = Dataset(chain, q, measure.points)
        return Recording(data, joint_series.received, measure.source)
    data, times, unseen = segment_poses(joint_series, chain, measure, options)
    warnings = _clock_warning(joint_series, measure, options)
    if unseen:
        warnings.append(f"{unseen} static segment(s) without a measurement on {measure.source} left out")
    return Recording(data, times, measure.source, tuple(warnings))


def read_static_joints(path: str | Path, joints: Sequence[str], options: RecordingOptions) -> np.ndarray:
    """The joint values (N, n) [rad or m] of a recording's static poses, no measurement needed
    (a program run and recorded, for :func:`pincal.export.compensate.compensate_program`).

    Raises:
        DataError: no joint states on the joint topic, a chain joint never named, no static pose.
    """
    path = Path(path)
    with open_recording(path) as reader:
        if topic_types(reader).get(options.joint_topic) != JOINT_STATE:
            raise DataError(f"{path}: no sensor_msgs/JointState on {options.joint_topic}: give joint_topic=")
        series = read_joints(reader, options.joint_topic)
    missing = [j for j in joints if j not in series.names]
    if missing:
        raise DataError(f"{path}: the joint states never name {', '.join(missing)}")
    q_all = series.columns(tuple(joints))
    known = ~np.isnan(q_all).any(axis=1)
    times, q = series.times[known], q_all[known]
    trim = TRIM * options.duration
    segments = static_segments(times, q, options.band, options.duration) if len(times) else []
    poses = [q[(times >= start + trim) & (times <= end - trim)].mean(axis=0) for start, end in segments]
    if not poses:
        raise DataError(
            f"{path}: no static pose of {options.duration:g} s with the joints within {options.band:g}"
        )
    return np.array(poses)
