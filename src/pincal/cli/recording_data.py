"""A ROS recording given where a measurement CSV is accepted: its static poses as a
:class:`pincal.data.dataset.Dataset`, read with the command's recording options."""

from __future__ import annotations

import argparse
from pathlib import Path

from pincal.cli.recording_args import DEFAULTS
from pincal.data.dataset import Dataset
from pincal.data.marker_recordings import is_labelled, read_marker_recording
from pincal.data.recording_reader import is_recording
from pincal.data.recordings import Recording, RecordingOptions, read_recording
from pincal.errors import DataError


def recording_options(args: argparse.Namespace) -> RecordingOptions:
    """The :class:`pincal.data.recordings.RecordingOptions` of the command line."""
    return RecordingOptions(
        joint_topic=args.joint_topic,
        measure_topic=args.measure_topic,
        measure_frame=args.measure_frame,
        time_offset=args.time_offset,
        band=args.static_band,
        duration=args.static_time,
        orientation=getattr(args, "measure", None) == "pose",
    )


def read_poses(path: Path, joints: tuple[str, ...] | None, args: argparse.Namespace) -> Recording:
    """The static poses of the recording at ``path``, its warnings kept for the end of the command.

    Raises:
        DataError: ``--degrees`` or ``--units mm`` (a recording holds radians and metres), or the
            recording cannot give poses (:func:`pincal.data.recordings.read_recording`).
    """
    if getattr(args, "degrees", False) or getattr(args, "units", "m") != "m":
        raise DataError(
            f"{path}: a ROS recording holds radians and metres (REP 103): drop --degrees and --units"
        )
    options = recording_options(args)
    reader = read_marker_recording if is_labelled(options.measure_topic) else read_recording
    recording = reader(path, joints, options)
    args.__dict__.setdefault("warnings", []).extend(f"{path}: {w}" for w in recording.warnings)
    print(f"{path}: {recording.data.n_poses} static poses, measured on {recording.source}")
    return recording


def recording_data(path: Path, joints: tuple[str, ...], args: argparse.Namespace) -> Dataset:
    """The poses of a recording for the chain's ``joints``, as a CSV would give them."""
    return read_poses(path, joints, args).data


def unused_recording_options(args: argparse.Namespace, *read: str | Path | None) -> list[str]:
    """The recording options given when none of the inputs ``read`` (default: DATA and ``--test``)
    is a recording."""
    given_inputs = read or (getattr(args, "data", None), getattr(args, "test", None))
    inputs = [p for p in given_inputs if p is not None]
    if any(is_recording(p) for p in inputs):
        return []
    given = [name for name, default in DEFAULTS.items() if getattr(args, name, default) != default]
    return [f"--{name.replace('_', '-')} (ROS recordings only)" for name in given]
