"""The ``pincal`` command line.

Exit codes: 0 success; 2 unusable input, with one ``pincal: error: ...`` line on stderr; 1 a bug.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

import numpy as np
import pinocchio as pin

from .checks import check_columns, check_limits, check_scale
from .data import UNITS, Dataset, atomic_write, csv_columns, read_csv
from .effects import Extension, Payload
from .errors import DataError, PincalError
from .measurements import MEASURES
from .models import MODELS
from .outliers import THRESHOLD
from .robots import BUNDLED, Robot, bundled_urdf, load_robot
from .solver import LOSSES, calibrate
from .tool import ORIENTATIONS, calibrate_tool, read_flange_poses
from .urdf_writer import check_frame_name, sidecar_path, write_corrected_urdf


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


def _vector3(text: str) -> np.ndarray:
    try:
        values = np.array([float(v) for v in text.split(",")])
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y,Z numbers, got {text!r}") from None
    if values.shape != (3,) or not np.all(np.abs(values) < 1e6):
        raise argparse.ArgumentTypeError(f"expected three finite numbers X,Y,Z (below 1e6), got {text!r}")
    return values


def _build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="pincal", description="Kinematic calibration of robot arms on Pinocchio.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

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
        "--extend", metavar="EFFECT:JOINT", help="identify a non-geometric effect too (as diagnose names it)"
    )
    cal.add_argument(
        "--pairs", choices=["all", "gao"], default="all", help="pose pairs for --measure distance"
    )
    _add_force(cal)

    diag = sub.add_parser("diagnose", help="name what the rigid model gets wrong, and the gain")
    _add_data_options(diag)
    diag.add_argument("--json", type=Path, help="write the diagnosis as JSON here")
    diag.add_argument("--plots", type=Path, metavar="DIR", help="write a PNG of the named cause here")
    diag.add_argument("--folds", type=_folds, default=5, help="folds of the cross-validation (2 or more)")
    diag.add_argument("--seed", type=_seed, default=0, help="seed of the folds")
    _add_force(diag)

    demo = sub.add_parser("demo", help="calibrate bundled data and print before/after tables")
    demo.add_argument("--seed", type=_seed, default=0)

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
    _add_force(tcp)

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

    tw = sub.add_parser("twists", help="print the chain's nominal joint twists, checked against Pinocchio")
    tw.add_argument("robot")
    tw.add_argument("--tip")
    return parser


def _urdf_path(robot: str | None) -> Path | None:
    """The URDF file a ROBOT argument names (bundled robots included)."""
    if robot is None:
        return None
    return bundled_urdf(robot) if robot in BUNDLED else Path(robot)


def _add_force(cmd: argparse.ArgumentParser) -> None:
    cmd.add_argument("--force", action="store_true", help="replace output files that exist already")


def _add_data_options(cmd: argparse.ArgumentParser) -> None:
    cmd.add_argument("robot", help=f"a .urdf path or a bundled robot ({', '.join(BUNDLED)})")
    cmd.add_argument("data", type=Path, help="measurement CSV (see contracts.md)")
    cmd.add_argument("--tip", help="the measured frame (default: the robot's documented tip)")
    cmd.add_argument("--model", choices=MODELS, default="placements")
    cmd.add_argument(
        "--measure", choices=MEASURES, help="default: pose if the CSV has qw,qx,qy,qz, else position"
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
        "--payload", type=Payload.parse, metavar="MASS,X,Y,Z", help="load on the tip [kg; m in the tip frame]"
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


def _names(text: str) -> tuple[str, ...]:
    return tuple(n.strip() for n in text.split(",") if n.strip())


def _robot(args: argparse.Namespace) -> Robot:
    """The chain; every chain joint needs a column in the data unless ``--lock`` holds it."""
    chain = load_robot(args.robot, tip=args.tip)
    unknown = [j for j in args.lock if j not in chain.joint_names]
    if unknown:
        raise DataError(
            f"--lock {','.join(unknown)}: not joints between the base and {chain.tip} "
            f"({', '.join(chain.joint_names)})"
        )
    check_columns(csv_columns(args.data), chain, args.lock)
    if not args.lock:
        return chain
    if len(args.lock) == chain.n_joints:
        raise DataError("--lock names every joint of the chain: nothing would move")
    print(f"locked at their neutral value: {', '.join(args.lock)}")
    return load_robot(args.robot, tip=args.tip, joints=[j for j in chain.joint_names if j not in args.lock])


def _check_outputs(args: argparse.Namespace, outputs: Sequence[Path | None], inputs: dict[str, Any]) -> None:
    """Refuse outputs that are inputs, repeat, sit in no folder, or exist (without ``--force``).

    Args:
        args: the parsed command line (``--force``).
        outputs: the files the command will write (None: not asked for).
        inputs: what each input is ("data file", ...) -> its path or ROBOT argument (or None).
    """
    sources = {label: Path(str(p)) for label, p in inputs.items() if p is not None}
    sources = {label: p for label, p in sources.items() if p.is_file()}
    seen: list[Path] = []
    for out in outputs:
        if out is None:
            continue
        if out.is_dir():
            raise DataError(f"{out} is a folder: give a file name for the output")
        for label, src in sources.items():
            if out.exists() and out.samefile(src):
                raise DataError(f"{out} is the {label}: write the output to another file")
        if out.resolve() in seen:
            raise DataError(f"{out} is named for two outputs: give each its own file")
        seen.append(out.resolve())
        if not out.parent.resolve().is_dir():
            raise DataError(f"the output folder {out.parent} does not exist: create it first")
        if out.exists() and not args.force:
            raise DataError(f"{out} exists already: pass --force to replace it, or choose another name")


def _options(args: argparse.Namespace) -> dict[str, Any]:
    """Keyword arguments of :func:`pincal.calibrate` from the shared options."""
    return {
        "instrument_T_base": pin.SE3.Identity() if args.instrument_frame == "base" else None,
        "tool": None if args.tool_point is None else args.tool_point * UNITS[args.units],
        "rotation_weight": args.rotation_weight,
        "loss": args.loss,
        "partial": args.partial,
    }


def _diagnose(args: argparse.Namespace) -> int:
    from .diagnose import diagnose
    from .plots import plot_diagnosis

    if args.plots is not None and not args.plots.is_dir():
        raise DataError(f"--plots {args.plots}: the folder does not exist, create it first")
    _check_outputs(args, [args.json], {"data file": args.data, "input URDF": _urdf_path(args.robot)})
    robot = _robot(args)
    data = _load_data(args.data, robot, args)
    if args.outliers:
        screened = calibrate(robot, data, args.model, args.measure, outliers=args.outliers, **_options(args))
        if screened.excluded:
            rows = [row for row, _ in screened.excluded]
            data = data.subset(np.flatnonzero(~np.isin(data.row_numbers, rows)))
            print(f"outliers left out (residual far outside the others'): rows {', '.join(map(str, rows))}")

    def progress(done: int, total: int, label: str) -> None:
        print(f"\r  candidates {done}/{total} ({label})".ljust(72), end="", file=sys.stderr, flush=True)

    result = diagnose(
        robot,
        data,
        args.model,
        args.measure,
        folds=args.folds,
        seed=args.seed,
        payload=args.payload,
        progress=progress if sys.stderr.isatty() else None,
        **_options(args),
    )
    if sys.stderr.isatty():
        print(file=sys.stderr)
    print(
        f"baseline {args.model}: cross-validated RMS {result.baseline_cv_rms_mm:.4f} mm ({args.folds} folds)"
    )
    for cand in result.candidates[:5]:
        print(f"  {cand.extension.label:42s} CV RMS {cand.cv_rms_mm:.4f} mm  F-test p = {cand.p_value:.2g}")
    print(result.summary())
    if args.plots is not None and result.cause is not None and result.baseline.measurement.kind != "distance":
        plot = args.plots / f"diagnose_{result.cause.extension.effect}.png"
        _check_outputs(args, [plot], {"data file": args.data, "input URDF": _urdf_path(args.robot)})
        path = plot_diagnosis(result, data, plot)
        print(f"plot written to {path}")
    if args.json is not None:
        atomic_write(args.json, json.dumps(result.to_dict(), indent=2) + "\n")
        print(f"written to {args.json}")
    return 0


def _mapping(text: str) -> dict[str, str]:
    try:
        pairs = [item.split("=", 1) for item in text.split(",")]
        return {k.strip(): v.strip() for k, v in pairs}
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected NAME=COLUMN pairs separated by commas, got {text!r}"
        ) from None


def _tcp(args: argparse.Namespace) -> int:
    _check_outputs(args, [args.json], {"poses file": args.poses, "input URDF": _urdf_path(args.robot)})
    robot = load_robot(args.robot, tip=args.tip) if args.robot else None
    rotations, positions = read_flange_poses(args.poses, args.units, args.columns, robot, args.degrees)
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
        print(f"pincal: warning: {warning}", file=sys.stderr)
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
        }
        atomic_write(args.json, json.dumps(result, indent=2) + "\n")
        print(f"written to {args.json}")
    return 0


def _load_data(path: Path, robot: Robot, args: argparse.Namespace) -> Dataset:
    """Read a measurement CSV and check its joint values and units against the robot."""
    data = read_csv(
        path, robot.joint_names, degrees=args.degrees, units=args.units, prismatic=robot.prismatic
    )
    check_limits(robot, data, args.degrees)
    check_scale(robot, data, args.units)
    return data


def _calibrate(args: argparse.Namespace) -> int:
    from .report import report_json, summary

    if args.add_frame is not None and args.output is None:
        raise DataError("--add-frame needs -o FILE.urdf")
    check_frame_name(args.add_frame)
    if args.test is not None and args.holdout is not None:
        raise DataError("give either --test or --holdout, not both")
    if args.output is not None and (args.output.is_dir() or not args.output.name):
        raise DataError(f"-o {args.output} is a folder: give a file name such as robot_calibrated.urdf")
    side = None if args.output is None else sidecar_path(args.output)
    _check_outputs(
        args,
        [args.output, side, args.report],
        {"data file": args.data, "test data file": args.test, "input URDF": _urdf_path(args.robot)},
    )
    robot = _robot(args)
    extension = Extension.parse(robot, args.extend, args.payload) if args.extend else None
    data = _load_data(args.data, robot, args)
    test = _load_data(args.test, robot, args) if args.test is not None else None
    if args.holdout is not None:
        data, test = data.split(args.holdout, args.seed)
    cal = calibrate(
        robot,
        data,
        args.model,
        args.measure,
        test=test,
        pairs=args.pairs,
        extension=extension,
        outliers=args.outliers or None,
        **_options(args),
    )
    print(summary(cal))
    extra = {}
    if args.output is not None:
        urdf, side = write_corrected_urdf(cal, args.output, args.add_frame)
        print(f"corrected URDF written to {urdf}; registration and tool (not in a URDF) to {side}")
        extra = {"urdf": str(urdf), "sidecar": str(side)}
    if args.report is not None:
        atomic_write(args.report, report_json(cal, **extra))
        print(f"report written to {args.report}")
    return 0


def _compensate(args: argparse.Namespace) -> int:
    from .compensate import compensate_program, write_program
    from .data import read_program
    from .urdf_writer import load_calibration

    inputs = {
        "program": args.program,
        "calibration URDF": args.calibration,
        "calibration sidecar": sidecar_path(args.calibration),
    }
    _check_outputs(args, [args.output], {**inputs, "input URDF": _urdf_path(args.robot)})
    cal = load_calibration(args.calibration)
    nominal = load_robot(args.robot, tip=cal.robot.tip, joints=cal.robot.joint_names)
    program = read_program(args.program, nominal, args.degrees, args.units)
    result = compensate_program(nominal, cal, program, task=args.task)
    n = len(result.status)
    if not result.ok.any():
        raise DataError(
            f"none of the {n} rows could be compensated ({result.failures()[0]}): check that the "
            "program is for this robot and within its limits"
        )
    write_program(args.output, result, args.degrees, nominal.prismatic)
    worst = float(result.position_error[result.ok].max()) * 1e3
    print(f"compensated {int(result.ok.sum())} of {n} rows ({result.task} task, worst {worst:.4f} mm)")
    for line in result.failures():
        print(f"  {line}")
    print(f"written to {args.output}")
    return 0


def _plan(args: argparse.Namespace) -> int:
    from .planning import plan_poses, write_poses

    _check_outputs(args, [args.output], {"input URDF": _urdf_path(args.robot)})
    if args.reach is not None and args.instrument is None:
        raise DataError("--reach needs --instrument X,Y,Z (where the instrument stands)")
    robot = load_robot(args.robot, tip=args.tip)
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


def _twists(args: argparse.Namespace) -> int:
    from .twists import nominal_twists, poe_forward

    robot = load_robot(args.robot, tip=args.tip)
    tw = nominal_twists(robot)
    print(f"{robot.name}: {robot.n_joints} joints from the base to {robot.tip}; twists (ω, v [m]) at q = 0")
    for name, xi in zip(robot.joint_names, tw.twists):
        print(
            f"  {name:24s} ω = {np.array2string(xi[3:], precision=4, suppress_small=True):26s} "
            f"v = {np.array2string(xi[:3], precision=4, suppress_small=True)}"
        )
    print(f"  home: p = {np.array2string(tw.home.translation, precision=5, suppress_small=True)} m")
    rng = np.random.default_rng(0)
    worst = 0.0
    for q in robot.random_configurations(100, rng):
        err = pin.log6(robot.frame_placement(q).actInv(poe_forward(tw.twists, tw.home, q)))
        worst = max(worst, float(np.abs(err.vector).max()))
    print(f"  product of exponentials vs Pinocchio at 100 random configurations: max error {worst:.2e}")
    return 0


def _attach_vectors(argv: Sequence[str]) -> list[str]:
    """Write ``--tool-point -1,2,3`` as ``--tool-point=-1,2,3`` (also ``--instrument``): argparse
    takes ``-1,2,3`` for an option."""
    out: list[str] = []
    for arg in argv:
        if out and out[-1] in ("--tool-point", "--instrument") and arg.startswith("-"):
            out[-1] = f"{out[-1]}={arg}"
        else:
            out.append(arg)
    return out


def _demo(args: argparse.Namespace) -> int:
    from .demo import run

    print(run(seed=args.seed))
    return 0


_COMMANDS = {
    "calibrate": _calibrate,
    "diagnose": _diagnose,
    "tcp": _tcp,
    "twists": _twists,
    "compensate": _compensate,
    "plan": _plan,
    "demo": _demo,
}


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``pincal`` command."""
    try:
        args = _build_parser().parse_args(_attach_vectors(sys.argv[1:] if argv is None else argv))
        return _COMMANDS[args.command](args)
    except PincalError as exc:
        message = " ".join(str(exc).split())
        print(f"pincal: error: {message}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
