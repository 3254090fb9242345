"""``pincal compensate``: joint commands with which the calibrated robot reaches the program."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from pincal.cli.common import check_outputs, robot_options, urdf_path, warn
from pincal.errors import DataError
from pincal.export.urdf_writer import sidecar_path
from pincal.plausibility.verdict import robot_size
from pincal.robot.robots import Robot, load_robot


def run(args: argparse.Namespace) -> int:
    """Run the command; 0 on success."""
    from pincal.cli.recording_data import recording_options, unused_recording_options
    from pincal.data.dataset import csv_columns
    from pincal.data.program import Targets, read_program
    from pincal.data.recording_reader import is_recording
    from pincal.data.recordings import read_static_joints
    from pincal.export.calibrated_robot import load_calibration
    from pincal.export.compensate import compensate_program, write_program

    inputs = {
        "program": args.program,
        "calibration URDF": args.calibration,
        "calibration sidecar": sidecar_path(args.calibration),
    }
    check_outputs(args, [args.output], {**inputs, "input URDF": urdf_path(args.robot)})
    options = robot_options(args)
    description = {k: v for k, v in options.items() if k != "kinematics"}  # a YAML's base robot
    cal = load_calibration(args.calibration, nominal=args.robot, **description)
    nominal = load_robot(args.robot, tip=cal.robot.tip_spec, joints=cal.robot.joint_names, **options)
    program: np.ndarray | Targets
    if is_recording(args.program):  # a program run and recorded: its static poses are the commands
        program = read_static_joints(args.program, nominal.joint_names, recording_options(args))
        print(f"{args.program}: {len(program)} static poses")
    else:
        program = read_program(args.program, nominal, args.degrees, args.units, args.quaternion_order)
        if isinstance(program, Targets):
            check_target_units(program, nominal, args.units)
    header = [] if is_recording(args.program) else csv_columns(args.program)
    unused = unused_recording_options(args, args.program)
    if unused:
        warn(args, f"ignored for a CSV program: {'; '.join(unused)}")
    targets = [c for c in ("x", "y", "z", "qw", "qx", "qy", "qz") if c in header]
    if not isinstance(program, Targets) and targets:
        warn(
            args,
            f"{args.program} has a column per joint and {','.join(targets)}: the joint columns are "
            "the commands, and those columns are not read (drop the joint columns to reach them as targets)",
        )
    result = compensate_program(nominal, cal, program, task=args.task)
    n = len(result.status)
    if not result.ok.any():
        raise DataError(
            f"none of the {n} rows could be compensated ({result.failures()[0]}): check that the "
            "program is for this robot and within its limits"
        )
    write_program(args.output, result, args.degrees, nominal.prismatic, args.units)
    print(result.summary())
    for line in result.failures():
        print(f"  {line}")
    print(f"written to {args.output}")
    return 0


#: Share of the robot's size within which every target of a program lies around the base's origin
#: when its metres were read as millimetres (a real program's targets are the arm's reach away).
INSIDE_BASE = 0.01


def check_target_units(targets: Any, robot: Robot, units: str) -> None:
    """Refuse tool targets that all lie inside the robot's base (within :data:`INSIDE_BASE` of its
    size from the base's origin): no program sends the tool there, metres read with ``--units mm`` do.

    Raises:
        DataError: with the unit that would put them within reach.
    """
    size = robot_size(robot)
    farthest = float(np.linalg.norm(targets.positions, axis=1).max(initial=0.0))
    if farthest >= INSIDE_BASE * size:
        return
    metres = units == "mm" and INSIDE_BASE * size <= farthest * 1e3 <= 2 * size
    hint = "the x,y,z look like metres: drop --units mm" if metres else "check the unit of x,y,z (--units)"
    raise DataError(
        f"every tool target lies within {farthest * 1e3:.3g} mm of the robot's base origin, inside the "
        f"robot ({size:.3g} m in size): {hint}"
    )
