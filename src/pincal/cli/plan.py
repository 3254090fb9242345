"""``pincal plan``: measurement poses chosen for identifiability."""

from __future__ import annotations

import argparse

from ..data import UNITS
from ..errors import DataError
from ..robots import load_robot
from .common import check_outputs, robot_options, urdf_path


def run(args: argparse.Namespace) -> int:
    """Run the command; 0 on success."""
    from ..planning import plan_poses, write_poses

    check_outputs(args, [args.output], {"input URDF": urdf_path(args.robot)})
    if args.reach is not None and args.instrument is None:
        raise DataError("--reach needs --instrument X,Y,Z (where the instrument stands)")
    robot = load_robot(args.robot, tip=args.tip, **robot_options(args))
    scale = UNITS[args.units]
    plan = plan_poses(
        robot,
        args.poses,
        model=args.model,
        measure=args.measure,
        candidates=args.candidates,
        seed=args.seed,
        tool=None if args.tool_point is None else args.tool_point * scale,
        extension=args.extend,
        clearance=args.clearance,
        reach=None if args.reach is None else args.reach * scale,
        instrument=None if args.instrument is None else args.instrument * scale,
    )
    print(plan.summary())
    write_poses(args.output, plan, args.degrees)
    print(f"written to {args.output}")
    return 0
