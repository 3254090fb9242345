"""Several markers from a ROS recording (issue 41): one measurement topic per marker label.

``measure_topic="1=/tracker/a,2=/tracker/b"`` names each marker's topic (``PointStamped``,
``PoseStamped`` or ``TransformStamped``). The static segments are the joint states' (as for one
marker, :mod:`pincal.data.recordings`); each marker's points are averaged over the segments it
was seen in, and a segment where a marker was not seen leaves it out of that pose (an empty cell
of a ``xK,yK,zK`` CSV). The result is the :class:`~pincal.data.dataset.Dataset` a CSV of several
markers gives: one row per marker seen, the pose's row number kept.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from pincal.data.dataset import Dataset
from pincal.data.directions import move_directions
from pincal.data.recording_reader import (
    JOINT_STATE,
    MEASURE_TYPES,
    JointSeries,
    MeasureSeries,
    open_recording,
    read_joints,
    read_measure,
    topic_types,
)
from pincal.data.recordings import Recording, RecordingOptions, segment_poses
from pincal.errors import DataError

_LABEL = re.compile(r"[A-Za-z0-9]+")


def is_labelled(topic: str | None) -> bool:
    """Whether ``measure_topic`` names a topic per marker label (``1=/a,2=/b``)."""
    return topic is not None and "=" in topic


def labelled_topics(text: str) -> dict[str, str]:
    """``1=/a,2=/b`` -> ``{"1": "/a", "2": "/b"}``.

    Raises:
        DataError: a pair without ``=``, a label not of digits or letters, a label given twice.
    """
    out: dict[str, str] = {}
    for part in text.split(","):
        label, sep, topic = (p.strip() for p in part.partition("="))
        if not sep or not topic or not _LABEL.fullmatch(label) or label in out:
            raise DataError(
                f"measure_topic={text!r}: give LABEL=TOPIC pairs separated by commas, each label once "
                "(digits or letters), for example 1=/tracker/a,2=/tracker/b"
            )
        out[label] = topic
    return out


def read_marker_recording(
    path: str | Path, joints: Sequence[str] | None, options: RecordingOptions
) -> Recording:
    """The static poses of a recording with a measurement topic per marker (module docstring).

    Raises:
        DataError: a topic missing or not a measurement, no joint states, a chain joint the joint
            states never name, a marker never seen during a static segment.
    """
    path = Path(path)
    topics = labelled_topics(str(options.measure_topic))
    with open_recording(path) as reader:
        types = topic_types(reader)
        for label, topic in topics.items():
            if types.get(topic) not in MEASURE_TYPES:
                found = "not in the recording" if topic not in types else f"a {types[topic]}"
                raise DataError(
                    f"{path}: marker {label}'s topic {topic} is {found}: give a measurement topic"
                )
        if types.get(options.joint_topic) != JOINT_STATE:
            raise DataError(f"{path}: no sensor_msgs/JointState on {options.joint_topic}: give joint_topic=")
        series = read_joints(reader, options.joint_topic)
        measures = {label: read_measure(reader, topic, types[topic]) for label, topic in topics.items()}
    chain = tuple(series.names if joints is None else joints)
    missing = [j for j in chain if j not in series.names]
    if missing:
        raise DataError(f"{path}: the joint states never name {', '.join(missing)}")
    return _merged(path, chain, series, measures, options)


def _merged(
    path: Path,
    chain: tuple[str, ...],
    series: JointSeries,
    measures: dict[str, MeasureSeries],
    options: RecordingOptions,
) -> Recording:
    """Each marker's static poses, merged by segment into one dataset of several markers."""
    each = {}
    for label, measure in measures.items():
        if not options.orientation:
            measure = MeasureSeries(measure.source, measure.times, measure.points, None, measure.received)
        try:
            each[label] = segment_poses(series, chain, measure, options)
        except DataError as exc:
            raise DataError(f"{path}: marker {label}: {exc}") from None
    times = np.unique(np.concatenate([t for _, t, _ in each.values()]))
    q = np.empty((len(times), len(chain)))
    rows, markers, points, spread = [], [], [], []
    for k, (data, when, _) in enumerate(each.values()):
        pose = np.searchsorted(times, when)
        q[pose] = data.q
        rows.append(pose)
        markers.append(np.full(len(pose), k))
        points.append(data.points)
        spread.append(data.spread if data.spread is not None else np.zeros(len(pose)))
    pose, marker = np.concatenate(rows), np.concatenate(markers)
    order = np.lexsort((marker, pose))  # pose by pose, markers in the labels' order
    data = Dataset(
        chain,
        q[pose[order]],
        np.concatenate(points)[order],
        rows=pose[order] + 1,
        spread=np.concatenate(spread)[order],
        marker=marker[order],
        marker_names=tuple(measures),
        directions=move_directions(q)[pose[order]],
    )
    sources = ", ".join(f"{label}={m.source}" for label, m in measures.items())
    return replace(Recording(data, times[pose[order]], sources), warnings=())
