"""The ``pincal`` command line's parser: the sub-commands, their options and the value types."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from ..errors import PincalError
from ..options import BUNDLED, LOSSES, MEASURES, MODELS, ORIENTATIONS, QUATERNION_ORDERS, THRESHOLD, UNITS


class _Parser(argparse.ArgumentParser):
    """argparse whose usage errors are one ``pincal: error:`` line and exit code 2."""

    def error(self, message: str) -> NoReturn:
        raise PincalError(f"{message} (see '{self.prog} --help')")


def _whole(text: str, minimum: int, what: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < minimum:
        raise argparse.ArgumentTypeError(f"{what} is {minimum} or more, got {value}")
    return value


def _folds(text: str) -> int:
    return _whole(text, 2, "the number of cross-validation folds")


def _seed(text: str) -> int:
    return _whole(text, 0, "a seed")


def _payload(text: str) -> Any:
    from ..effects import Payload  # here: --help does not load Pinocchio

    return Payload.parse(text)


def _vector3(text: str) -> Any:
    import numpy as np  # here: --help does not load NumPy

    try:
        values = np.array([float(v) for v in text.split(",")])
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y,Z numbers, got {text!r}") from None
    if values.shape != (3,) or not np.all(np.abs(values) < 1e6):
        raise argparse.ArgumentTypeError(f"expected three finite numbers X,Y,Z (below 1e6), got {text!r}")
    return values


def build_parser() -> argparse.ArgumentParser:
    """The ``pincal`` command line: one sub-command per task."""
    parser = _Parser(prog="pincal", description="Kinematic calibration of robot arms on Pinocchio.")
    parser.add_argument(
        "--threads",
        type=lambda text: _whole(text, 0, "--threads"),
        default=None,
        help="BLAS threads (default: $PINCAL_THREADS, else 1; 0 leaves BLAS as it is)",
    )
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for add in (_add_calibrate, _add_diagnose, _add_demo, _add_tcp, _add_compensate, _add_plan, _add_twists):
        add(sub)
    return parser


def _add_calibrate(sub: Any) -> None:
    """``pincal calibrate``."""
    cal = sub.add_parser("calibrate", help="identify a kinematic model from measurements")
    _add_data_options(cal)
    cal.add_argument("--test", type=Path, help="held-out poses (CSV) for the error after calibration")
    cal.add_argument("--holdout", type=float, help="fraction of the poses to hold out instead of --test")
    cal.add_argument("--seed", type=_seed, default=0, help="seed of the --holdout split")
    cal.add_argument("--report", type=Path, help="write the JSON report here")
    cal.add_argument(
        "-o", "--output", type=Path, help="write the corrected URDF here (and NAME.calibration.json)"
    )
    cal.add_argument(
        "--add-frame", metavar="NAME", help="with -o: add a fixed frame NAME at the calibrated tool"
    )
    cal.add_argument(
        "--params",
        type=_params,
        default="auto",
        metavar="auto|all|NAME,...|@FILE",
        help="model parameters to fit: 'auto' (default) chooses them by leave-one-out cross-validation "
        "on the data; 'all' fits every identifiable one; or names (or a file of names, one a line)",
    )
    cal.add_argument(
        "--extend",
        default="none",
        metavar="auto|none|EFFECT:JOINT",
        help="a non-geometric effect to identify too: 'auto' runs the diagnosis on the chosen geometry "
        "and adds the cause it names, if its test passes; 'none' (default); or EFFECT:JOINT",
    )
    cal.add_argument(
        "--folds", type=_folds, default=5, help="folds of --extend auto's and the nested cross-validation"
    )
    cal.add_argument(
        "--nested",
        choices=["auto", "yes", "no"],
        default="auto",
        help="judge the whole choice by nested cross-validation: 'auto' when cheap (default)",
    )
    cal.add_argument(
        "--pairs", choices=["all", "gao"], default="all", help="pose pairs for --measure distance"
    )
    _add_force(cal)


def _add_diagnose(sub: Any) -> None:
    """``pincal diagnose``."""
    diag = sub.add_parser("diagnose", help="name what the rigid model gets wrong, and the gain")
    _add_data_options(diag)
    diag.add_argument("--json", type=Path, help="write the diagnosis as JSON here")
    diag.add_argument("--plots", type=Path, metavar="DIR", help="write a PNG of the named cause here")
    diag.add_argument("--folds", type=_folds, default=5, help="folds of the cross-validation (2 or more)")
    diag.add_argument("--seed", type=_seed, default=0, help="seed of the folds")
    diag.add_argument(
        "--params",
        type=_params,
        default="all",
        metavar="all|auto|NAME,...|@FILE",
        help="the geometric baseline's parameters: 'all' (default), 'auto' or names",
    )
    _add_force(diag)


def _add_demo(sub: Any) -> None:
    """``pincal demo``."""
    demo = sub.add_parser("demo", help="calibrate bundled data and print before/after tables")
    demo.add_argument("--seed", type=_seed, default=0)


def _add_tcp(sub: Any) -> None:
    """``pincal tcp``."""
    tcp = sub.add_parser("tcp", help="tool centre point and tool frame from flange poses (Xiong 2012)")
    tcp.add_argument(
        "poses", type=Path, help="CSV: x,y,z,a,b,c (deg) or x,y,z,qw,qx,qy,qz, or joints with --robot"
    )
    tcp.add_argument("--orientation", choices=ORIENTATIONS, default="default")
    tcp.add_argument("--units", choices=sorted(UNITS), default="m", help="unit of x,y,z and of the TCP")
    tcp.add_argument("--json", type=Path, help="write the result as JSON here")
    tcp.add_argument("--columns", type=_mapping, help="column names of the file, e.g. x=X_mm,y=Y_mm,a=A_deg")
    tcp.add_argument("--robot", help="compute flange poses from joint columns with this robot (URDF or name)")
    tcp.add_argument("--tip", help="with --robot: the flange frame (default: the robot's tip)")
    tcp.add_argument("--degrees", action="store_true", help="with --robot: joint values in degrees")
    _add_plausibility_options(tcp)
    _add_force(tcp)


def _add_compensate(sub: Any) -> None:
    """``pincal compensate``."""
    comp = sub.add_parser(
        "compensate", help="joint commands that make the calibrated robot reach the program"
    )
    comp.add_argument("robot", help="the nominal robot the program was written for (URDF or bundled name)")
    comp.add_argument(
        "calibration", type=Path, help="the corrected URDF 'calibrate -o' wrote (sidecar beside)"
    )
    comp.add_argument(
        "program", type=Path, help="CSV: a column per chain joint, or tool targets x,y,z[,qw,qx,qy,qz]"
    )
    comp.add_argument("-o", "--output", type=Path, required=True, help="the compensated program (CSV)")
    comp.add_argument("--task", choices=["pose", "position"], help="default: pose after pose data")
    comp.add_argument("--degrees", action="store_true", help="revolute joint values in degrees (in and out)")
    comp.add_argument("--units", choices=sorted(UNITS), default="m", help="unit of x,y,z targets, prismatic")
    _add_force(comp)


def _add_plan(sub: Any) -> None:
    """``pincal plan``."""
    plan = sub.add_parser("plan", help="choose measurement poses for identifiability (D-optimal)")
    plan.add_argument("robot", help=f"a .urdf path or a bundled robot ({', '.join(BUNDLED)})")
    plan.add_argument("--tip", help="the measured frame (default: the robot's documented tip)")
    plan.add_argument("--poses", type=int, required=True, help="number of poses to measure")
    plan.add_argument("--model", choices=MODELS, default="placements")
    plan.add_argument("--measure", choices=MEASURES, default="position")
    plan.add_argument(
        "--candidates", type=int, default=1000, help="random feasible candidates to choose from"
    )
    plan.add_argument("--seed", type=_seed, default=0)
    plan.add_argument("--units", choices=sorted(UNITS), default="m", help="unit of lengths given below")
    plan.add_argument("--tool-point", type=_vector3, help="the measured point on the tip, X,Y,Z (if known)")
    plan.add_argument("--clearance", type=float, default=0.05, help="height above the floor z = 0 [m]")
    plan.add_argument("--instrument", type=_vector3, help="instrument position X,Y,Z in the base frame")
    plan.add_argument("--reach", type=float, help="with --instrument: its range [units]")
    plan.add_argument("--extend", metavar="EFFECT:JOINT", help="plan for a non-geometric effect too")
    plan.add_argument("--degrees", action="store_true", help="write revolute joint values in degrees")
    plan.add_argument("-o", "--output", type=Path, required=True, help="the poses (CSV, a column per joint)")
    _add_force(plan)


def _add_twists(sub: Any) -> None:
    """``pincal twists``."""
    tw = sub.add_parser("twists", help="print the chain's nominal joint twists, checked against Pinocchio")
    tw.add_argument("robot")
    tw.add_argument("--tip")


def _params(text: str) -> str | tuple[str, ...]:
    """``auto``, ``all``, ``NAME,NAME,...`` or ``@FILE`` (names one a line or comma separated;
    ``#`` starts a comment)."""
    if text in ("auto", "all"):
        return text
    if text.startswith("@"):
        path = Path(text[1:])
        try:
            lines = path.read_text().splitlines()
        except (OSError, UnicodeDecodeError) as exc:
            raise argparse.ArgumentTypeError(f"cannot read the parameter list {path}: {exc}") from None
        names = _names(",".join(line.split("#", 1)[0] for line in lines))
    else:
        names = _names(text)
    if not names:
        raise argparse.ArgumentTypeError(f"expected auto, all, names or @FILE, got {text!r}")
    return names


def _add_force(cmd: argparse.ArgumentParser) -> None:
    cmd.add_argument("--force", action="store_true", help="replace output files that exist already")


def _add_data_options(cmd: argparse.ArgumentParser) -> None:
    cmd.add_argument("robot", help=f"a .urdf path or a bundled robot ({', '.join(BUNDLED)})")
    cmd.add_argument(
        "data", type=Path, help="measurement CSV (see contracts.md), or a folder of hole_<name>.csv files"
    )
    cmd.add_argument("--tip", help="the measured frame (default: the robot's documented tip)")
    cmd.add_argument("--model", choices=MODELS, default="placements")
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
        "--tool-point", type=_vector3, help="the measured point on the tip frame, X,Y,Z (data units)"
    )
    cmd.add_argument(
        "--payload", type=_payload, metavar="MASS,X,Y,Z", help="load on the tip [kg; m in the tip frame]"
    )
    cmd.add_argument("--loss", choices=LOSSES, default="linear", help="robust loss for outliers")
    cmd.add_argument(
        "--outliers",
        type=float,
        default=THRESHOLD,
        metavar="SIGMAS",
        help=f"leave out poses whose residual is this many robust std above the others' "
        f"(default {THRESHOLD:g}; 0 keeps every pose)",
    )
    cmd.add_argument(
        "--lock", type=_names, default=(), metavar="JOINT,...", help="chain joints to hold at neutral"
    )
    cmd.add_argument(
        "--partial", action="store_true", help="fit only what the data identifies when it is not all"
    )
    cmd.add_argument(
        "--rotation-weight",
        type=float,
        default=0.1,
        help="weight of orientation residuals for pose data [m/rad] (default 0.1: 1 mrad ~ 0.1 mm)",
    )
    _add_plausibility_options(cmd)


def _add_plausibility_options(cmd: argparse.ArgumentParser) -> None:
    cmd.add_argument(
        "--quaternion-order",
        choices=QUATERNION_ORDERS,
        default="wxyz",
        help="wxyz (default): the columns qw,qx,qy,qz hold what their names say; xyzw: the four "
        "quaternion columns, left to right, hold x, y, z, w (data exported as x,y,z,w)",
    )
    cmd.add_argument(
        "--accept-implausible",
        action="store_true",
        help="keep a result that no rigid arm can be (a warning instead of an error)",
    )


def _names(text: str) -> tuple[str, ...]:
    return tuple(n.strip() for n in text.split(",") if n.strip())


def _mapping(text: str) -> dict[str, str]:
    try:
        pairs = [item.split("=", 1) for item in text.split(",")]
        return {k.strip(): v.strip() for k, v in pairs}
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected NAME=COLUMN pairs separated by commas, got {text!r}"
        ) from None


def attach_vectors(argv: Sequence[str]) -> list[str]:
    """Write ``--tool-point -1,2,3`` as ``--tool-point=-1,2,3`` (also ``--instrument``): argparse
    takes ``-1,2,3`` for an option."""
    out: list[str] = []
    for arg in argv:
        if out and out[-1] in ("--tool-point", "--instrument") and arg.startswith("-"):
            out[-1] = f"{out[-1]}={arg}"
        else:
            out.append(arg)
    return out
