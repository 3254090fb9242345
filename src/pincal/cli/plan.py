"""``pincal plan``: measurement poses chosen for the accuracy of the calibrated robot."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from pincal.cli.common import check_outputs, end_progress, progress_line, robot_options, urdf_path, warn
from pincal.data.checks import check_limits
from pincal.data.dataset import UNITS, Dataset
from pincal.data.program import read_joints
from pincal.errors import DataError
from pincal.robot.robots import Robot, load_robot

#: ``--clearance`` when not given [m].
CLEARANCE = 0.05


def run(args: argparse.Namespace) -> int:
    """Run the command; 0 on success."""
    from pincal.identify.fixed_points import parse_point_distances
    from pincal.planning.plan import plan_poses, write_poses

    check_outputs(args, [args.output], {"input URDF": urdf_path(args.robot), "task poses": args.task})
    if args.reach is not None and args.instrument is None:
        raise DataError("--reach needs --instrument X,Y,Z (where the instrument stands)")
    if (args.sockets is not None) != (args.measure == "points"):
        raise DataError("--sockets X,Y,Z;X,Y,Z and --measure points go together: where the ball is held")
    check_applicable(args)
    robot = load_robot(args.robot, tip=args.tip, **robot_options(args))
    scale = UNITS[args.units]

    def length(value: Any) -> Any:
        return None if value is None else value * scale

    points = args.measure == "points"
    progress = progress_line("planning")
    plan = plan_poses(
        robot,
        args.poses,
        model=args.model,
        measure=args.measure,
        criterion=args.criterion,
        candidates=args.candidates,
        seed=args.seed,
        tool=length(args.tool_point),
        tool_tolerance=length(args.tool_tolerance),
        task=None if args.task is None else read_task(args.task, robot, args),
        sockets=length(args.sockets),
        point_distances=parse_point_distances(args.point_distance, args.units) if points else (),
        extension=args.extend,
        clearance=CLEARANCE if args.clearance is None else args.clearance * scale,
        reach=length(args.reach),
        instrument=length(args.instrument) if args.reach is not None else None,
        progress=progress,
    )
    end_progress(progress)
    print(plan.summary())
    for text in plan.warnings:
        warn(args, text)
    write_poses(args.output, plan, args.degrees, args.units)
    print(f"written to {args.output}")
    return 0


def check_applicable(args: argparse.Namespace) -> None:
    """Warn of options that would have no effect, instead of ignoring them in silence."""
    if args.instrument is not None and args.reach is None:
        warn(args, "ignored: --instrument (it only centres --reach, the instrument's range)")
    if args.point_distance is not None and args.measure != "points":
        warn(args, "ignored: --point-distance (fixed-point data only: --measure points --sockets)")


def read_task(path: Path, robot: Robot, args: argparse.Namespace) -> np.ndarray:
    """The task poses (T, n) [rad or m] of ``--task``, checked against the joint limits as
    ``calibrate`` checks its data: refused far beyond them, said a little beyond.

    Raises:
        DataError: missing file or columns, non-numeric cells, a value outside the limits.
    """
    q = read_joints(path, robot, args.degrees, args.units)  # prismatic joints in --units, as -o writes them
    try:
        beyond = check_limits(robot, Dataset(robot.joint_names, q, np.zeros((len(q), 3))), args.degrees)
    except DataError as exc:
        raise DataError(f"--task {path}: {exc}") from None
    if beyond:
        warn(args, f"--task {path}: {beyond} joint value(s) beyond the URDF limits, kept as given")
    return q
