"""``pincal plan``'s options: which poses to measure for the accuracy of the calibrated robot."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from pincal.cli.numeric import count, height, reach, seed
from pincal.cli.values import vector3, vectors3
from pincal.options import BUNDLED, MEASURES, MODELS, UNITS


def add_plan(
    sub: Any,
    robot_options: Callable[[Any], None],
    force: Callable[[Any], None],
    model: Callable[[Any], None] | None = None,
) -> None:
    """``pincal plan`` (``robot_options``, ``force``, ``model``: the parser's shared option adders)."""
    plan = sub.add_parser("plan", help="choose measurement poses for the accuracy of the calibrated robot")
    plan.add_argument("robot", help=f"a .urdf or .xacro path or a bundled robot ({', '.join(BUNDLED)})")
    robot_options(plan)
    plan.add_argument("--tip", help="the measured frame (default: the robot's documented tip)")
    plan.add_argument("--poses", type=count, required=True, help="number of poses to measure")
    if model is not None:
        model(plan)
    else:
        plan.add_argument(
            "--model", choices=MODELS, default="placements", help="the error model to calibrate"
        )
    plan.add_argument(
        "--measure", choices=MEASURES, default="position", help="what the instrument will measure"
    )
    plan.add_argument(
        "--candidates", type=count, default=1000, help="random feasible candidates to choose from"
    )
    plan.add_argument("--seed", type=seed, default=0, help="seed of the random candidates")
    plan.add_argument(
        "--units",
        choices=sorted(UNITS),
        default="m",
        help="unit of the lengths given below (--tool-point, --tool-tolerance, --sockets, --point-distance, "
        "--clearance, --instrument, --reach) and of prismatic joints in --task and -o",
    )
    plan.add_argument(
        "--criterion",
        choices=("i", "d"),
        default="i",
        help="i: least mean squared error of the calibrated tip over the task poses (default); "
        "d: largest log det of the information",
    )
    plan.add_argument(
        "--task",
        type=Path,
        help="CSV of the poses the robot will work in, a column per joint (default: its whole workspace)",
    )
    plan.add_argument(
        "--tool-point", type=vector3, help="the measured point on the tip, X,Y,Z, roughly [units]"
    )
    plan.add_argument(
        "--tool-tolerance",
        type=reach,
        help="how far the real point may be from --tool-point [units] (default 0.01 m; 0.1 m from the tip)",
    )
    plan.add_argument(
        "--sockets", type=vectors3, help="with --measure points: where the sockets are, X,Y,Z;X,Y,Z [units]"
    )
    plan.add_argument(
        "--point-distance", metavar="A,B=D[;...]", help="with --sockets: known distances between them [units]"
    )
    plan.add_argument(
        "--clearance", type=height, help="height above the floor z = 0 [units] (default 0.05 m)"
    )
    plan.add_argument(
        "--instrument", type=vector3, help="with --reach: instrument position X,Y,Z in the base frame [units]"
    )
    plan.add_argument("--reach", type=reach, help="with --instrument: its range [units]")
    plan.add_argument("--extend", metavar="EFFECT:JOINT", help="plan for a non-geometric effect too")
    plan.add_argument(
        "--degrees",
        action="store_true",
        help="revolute joint values in degrees: those read from --task and those written to -o",
    )
    plan.add_argument("-o", "--output", type=Path, required=True, help="the poses (CSV, a column per joint)")
    force(plan)
