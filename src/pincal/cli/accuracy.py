"""``pincal accuracy``: ISO 9283 pose accuracy and repeatability of repeated visits."""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pinocchio as pin

from pincal.accuracy.iso9283 import AccuracyResult, iso9283, too_few_cycles
from pincal.accuracy.visits import (
    Commanded,
    attained_in_base,
    by_model,
    group_visits,
    pose_labels,
    programmed,
)
from pincal.cli.common import check_outputs, load_data, robot_options, urdf_path, warn
from pincal.cli.recording_data import read_poses, unused_recording_options
from pincal.data.dataset import UNITS, Dataset
from pincal.data.recording_reader import is_recording
from pincal.errors import DataError
from pincal.export.calibrated_robot import CalibratedRobot, load_calibration
from pincal.files import atomic_write_many
from pincal.robot.robots import Robot, load_robot

#: ``--pose-tolerance``'s default [rad].
POSE_TOLERANCE = 1e-3
#: The sidecar's suffix: ``--calibration`` may name the sidecar instead of the URDF beside it.
SIDECAR = ".calibration.json"


def _calibration(args: argparse.Namespace) -> CalibratedRobot | None:
    """The calibrated robot of ``--calibration`` (its URDF, or its sidecar), or None."""
    if args.calibration is None:
        return None
    path = args.calibration
    if path.name.endswith(SIDECAR):
        return load_calibration(path.with_name(path.name[: -len(SIDECAR)] + ".urdf"), path)
    return load_calibration(path)


def _visits(args: argparse.Namespace, robot: Robot) -> tuple[Dataset, list[str]]:
    """The visits and the pose each visits: a CSV's pose column, or a recording's grouped poses."""
    if is_recording(args.data):
        data = read_poses(args.data, robot.joint_names, args).data
        return data, group_visits(data.q, args.pose_tolerance)
    data = load_data(args.data, robot, args)
    if args.measure == "position":
        data = replace(data, quaternions=None)
    return data, pose_labels(args.data)


def _commanded(
    args: argparse.Namespace, robot: Robot, cal: CalibratedRobot | None, data: Dataset
) -> tuple[str, Commanded]:
    """What was commanded: the programmed positions, else the calibrated or nominal model's."""
    program = None if is_recording(args.data) else programmed(args.data, args.units)
    if program is not None:
        return "programmed", Commanded(program)
    if cal is not None:
        return "calibrated_model", by_model(cal, data.q, cal.tool)
    point = np.zeros(3) if args.tool_point is None else args.tool_point * UNITS[args.units]
    return "nominal_model", by_model(robot, data.q, pin.SE3(np.eye(3), point))


def figures(args: argparse.Namespace) -> AccuracyResult:
    """The ISO 9283 figures of the command line's data."""
    cal = _calibration(args)
    if cal is not None and args.tip is not None and args.tip != cal.robot.tip:
        raise DataError(f"--tip {args.tip}: the calibration {args.calibration} is of the tip {cal.robot.tip}")
    robot = cal.robot if cal is not None else load_robot(args.robot, tip=args.tip, **robot_options(args))
    if cal is not None and args.tool_point is not None:
        warn(args, "--tool-point ignored: the calibration holds the tool")
    data, labels = _visits(args, robot)
    attained, rotations = attained_in_base(data, None if cal is None else cal.instrument_T_base)
    command, commanded = _commanded(args, robot, cal, data)
    if rotations is None or commanded.rotations is None:
        rotations = None
    return iso9283(labels, commanded.positions, attained, command, commanded.rotations, rotations)


def run(args: argparse.Namespace) -> int:
    """Run the command; 0 on success."""
    inputs = {"data file": args.data, "input URDF": urdf_path(args.robot), "calibration": args.calibration}
    check_outputs(args, [args.report, args.plot], inputs)
    result = figures(args)
    unused = unused_recording_options(args, args.data)
    if not is_recording(args.data) and args.pose_tolerance != POSE_TOLERANCE:
        unused.append("--pose-tolerance (ROS recordings only)")
    if unused:
        warn(args, f"ignored for a CSV: {'; '.join(unused)}")
    few = too_few_cycles(result)
    if few is not None:
        warn(args, few)
    print(result.table())
    files: list[tuple[str | Path, str | bytes]] = []
    if args.plot is not None:
        from pincal.accuracy.accuracy_plot import accuracy_png

        files.append((args.plot, accuracy_png(result)))
    if args.report is not None:
        report = {
            "robot": args.robot,
            "data": str(args.data),
            "calibration": None if args.calibration is None else str(args.calibration),
            "iso9283": result.to_dict(),
        }
        files.append((args.report, json.dumps(report, indent=2) + "\n"))
    atomic_write_many(files)  # every output or none
    for path, _ in files:
        print(f"written to {path}")
    return 0
