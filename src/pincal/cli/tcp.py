"""``pincal tcp``: tool centre point and tool frame from flange poses (Xiong et al. 2012)."""

from __future__ import annotations

import argparse

import numpy as np

from pincal.cli.common import check_outputs, locked_robot, urdf_path, warn
from pincal.cli.flags import as_flags
from pincal.data.dataset import UNITS
from pincal.errors import DataError, ImplausibleError
from pincal.files import atomic_write
from pincal.json_text import json_text
from pincal.tool.flange_poses import read_flange_poses
from pincal.tool.plausibility import judge_tool
from pincal.tool.tcp import calibrate_tool


def run(args: argparse.Namespace) -> int:
    """Run the command; 0 on success."""
    check_outputs(args, [args.json], {"poses file": args.poses, "input URDF": urdf_path(args.robot)})
    _robot_only(args)
    _inapplicable(args)
    robot = locked_robot(args) if args.robot else None
    rotations, positions = read_flange_poses(
        args.poses, args.units, args.columns, robot, args.degrees, args.quaternion_order
    )
    tool = calibrate_tool(rotations, positions, args.orientation, scale=1.0 / UNITS[args.units])
    u = args.units
    print(f"TCP in the flange frame: ({', '.join(f'{v:.4f}' for v in tool.tcp)}) {u}")
    print(f"  std: ({', '.join(f'{v:.4f}' for v in tool.tcp_std)}) {u}")
    print(f"  fit error δ (eq. 10): {tool.fit_error:.4f} {u}")
    print(f"  condition number of the TCP poses: {tool.condition_number:.3g}")
    for row, (res, suspect) in enumerate(zip(tool.residuals, tool.suspects), start=1):
        flag = "   <- far from the others (fit without it): re-teach this pose?" if suspect else ""
        print(f"  pose {row}: TCP point off the others' common point by {res:.4f} {u}{flag}")
    print(f"tool orientation ({args.orientation}), flange_R_tool:")
    for line in tool.rotation:
        print("  " + " ".join(f"{v:9.5f}" for v in line))
    for warning in tool.warnings:
        warn(args, warning)
    verdict = judge_tool(tool, rotations, positions, args.orientation, robot, 1.0 / UNITS[args.units], u)
    if not verdict.plausible:
        if not args.accept_implausible:
            raise ImplausibleError(verdict.message())
        warn(args, verdict.warning())
    if args.json is not None:
        result = {
            "tcp": tool.tcp.tolist(),
            "rotation": tool.rotation.tolist(),
            "fit_error": tool.fit_error,
            "units": u,
            "tcp_std": tool.tcp_std.tolist(),
            "point": tool.point.tolist(),
            "residuals": tool.residuals.tolist(),
            "suspect_poses": [int(i) + 1 for i in np.flatnonzero(tool.suspects)],
            "condition_number": tool.condition_number,
            "orientation": args.orientation,
            "warnings": list(tool.warnings),
            "plausibility": verdict.to_dict(),
        }
        atomic_write(args.json, as_flags(json_text(result)))
        print(f"written to {args.json}")
    return 0


def _inapplicable(args: argparse.Namespace) -> None:
    """Refuse the options ``tcp`` would ignore in silence (issue 33): ``--inertias`` (no gravity
    torque is computed) and ``--quaternion-order`` for poses without quaternion columns."""
    from pincal.data.dataset import csv_columns

    named = ["--inertias"] if args.inertias is not None else []
    if args.quaternion_order != "wxyz":
        quaternion = {(args.columns or {}).get(c, c) for c in ("qw", "qx", "qy", "qz")}
        if args.robot is not None or not quaternion <= set(csv_columns(args.poses)):
            named.append("--quaternion-order (the poses have no quaternion columns)")
    if named:
        raise DataError(f"{'; '.join(named)}: not used by pincal tcp on these poses: drop it")


def _robot_only(args: argparse.Namespace) -> None:
    """Refuse the options that read joint columns with a robot when there is no ``--robot``
    (they would be ignored, and the poses read as flange poses)."""
    if args.robot is not None:
        return
    given = {
        "--tip": args.tip is not None,
        "--degrees": args.degrees,
        "--xacro-arg": bool(args.xacro_arg),
        "--package-path": bool(args.package_path),
        "--kinematics": args.kinematics is not None,
        "--lock": bool(args.lock),
    }
    named = [flag for flag, on in given.items() if on]
    if named:
        degrees = " (the angles a,b,c are in degrees without it)" if args.degrees else ""
        raise DataError(
            f"{', '.join(named)}: only with --robot ROBOT, which reads joint columns: give --robot, "
            f"or drop {' '.join(named)}{degrees}"
        )
