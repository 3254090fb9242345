"""The ``pincal`` command line's parser: the sub-commands, their options and the value types."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any, NoReturn

from pincal.cli.data_options import add_lock, add_plausibility_options, add_program_quaternion_order
from pincal.cli.deliver_options import add_baseline_params, add_geometry, add_noise
from pincal.cli.help_groups import group_options, report_option, version
from pincal.cli.numeric import folds, fraction, rotation_weight, seed, sigmas, threads
from pincal.cli.plan_args import add_plan
from pincal.cli.pull_options import add_pull_options
from pincal.cli.recording_args import add_accuracy, add_extract, add_recording_options
from pincal.cli.template import add_template
from pincal.cli.values import mapping, name_list, parameters, payload, tool_points
from pincal.errors import PincalError
from pincal.options import (
    BUNDLED,
    LOSSES,
    MEASURES,
    MODELS,
    ORIENTATIONS,
    ROTATION_WEIGHT,
    THRESHOLD,
    UNITS,
)


class _Parser(argparse.ArgumentParser):
    """argparse whose usage errors are one ``pincal: error:`` line and exit code 2."""

    def error(self, message: str) -> NoReturn:
        raise PincalError(f"{message} (see '{self.prog} --help')")


class _Version(argparse.Action):
    """``--version``: the version is looked up when asked for (its lookup costs every run 40 ms)."""

    def __init__(self, option_strings: list[str], dest: str, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser: argparse.ArgumentParser, *_: Any) -> NoReturn:
        print(f"{parser.prog} {version()}")  # on standard output, as argparse's own action
        parser.exit()


def build_parser() -> argparse.ArgumentParser:
    """The ``pincal`` command line: one sub-command per task."""
    parser = _Parser(prog="pincal", description="Kinematic calibration of robot arms on Pinocchio.")
    parser.add_argument("--version", action=_Version, help="show program's version number and exit")
    parser.add_argument(
        "--threads",
        type=threads,
        default=None,
        help="BLAS threads (default: $PINCAL_THREADS, else 1; 0 leaves BLAS as it is)",
    )
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for add in (_add_calibrate, _add_diagnose, _add_demo, _add_tcp, _add_compensate):
        add(sub)
    add_plan(sub, _add_robot_options, _add_force, add_model)
    _add_twists(sub)
    add_template(sub, _add_robot_options, _add_force)
    add_extract(sub)
    add_accuracy(sub, lambda cmd: _add_robot_options(cmd, inertias=False))
    group_options(parser)  # --help in groups (data, model, automatic choice, output), docs cited
    return parser


def _add_calibrate(sub: Any) -> None:
    """``pincal calibrate``."""
    cal = sub.add_parser("calibrate", help="identify a kinematic model from measurements")
    _add_data_options(cal)
    cal.add_argument("--test", type=Path, help="held-out poses (CSV) for the error after calibration")
    cal.add_argument(
        "--holdout",
        type=fraction,
        help="fraction of the poses to hold out instead of --test (default: none, every pose is fitted)",
    )
    cal.add_argument(
        "--seed", type=seed, default=0, help="seed of the --holdout split and of the cross-validation folds"
    )
    cal.add_argument("--report", type=Path, help="write the JSON report here")
    add_noise(cal)
    cal.add_argument(
        "-o",
        "--output",
        type=Path,
        help="write the corrected URDF here (and NAME.calibration.json); a .yaml name writes a UR "
        "kinematics YAML (ur_description's format) instead",
    )
    cal.add_argument(
        "--add-frame", metavar="NAME", help="with -o: add a fixed frame NAME at the calibrated tool"
    )
    cal.add_argument(
        "--params",
        type=parameters,
        default="auto",
        metavar="auto|all|NAME,...|@FILE",
        help="model parameters to fit: 'auto' (default) chooses them by leave-one-out cross-validation "
        "on the data; 'all' fits every identifiable one; or names (or a file of names, one a line)",
    )
    cal.add_argument(
        "--extend",
        default=None,
        metavar="auto|none|EFFECT:JOINT",
        help="a non-geometric effect to identify too: 'auto' (default; 'none' for --measure points) runs the "
        "diagnosis on the chosen geometry and adds the cause it names if its cross-validated test passes; "
        "'none'; or EFFECT:JOINT",
    )
    add_geometry(cal)
    cal.add_argument("--folds", type=folds, default=5, help="folds of --extend auto's and nested CV")
    cal.add_argument(
        "--nested",
        choices=["auto", "yes", "no"],
        default="auto",
        help="judge the whole choice by nested cross-validation: 'auto' when cheap (default)",
    )
    cal.add_argument("--pairs", choices=["all", "gao"], default="all", help="pairs for --measure distance")
    add_pull_options(cal)  # issue 31
    _add_force(cal)


def _add_diagnose(sub: Any) -> None:
    """``pincal diagnose``."""
    diag = sub.add_parser("diagnose", help="name what the rigid model gets wrong, and the gain")
    _add_data_options(diag)
    report_option(diag, "the diagnosis")
    add_noise(diag)
    diag.add_argument(
        "--plot",
        type=Path,
        metavar="FILE.png",
        help="plot the named cause (or the residual) as a PNG here; a further cause as FILE_2.png, ...",
    )
    diag.add_argument(
        "--plots",
        type=Path,
        metavar="DIR",
        help="write that PNG into this folder (created if missing) as diagnose_CAUSE.png instead",
    )
    diag.add_argument("--folds", type=folds, default=5, help="folds of the cross-validation (2 or more)")
    diag.add_argument("--seed", type=seed, default=0, help="seed of the folds")
    add_baseline_params(diag, parameters)
    _add_force(diag)


def _add_demo(sub: Any) -> None:
    """``pincal demo``."""
    demo = sub.add_parser("demo", help="calibrate bundled data and print before/after tables")
    demo.add_argument("--seed", type=seed, default=0, help="seed of the simulated robot and measurements")


def _add_tcp(sub: Any) -> None:
    """``pincal tcp``."""
    tcp = sub.add_parser("tcp", help="tool centre point and tool frame from flange poses (Xiong 2012)")
    tcp.add_argument(
        "poses", type=Path, help="CSV: x,y,z,a,b,c (deg) or x,y,z,qw,qx,qy,qz, or joints with --robot"
    )
    tcp.add_argument(
        "--orientation",
        choices=ORIENTATIONS,
        default="default",
        help="default: every row touches the TCP point and the tool frame is the flange's; z: the last two "
        "rows are the origin and a move along the tool's +Z (its Z axis); zx: the last three are the "
        "origin, a move along +X and one along +Z (the whole tool frame)",
    )
    tcp.add_argument("--units", choices=sorted(UNITS), default="m", help="unit of x,y,z and of the TCP")
    report_option(tcp, "the result")
    tcp.add_argument("--columns", type=mapping, help="column names of the file, e.g. x=X_mm,y=Y_mm,a=A_deg")
    tcp.add_argument("--robot", help="compute flange poses from joint columns with this robot (URDF or name)")
    tcp.add_argument("--tip", help="with --robot: the flange frame (default: the robot's tip)")
    tcp.add_argument("--degrees", action="store_true", help="with --robot: joint values in degrees")
    _add_robot_options(tcp, "--robot")
    add_lock(tcp)  # issue 31
    add_plausibility_options(tcp)
    _add_force(tcp)


def _add_compensate(sub: Any) -> None:
    """``pincal compensate``."""
    comp = sub.add_parser(
        "compensate", help="joint commands that make the calibrated robot reach the program"
    )
    comp.add_argument(
        "robot",
        help=f"the nominal robot the program was written for: a .urdf or .xacro path or a bundled robot "
        f"({', '.join(BUNDLED)})",
    )
    _add_robot_options(comp)
    comp.add_argument(
        "calibration",
        type=Path,
        help="the corrected URDF or UR kinematics YAML 'calibrate -o' wrote (sidecar beside); a YAML "
        "applies to ROBOT (with --kinematics: the controller's calibration the program was written for)",
    )
    comp.add_argument(
        "program",
        type=Path,
        help="CSV: a column per chain joint, or tool targets x,y,z[,qw,qx,qy,qz]; or a ROS recording of "
        "the program run (its static poses are the commands)",
    )
    comp.add_argument("-o", "--output", type=Path, required=True, help="the compensated program (CSV)")
    comp.add_argument(
        "--task",
        choices=["pose", "position"],
        help="pose (default): the tool's point and orientation where the nominal URDF put them "
        "(x,y,z targets without qw,qx,qy,qz: position); position: the point only, the orientation "
        "moves (the summary says how far)",
    )
    comp.add_argument("--degrees", action="store_true", help="revolute joint values in degrees (in and out)")
    comp.add_argument("--units", choices=sorted(UNITS), default="m", help="unit of x,y,z targets, prismatic")
    add_recording_options(comp, "PROGRAM")
    add_program_quaternion_order(comp)  # issue 31
    _add_force(comp)


#: What each ``--model`` is, for its help.
MODEL_HELP = (
    "the error model: placements (default): 6 errors per joint placement, in the URDF's own joint "
    "frames; poe: product-of-exponentials joint twists; mdh: modified DH with Hayati's beta (5 per "
    "joint); offsets: joint zero offsets only"
)


def add_model(cmd: argparse.ArgumentParser) -> None:
    """``--model``, with what each model is."""
    cmd.add_argument("--model", choices=MODELS, default="placements", help=MODEL_HELP)


def _add_twists(sub: Any) -> None:
    """``pincal twists``."""
    tw = sub.add_parser("twists", help="print the chain's nominal joint twists, checked against Pinocchio")
    tw.add_argument("robot", help=f"a .urdf or .xacro path or a bundled robot ({', '.join(BUNDLED)})")
    tw.add_argument("--tip", help="the last frame of the chain (default: the robot's documented tip)")
    _add_robot_options(tw)


def _add_robot_options(cmd: argparse.ArgumentParser, flag: str = "ROBOT", inertias: bool = True) -> None:
    """How ROBOT is read: a xacro's arguments and packages, a UR kinematics YAML on top, and (with
    ``inertias``, for the commands that compute gravity torques) the masses of another URDF."""
    cmd.add_argument(
        "--xacro-arg",
        action="append",
        default=[],
        metavar="NAME:=VALUE",
        help=f"an argument of a .xacro {flag} (repeatable)",
    )
    cmd.add_argument(
        "--package-path",
        action="append",
        default=[],
        metavar="PKG=DIR",
        help="the folder $(find PKG) means in a xacro (repeatable; else ROS_PACKAGE_PATH is searched)",
    )
    cmd.add_argument(
        "--kinematics",
        type=Path,
        metavar="FILE.yaml",
        help=f"a UR kinematics YAML (ur_description's format) applied on the UR {flag}",
    )
    if not inertias:
        return
    cmd.add_argument(
        "--inertias",
        metavar="URDF",
        help=f"a URDF or bundled robot whose links lend their masses to {flag}'s links of the same "
        "name that have none (gravity torques: compliance and backlash)",
    )


def _add_force(cmd: argparse.ArgumentParser) -> None:
    cmd.add_argument("--force", action="store_true", help="replace output files that exist already")


def _add_data_options(cmd: argparse.ArgumentParser) -> None:
    cmd.add_argument("robot", help=f"a .urdf or .xacro path or a bundled robot ({', '.join(BUNDLED)})")
    _add_robot_options(cmd)
    cmd.add_argument(
        "data",
        type=Path,
        help="measurement CSV (docs/formats.md; 'pincal template' writes its header), a folder of "
        "hole_<name>.csv files, or a ROS recording (docs/recordings.md)",
    )
    cmd.add_argument("--tip", help="the measured frame (default: the robot's documented tip)")
    add_model(cmd)
    cmd.add_argument(
        "--measure",
        choices=MEASURES,
        help="default: points if the CSV has a point column (or DATA is a folder), pose if it has "
        "qw,qx,qy,qz, else position",
    )
    cmd.add_argument(
        "--point-distance",
        metavar="A,B=D[;C,E=F]",
        help="known distances between fixed points, in --units (for example 0,1=50 --units mm)",
    )
    cmd.add_argument("--degrees", action="store_true", help="revolute joint values are in degrees")
    cmd.add_argument("--units", choices=sorted(UNITS), default="m", help="unit of x,y,z and prismatic joints")
    cmd.add_argument(
        "--instrument-frame",
        choices=["unknown", "base"],
        default="unknown",
        help="'base': the data is already in the robot's base frame",
    )
    cmd.add_argument(
        "--tool-point",
        type=tool_points,
        help="the measured point on the tip frame, X,Y,Z (data units); several markers: "
        "LABEL=X,Y,Z;LABEL=X,Y,Z, each on its frame",
    )
    cmd.add_argument(
        "--payload", type=payload, metavar="MASS,X,Y,Z", help="load on the tip [kg; m in the tip frame]"
    )
    cmd.add_argument(
        "--loss", choices=LOSSES, default="linear", help="robust loss for outliers ('linear': least squares)"
    )
    cmd.add_argument(
        "--outliers",
        type=sigmas,
        default=THRESHOLD,
        metavar="SIGMAS",
        help=f"leave out poses whose residual is this many robust std above the others' "
        f"(default {THRESHOLD:g}; 0 keeps every pose)",
    )
    cmd.add_argument(
        "--lock", type=name_list, default=(), metavar="JOINT,...", help="chain joints to hold at neutral"
    )
    cmd.add_argument(
        "--partial", action="store_true", help="fit only what the data identifies when it is not all"
    )
    cmd.add_argument(
        "--rotation-weight",
        type=rotation_weight,
        default=ROTATION_WEIGHT,
        help="weight of orientation residuals for pose data [m/rad] (default 0.1: 1 mrad ~ 0.1 mm)",
    )
    add_plausibility_options(cmd)
    add_recording_options(cmd)
