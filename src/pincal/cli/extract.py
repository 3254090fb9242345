"""``pincal extract``: the static poses of a ROS recording, written as a measurement CSV."""

from __future__ import annotations

import argparse
import csv
import io
from pathlib import Path

from pincal.cli.common import check_outputs, urdf_path
from pincal.cli.recording_data import read_poses
from pincal.data.dataset import Dataset
from pincal.errors import DataError
from pincal.files import atomic_write
from pincal.robot.robots import load_robot


def pose_csv(data: Dataset) -> str:
    """The CSV text of poses: a column per joint [rad or m], ``x,y,z`` [m], ``qw,qx,qy,qz`` with
    orientations, and ``spread_mm``, the measurement's spread over the pose (RMS per axis) [mm]."""
    header = [*data.joint_names, "x", "y", "z", *(("qw", "qx", "qy", "qz") if data.has_orientation else ())]
    header += ["spread_mm"] if data.spread is not None else []
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    for i in range(len(data)):
        row = [*data.q[i], *data.points[i]]
        row += [] if data.quaternions is None else list(data.quaternions[i])
        row += [] if data.spread is None else [data.spread[i] * 1e3]
        writer.writerow([repr(float(v)) for v in row])
    return buffer.getvalue()


def run(args: argparse.Namespace) -> int:
    """Run the command; 0 on success."""
    if len(args.inputs) > 2:
        raise DataError(f"extract takes [ROBOT] RECORDING, got {len(args.inputs)} arguments")
    robot_arg, recording = (None, *args.inputs) if len(args.inputs) == 1 else args.inputs
    if args.tip is not None and robot_arg is None:
        raise DataError("--tip needs ROBOT: pincal extract ROBOT --tip FRAME RECORDING -o poses.csv")
    path = Path(recording)
    check_outputs(args, [args.output], {"recording": path, "input URDF": urdf_path(robot_arg)})
    joints = None if robot_arg is None else load_robot(robot_arg, tip=args.tip).joint_names
    data = read_poses(path, joints, args).data
    atomic_write(args.output, pose_csv(data))
    print(f"{len(data)} poses ({', '.join(data.joint_names)}) written to {args.output}")
    return 0
