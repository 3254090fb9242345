"""``pincal calibrate``: identify the model the data supports and write what it found."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pincal.auto.large_choice import calibrate_choosing
from pincal.auto.pipeline import calibrate
from pincal.cli.common import (
    chain,
    check_applicable,
    check_outputs,
    end_progress,
    fit_options,
    load_data,
    plausible,
    progress_line,
    ur_yaml_output,
    urdf_path,
)
from pincal.cli.deliver_options import GEOMETRY
from pincal.cli.flags import as_flags
from pincal.cli.gravity_options import check_gravity_options, warn_unused_gravity
from pincal.cli.pull_options import pull
from pincal.data.dataset import Dataset
from pincal.errors import DataError
from pincal.export.added_frame import check_frame_name
from pincal.export.ur_yaml import robot_ur_chain, write_ur_kinematics
from pincal.export.urdf_writer import corrected_files, origin_changes, sidecar_path
from pincal.files import STDIN, atomic_write_many
from pincal.identify.calibration import Calibration
from pincal.report.outcome import Outcome, outcome
from pincal.report.report import report_json
from pincal.report.summary_table import summary
from pincal.robot.robots import Robot
from pincal.robot.ur_frames import DEFAULT_DH, read_ur_kinematics

#: ``--nested`` -> the ``nested`` argument of :func:`pincal.calibrate`.
NESTED = {"auto": None, "yes": True, "no": False}
#: What the nested cross-validation's ``before`` is, in a warning.
NOMINAL_FITTED = "the URDF's geometry with the registration and tool fitted"
#: ``-o`` suffixes of what the corrected robot is written as: a URDF, or a UR kinematics YAML.
ROBOT_SUFFIXES = (".urdf", ".yaml", ".yml")


def _check_arguments(args: argparse.Namespace) -> None:
    """Refuse option combinations that cannot work, before anything is read."""
    if args.add_frame is not None and (args.output is None or ur_yaml_output(args)):
        raise DataError("--add-frame needs -o FILE.urdf")
    check_frame_name(args.add_frame)
    if args.test is not None and args.holdout is not None:
        raise DataError("give either --test or --holdout, not both")
    if str(args.data) == str(args.test) == STDIN:
        raise DataError("DATA and --test are both '-': standard input holds one file, give the other by name")
    if args.output is not None and (args.output.is_dir() or not args.output.name):
        raise DataError(f"-o {args.output} is a folder: give a file name such as robot_calibrated.urdf")
    if args.output is not None and args.output.suffix.lower() not in ROBOT_SUFFIXES:
        kind = f"not a {args.output.suffix} file" if args.output.suffix else "and the name has no suffix"
        raise DataError(
            f"-o {args.output}: the corrected robot is a URDF or a UR kinematics YAML, {kind}: name it "
            ".urdf or .yaml (--report FILE.json for the report)"
        )
    side = None if args.output is None else sidecar_path(args.output)
    check_outputs(
        args,
        [args.output, side, args.report],
        {"data file": args.data, "test data file": args.test, "input URDF": urdf_path(args.robot)},
    )


def default_extension(given: str | None, measure: str | None, data: Dataset) -> str:
    """``--extend`` as given, else ``auto``, or ``none`` for fixed-point data: there the
    cross-validation runs over one fixture's rows, which cannot tell whether an effect carries to
    another placement (on MUKCa's Pandas it named effects that predicted other placements worse)."""
    if given is not None:
        return given
    return "none" if (measure or data.measured) == "points" else "auto"


def _fit(
    args: argparse.Namespace,
    robot: Robot,
    data: Dataset,
    test: Dataset | None,
    progress: Callable[[int, int, str], None] | None,
) -> Calibration:
    """The calibration the options ask for; above :data:`pincal.auto.large_choice.CHOICE_POSES` poses
    the automatic choice is made on a random subset, said first."""
    options: dict[str, Any] = dict(
        model=args.model,
        measure=args.measure,
        pairs=args.pairs,
        params=args.params,
        extension=args.extend,
        payload=args.payload,
        outliers=args.outliers or None,
        folds=args.folds,
        seed=args.seed,
        nested=NESTED[args.nested],
        progress=progress,
        deliver=GEOMETRY[args.geometry],
        pull=pull(args),
        **fit_options(args),
    )
    return calibrate_choosing(calibrate, robot, data, print, test=test, **options)


def run(args: argparse.Namespace) -> int:
    """Run the command; 0 on success."""
    _check_arguments(args)
    robot = chain(args)
    if ur_yaml_output(args):
        robot_ur_chain(robot)  # refused before the fit, not after
        if args.kinematics is None and args.robot in DEFAULT_DH:
            print(f"{args.robot} in ur_description's frames, from its default kinematics (nominal)")
    data = load_data(args.data, robot, args)
    test = load_data(args.test, robot, args) if args.test is not None else None
    if test is not None and (test.labels is None) != (data.labels is None):  # issue 33
        raise DataError(
            f"--test {args.test} holds {test.measured} data and {args.data} {data.measured} data: "
            "held-out poses are scored as the fit's, give a --test file of the same kind"
        )
    check_applicable(args, data)
    if args.holdout is not None:
        data, test = data.split(args.holdout, args.seed)
    args.extend = default_extension(args.extend, args.measure, data)
    check_gravity_options(args, args.extend)
    progress = progress_line("calibration")  # the diagnosis, then the nested cross-validation
    cal = _fit(args, robot, data, test, progress)
    end_progress(progress)
    cal = plausible(cal, data, args)
    warn_unused_gravity(args, cal)
    result = outcome(cal, data, test, args.noise, args.folds, args.seed)
    print(as_flags(summary(cal, data, test, result)))
    files: list[tuple[str | Path, str | bytes]] = []
    extra: dict[str, Any] = {}
    if ur_yaml_output(args):
        source = None if args.kinematics is None else read_ur_kinematics(args.kinematics).calibration_hash
        yaml, side = write_ur_kinematics(cal, args.output, source, accept_implausible=True)  # judged above
        print(f"UR kinematics YAML written to {yaml}; registration and tool (not in it) to {side}")
        extra.update(ur_kinematics=str(yaml), sidecar=str(side))
    elif args.output is not None:
        files = list(corrected_files(cal, args.output, args.add_frame))
        extra.update(urdf=str(files[0][0]), sidecar=str(files[1][0]))
    if args.report is not None:
        files.append((args.report, as_flags(report_json(cal, data, test, result, **extra))))
    atomic_write_many(files)  # every output or none
    if "urdf" in extra:
        print(f"corrected URDF written to {extra['urdf']}; registration and tool (not in a URDF) to ", end="")
        print(extra["sidecar"])
        print("joint origins in the corrected URDF, moved and turned from the input's:")
        for change in origin_changes(cal):
            print(f"  {change.text()}")
    if args.report is not None:
        print(f"report written to {args.report}")
    print(
        as_flags(
            result.verdict_line(str(args.output) if args.output else None, verdict_warnings(cal, result))
        )
    )
    return 0


def verdict_warnings(cal: Any, result: Outcome) -> tuple[str, ...]:
    """What the user must act on, for the verdict line: a nested cross-validation (the whole
    procedure re-run without each fold) worse than the URDF as is, or than the URDF's geometry
    with the registration and tool fitted (the corrections do not hold on poses they did not see).
    An undetermined residual says itself what to give."""
    nested = cal.choice.nested if cal.choice is not None else None
    if nested is None:
        return ()
    for stats, what in ((nested.urdf, "the URDF as is"), (nested.before, NOMINAL_FITTED)):
        if nested.after.rms_mm > stats.rms_mm * 1.01:
            return (
                f"warning: the nested cross-validation is worse than {what} "
                f"({nested.after.rms_mm:.3g} against {stats.rms_mm:.3g} mm): measure more varied poses",
            )
    return ()
