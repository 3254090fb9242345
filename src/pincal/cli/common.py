"""What the ``pincal`` commands share: the chain and data from the arguments, output checks,
the fit options and a progress line."""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pinocchio as pin

from pincal.cli.data_options import check_lock
from pincal.cli.recording_data import recording_data, unused_recording_options
from pincal.data.checks import check_columns, check_limits, check_scale, small_angles
from pincal.data.dataset import UNITS, Dataset, csv_columns, read_csv
from pincal.data.point_files import read_socket_folder
from pincal.data.recording_reader import is_recording
from pincal.errors import DataError, ImplausibleError, OutputError
from pincal.files import STDIN, output_target
from pincal.identify.fixed_points import parse_point_distances
from pincal.identify.kinds import get_kind
from pincal.inputs import input_named, note_standard_input
from pincal.options import ROTATION_WEIGHT
from pincal.plausibility.judge import judge_calibration
from pincal.plausibility.past_tip import Reading, check_past_tip
from pincal.robot.robots import BUNDLED, Robot, bundled_urdf, load_robot

if TYPE_CHECKING:
    from pincal.identify.calibration import Calibration


def urdf_path(robot: str | None) -> Path | None:
    """The URDF file a ROBOT argument names (bundled robots included)."""
    if robot is None:
        return None
    return bundled_urdf(robot) if robot in BUNDLED else Path(robot)


def ur_yaml_output(args: argparse.Namespace) -> bool:
    """True when ``-o`` names a UR kinematics YAML (``.yaml`` or ``.yml``)."""
    from pincal.export.ur_yaml import is_yaml

    return is_yaml(getattr(args, "output", None))


def robot_options(args: argparse.Namespace) -> dict[str, Any]:
    """Keyword arguments of :func:`pincal.load_robot` from ``--xacro-arg``, ``--package-path``,
    ``--kinematics`` (for a bundled UR written as, or compensated with, a UR YAML:
    ``ur_description``'s default) and ``--inertias``."""
    from pincal.export.ur_yaml import is_yaml
    from pincal.robot.descriptions import parse_package_paths, parse_xacro_args
    from pincal.robot.ur_frames import DEFAULT_DH, default_ur_kinematics

    kinematics = getattr(args, "kinematics", None)
    ur_frames = ur_yaml_output(args) or is_yaml(getattr(args, "calibration", None))
    if kinematics is None and ur_frames and args.robot in DEFAULT_DH:
        kinematics = default_ur_kinematics(args.robot)
    return {
        "xacro_args": parse_xacro_args(getattr(args, "xacro_arg", None)),
        "package_paths": parse_package_paths(getattr(args, "package_path", None)),
        "kinematics": kinematics,
        "inertias": getattr(args, "inertias", None),
    }


def locked_robot(args: argparse.Namespace) -> Robot:
    """The ``--robot`` chain to ``--tip``, without the ``--lock`` joints (held at neutral).

    Raises:
        DataError: a locked joint not in the chain, or every joint locked.
    """
    chain = load_robot(args.robot, tip=args.tip, **robot_options(args))
    check_lock(chain, args.lock)
    if not args.lock:
        return chain
    if len(args.lock) == chain.n_joints:
        raise DataError("--lock names every joint of the chain: nothing would move")
    joints = [j for j in chain.joint_names if j not in args.lock]
    return load_robot(args.robot, tip=args.tip, joints=joints, **robot_options(args))


def chain(args: argparse.Namespace) -> Robot:
    """The chain; every chain joint needs a column in the data unless ``--lock`` holds it."""
    chain = load_robot(args.robot, tip=args.tip, **robot_options(args))
    check_lock(chain, args.lock)
    if not Path(args.data).is_dir() and not is_recording(args.data):  # no CSV header to check
        check_columns(csv_columns(args.data), chain, args.lock)
    if not args.lock:
        return chain
    if len(args.lock) == chain.n_joints:
        raise DataError("--lock names every joint of the chain: nothing would move")
    print(f"locked at their neutral value: {', '.join(args.lock)}")
    joints = [j for j in chain.joint_names if j not in args.lock]
    return load_robot(args.robot, tip=args.tip, joints=joints, **robot_options(args))


def check_outputs(args: argparse.Namespace, outputs: Sequence[Path | None], inputs: dict[str, Any]) -> None:
    """Refuse outputs that are inputs, repeat, are not regular files (a folder, a device, a pipe),
    sit in no folder or one that cannot be written to, or exist (without ``--force``). A symlink
    is written through: its target is what is checked.

    Args:
        args: the parsed command line (``--force``).
        outputs: the files the command will write (None: not asked for).
        inputs: what each input is ("data file", ...) -> its path or ROBOT argument (or None).
    """
    inputs = {**inputs, "kinematics YAML": getattr(args, "kinematics", None)}
    inputs["--inertias URDF"] = getattr(args, "inertias", None)
    for label, p in inputs.items():
        if str(p) == STDIN:
            note_standard_input(label)  # '- < data.csv': the output must not be data.csv
    sources = {label: Path(str(p)) for label, p in inputs.items() if p is not None and str(p) != STDIN}
    sources = {label: p for label, p in sources.items() if p.is_file()}
    seen: list[Path] = []
    for out in outputs:
        if out is None:
            continue
        target = output_target(out)  # refuses '-', folders and special files, --force or not
        for label, src in sources.items():
            if target.exists() and target.samefile(src):
                raise DataError(f"{out} is the {label}: write the output to another file")
        read = input_named(target)  # any file read so far: @FILE lists, xacro includes (issue 33)
        if read is not None:
            raise DataError(f"{out} is the {read} this run reads: write the output to another file")
        if target in seen:
            raise DataError(f"{out} is named for two outputs: give each its own file")
        seen.append(target)
        if not target.parent.is_dir():
            folder = target.parent if out.is_symlink() else out.parent  # where a symlink points
            raise DataError(f"the output folder {folder} does not exist: create it first")
        if not os.access(target.parent, os.W_OK | os.X_OK):
            raise OutputError(f"cannot write {out}: the folder {target.parent} is not writable")
        if target.exists() and not args.force:
            raise DataError(f"{out} exists already: pass --force to replace it, or choose another name")


def fit_options(args: argparse.Namespace) -> dict[str, Any]:
    """Keyword arguments of :func:`pincal.calibrate` from the shared options."""
    return {
        "instrument_T_base": pin.SE3.Identity() if args.instrument_frame == "base" else None,
        "tool": scaled_points(args.tool_point, UNITS[args.units]),
        "rotation_weight": args.rotation_weight,
        "loss": args.loss,
        "partial": args.partial,
        "point_distances": parse_point_distances(args.point_distance, args.units),
    }


def scaled_points(points: Any, scale: float) -> Any:
    """``--tool-point`` in metres: one point (3,), or a point per marker label, or None."""
    if points is None:
        return None
    if isinstance(points, dict):
        return {label: p * scale for label, p in points.items()}
    return points * scale


def warn(args: argparse.Namespace, text: str) -> None:
    """Keep a ``pincal: warning:`` for the end of the command: :func:`pincal.cli.main` says the
    warnings of a command that succeeds; one that fails says its one error line alone."""
    args.__dict__.setdefault("warnings", []).append(text)


def load_data(path: Path, robot: Robot, args: argparse.Namespace) -> Dataset:
    """Read a measurement CSV (or a ROS recording) and check its joint values and units against the robot."""
    if is_recording(path):
        data = recording_data(path, robot.joint_names, args)
    elif path.is_dir():
        if args.degrees:
            raise DataError(f"{path}: MUKCa's files hold radians: drop --degrees")
        data = read_socket_folder(path, robot.joint_names, robot.prismatic)
    else:
        data = read_csv(
            path,
            robot.joint_names,
            degrees=args.degrees,
            units=args.units,
            prismatic=robot.prismatic,
            measure=args.measure,
            quaternion_order=args.quaternion_order,
            locked=args.lock,
        )
    beyond = check_limits(robot, data, args.degrees)
    if beyond:
        limits = "kept as measured (are the limits too tight?)"
        warn(args, f"{path}: {beyond} joint value(s) beyond the URDF limits, {limits}")
    if data.labels is None:  # fixed points have no measured positions to compare
        check_scale(robot, data, args.units, args.degrees)
        if not is_recording(path):  # past-tip columns are a CSV's
            reading = Reading(
                args.measure, args.degrees, args.units, args.rotation_weight, robot_options(args)
            )
            check_past_tip(robot, data, path, reading)
    elif args.degrees and small_angles(robot, data):
        warn(
            args,
            f"{path}: with --degrees every revolute joint value is within ±6.3 degrees: "
            "if the file holds radians, drop --degrees",
        )
    return data


def check_applicable(args: argparse.Namespace, data: Dataset) -> None:
    """Warn of options the data's measurement kind has no use for, instead of ignoring them in
    silence (those of another kind, ``--pairs`` and ``--point-distance``, the fit refuses)."""
    kind = args.measure or data.measured
    ignored = []
    if args.rotation_weight != ROTATION_WEIGHT and not get_kind(kind).orientation:
        ignored.append("--rotation-weight (pose data only)")
    if args.quaternion_order != "wxyz" and not data.has_orientation:
        ignored.append("--quaternion-order (the data has no quaternion)")
    if args.instrument_frame == "base" and not get_kind(kind).registered:
        ignored.append(f"--instrument-frame base ({kind} data needs no registration)")
    ignored += unused_recording_options(args)
    if ignored:
        warn(args, f"ignored for {kind} data: " + "; ".join(ignored))


def plausible(cal: Calibration, data: Dataset, args: argparse.Namespace) -> Calibration:
    """The fit with the plausibility verdict :func:`pincal.calibrate` gave it
    (:mod:`pincal.plausibility.judge`); a fit that cannot be right is judged again knowing how
    the data was read (so that the hint names the reading to change), and raised as an error, or
    said as a warning with ``--accept-implausible``."""
    if cal.plausibility is not None and cal.plausibility.plausible:
        return cal
    order = args.quaternion_order
    verdict = judge_calibration(cal, data, degrees=args.degrees, quaternion_order=order, loss=args.loss)
    if not verdict.plausible:
        if not args.accept_implausible:
            raise ImplausibleError(verdict.message())
        warn(args, verdict.warning())
    return replace(cal, plausibility=verdict)


class ProgressBar:
    """A tqdm progress bar on stderr, fed by the library's ``progress(done, total, label)``
    callback; a new total starts a new bar (another stage, or round of the choice)."""

    def __init__(self, what: str) -> None:
        self.what = what
        self.bar: Any = None

    def __call__(self, done: int, total: int, label: str) -> None:
        from tqdm import tqdm

        if self.bar is None or self.bar.total != total:
            self.close()
            self.bar = tqdm(total=total, desc=f"  {self.what}", file=sys.stderr, leave=False, unit="step")
        self.bar.set_postfix_str(label, refresh=False)
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        """Close the bar: it leaves no line behind."""
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def progress_line(what: str) -> ProgressBar | None:
    """A progress bar for ``what``; None, and nothing shown, when stderr is not a terminal (a
    log, a pipe, CI)."""
    return ProgressBar(what) if sys.stderr.isatty() else None


def end_progress(show: Callable[[int, int, str], None] | None) -> None:
    """Close the progress bar."""
    if isinstance(show, ProgressBar):
        show.close()
