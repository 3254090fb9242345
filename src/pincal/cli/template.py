"""``pincal template``: the header of a measurement CSV for a robot, with its units."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pincal.options import BUNDLED, UNITS

#: What adds the shared options to a sub-command (:mod:`pincal.cli.parser`'s).
Adder = Callable[[argparse.ArgumentParser], None]


def add_template(sub: Any, robot_options: Adder, force: Adder) -> None:
    """The ``pincal template`` sub-command and its options (``robot_options``: how ROBOT is
    read; ``force``: ``--force``)."""
    tpl = sub.add_parser("template", help="write the header of a measurement CSV for a robot, to fill")
    tpl.add_argument("robot", help=f"a .urdf or .xacro path or a bundled robot ({', '.join(BUNDLED)})")
    robot_options(tpl)
    tpl.add_argument("--tip", help="the measured frame (default: the robot's documented tip)")
    kind = tpl.add_mutually_exclusive_group()
    kind.add_argument("--pose", action="store_true", help="add qw,qx,qy,qz: the measured orientation")
    kind.add_argument("--points", action="store_true", help="a point column (fixed points) instead of x,y,z")
    tpl.add_argument(
        "--markers",
        type=int,
        metavar="N",
        help="several markers per pose: columns x1,y1,z1 ... xN,yN,zN (with --tip 1=FRAME_A,2=FRAME_B: "
        "one per label of --tip)",
    )
    tpl.add_argument("--degrees", action="store_true", help="revolute joint values in degrees")
    tpl.add_argument("--units", choices=sorted(UNITS), default="m", help="unit of x,y,z and prismatic joints")
    tpl.add_argument("-o", "--output", type=Path, help="write the template here (default: stdout)")
    force(tpl)


def run(args: argparse.Namespace) -> int:
    """Run the command; 0 on success."""
    from pincal.cli.common import check_outputs, robot_options, urdf_path
    from pincal.cli.flags import as_flags
    from pincal.export.template import csv_template
    from pincal.files import atomic_write
    from pincal.robot.robots import load_robot

    check_outputs(args, [args.output], {"input URDF": urdf_path(args.robot)})
    robot = load_robot(args.robot, tip=args.tip, **robot_options(args))
    kind = "pose" if args.pose else "points" if args.points else "position"
    markers = template_markers(args, robot.tip, robot.marker_frames)
    text = as_flags(csv_template(robot, kind, args.units, args.degrees, markers))
    if args.output is None:
        print(text, end="")
        return 0
    atomic_write(args.output, text)
    print(f"template written to {args.output}: fill one row per pose")
    return 0


def template_markers(args: argparse.Namespace, tip: str, frames: dict[str, str]) -> dict[str, str] | None:
    """Each marker's label and frame: ``--tip 1=FRAME_A,2=FRAME_B``'s (``frames``), or for
    ``--markers N`` labels 1..N on the tip; else None.

    Raises:
        DataError: ``--markers`` below 1, or with ``--pose`` or ``--points``, or beside frames per label.
    """
    from pincal.errors import DataError

    if frames and args.markers is not None:
        raise DataError("--tip names the markers and their frames already: drop --markers")
    if frames:
        return dict(frames)
    if args.markers is None:
        return None
    if args.markers < 1:
        raise DataError(f"--markers {args.markers}: give the number of markers per pose, 1 or more")
    if args.pose or args.points:
        raise DataError("--markers is for position data (xK,yK,zK per marker): drop --pose or --points")
    return {str(k): tip for k in range(1, args.markers + 1)}
