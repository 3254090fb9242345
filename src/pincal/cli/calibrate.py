"""``pincal calibrate``: identify the model the data supports and write what it found."""

from __future__ import annotations

import argparse
from typing import Any

from ..data import atomic_write
from ..errors import DataError
from ..pipeline import calibrate
from ..report import report_json, summary
from ..urdf_writer import check_frame_name, sidecar_path, write_corrected_urdf
from .common import (
    chain,
    check_outputs,
    end_progress,
    fit_options,
    load_data,
    plausible,
    progress_line,
    urdf_path,
)

#: ``--nested`` -> the ``nested`` argument of :func:`pincal.calibrate`.
NESTED = {"auto": None, "yes": True, "no": False}


def _check_arguments(args: argparse.Namespace) -> None:
    """Refuse option combinations that cannot work, before anything is read."""
    if args.add_frame is not None and args.output is None:
        raise DataError("--add-frame needs -o FILE.urdf")
    check_frame_name(args.add_frame)
    if args.test is not None and args.holdout is not None:
        raise DataError("give either --test or --holdout, not both")
    if args.output is not None and (args.output.is_dir() or not args.output.name):
        raise DataError(f"-o {args.output} is a folder: give a file name such as robot_calibrated.urdf")
    side = None if args.output is None else sidecar_path(args.output)
    check_outputs(
        args,
        [args.output, side, args.report],
        {"data file": args.data, "test data file": args.test, "input URDF": urdf_path(args.robot)},
    )


def run(args: argparse.Namespace) -> int:
    """Run the command; 0 on success."""
    _check_arguments(args)
    robot = chain(args)
    data = load_data(args.data, robot, args)
    test = load_data(args.test, robot, args) if args.test is not None else None
    if args.holdout is not None:
        data, test = data.split(args.holdout, args.seed)
    progress = progress_line("diagnosis") if args.extend == "auto" else None
    cal = calibrate(
        robot,
        data,
        args.model,
        args.measure,
        test=test,
        pairs=args.pairs,
        params=args.params,
        extension=args.extend,
        payload=args.payload,
        outliers=args.outliers or None,
        folds=args.folds,
        seed=args.seed,
        nested=NESTED[args.nested],
        progress=progress,
        **fit_options(args),
    )
    end_progress(progress)
    print(summary(cal, data))
    verdict = plausible(cal, data, args)
    extra: dict[str, Any] = {"plausibility": verdict.to_dict()}
    if args.output is not None:
        urdf, side = write_corrected_urdf(cal, args.output, args.add_frame)
        print(f"corrected URDF written to {urdf}; registration and tool (not in a URDF) to {side}")
        extra.update(urdf=str(urdf), sidecar=str(side))
    if args.report is not None:
        atomic_write(args.report, report_json(cal, data, **extra))
        print(f"report written to {args.report}")
    return 0
