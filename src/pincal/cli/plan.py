"""``pincal plan``: measurement poses chosen for the accuracy of the calibrated robot."""

from __future__ import annotations

import argparse
from typing import Any

from ..data import UNITS, read_joints
from ..errors import DataError
from ..robots import load_robot
from .common import check_outputs, robot_options, urdf_path


def run(args: argparse.Namespace) -> int:
    """Run the command; 0 on success."""
    from ..fixed_points import parse_point_distances
    from ..planning import plan_poses, write_poses

    check_outputs(args, [args.output], {"input URDF": urdf_path(args.robot), "task poses": args.task})
    if args.reach is not None and args.instrument is None:
        raise DataError("--reach needs --instrument X,Y,Z (where the instrument stands)")
    if (args.sockets is not None) != (args.measure == "points"):
        raise DataError("--sockets X,Y,Z;X,Y,Z and --measure points go together: where the ball is held")
    robot = load_robot(args.robot, tip=args.tip, **robot_options(args))
    scale = UNITS[args.units]

    def length(value: Any) -> Any:
        return None if value is None else value * scale

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
        task=None if args.task is None else read_joints(args.task, robot, args.degrees),
        sockets=length(args.sockets),
        point_distances=parse_point_distances(args.point_distance, args.units),
        extension=args.extend,
        clearance=args.clearance,
        reach=length(args.reach),
        instrument=length(args.instrument),
    )
    print(plan.summary())
    write_poses(args.output, plan, args.degrees)
    print(f"written to {args.output}")
    return 0

