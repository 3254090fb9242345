"""``pincal diagnose``: name what the rigid model gets wrong, and the gain."""

from __future__ import annotations

import argparse

import numpy as np

from ..data import atomic_write
from ..errors import DataError
from ..json_text import json_text
from ..pipeline import calibrate
from ..selection import select_parameters
from .common import (
    chain,
    check_applicable,
    check_outputs,
    end_progress,
    fit_options,
    load_data,
    plausible,
    progress_line,
    urdf_path,
)


def run(args: argparse.Namespace) -> int:
    """Run the command; 0 on success."""
    from ..diagnose import diagnose
    from ..plots import plot_diagnosis

    if args.plots is not None and not args.plots.is_dir():
        raise DataError(f"--plots {args.plots}: the folder does not exist, create it first")
    check_outputs(args, [args.json], {"data file": args.data, "input URDF": urdf_path(args.robot)})
    robot = chain(args)
    data = load_data(args.data, robot, args)
    check_applicable(args, data)
    if args.outliers:
        options = fit_options(args)
        screened = calibrate(robot, data, args.model, args.measure, outliers=args.outliers, **options)
        if screened.excluded:
            rows = [row for row, _ in screened.excluded]
            data = data.subset(np.flatnonzero(~np.isin(data.row_numbers, rows)))
            named = ", ".join(data.row_name(row) for row in rows)
            print(f"outliers left out (residual far outside the others'): {named}")

    params = None if args.params == "all" else args.params
    if params == "auto":
        params = select_parameters(robot, data, args.model, args.measure, **fit_options(args)).params
    progress = progress_line("candidates")
    result = diagnose(
        robot,
        data,
        args.model,
        args.measure,
        folds=args.folds,
        seed=args.seed,
        payload=args.payload,
        progress=progress,
        params=None if params is None else list(params),
        **fit_options(args),
    )
    end_progress(progress)
    print(
        f"baseline {args.model}: cross-validated RMS {result.baseline_cv_rms_mm:.4f} mm ({args.folds} folds)"
    )
    for cand in result.candidates[:5]:
        print(f"  {cand.extension.label:42s} CV RMS {cand.cv_rms_mm:.4f} mm  F-test p = {cand.p_value:.2g}")
    print(result.summary())
    verdict = plausible(result.baseline, data, args)
    if args.plots is not None and result.cause is not None and result.baseline.measurement.kind != "distance":
        plot = args.plots / f"diagnose_{result.cause.extension.effect}.png"
        check_outputs(args, [plot], {"data file": args.data, "input URDF": urdf_path(args.robot)})
        path = plot_diagnosis(result, data, plot)
        print(f"plot written to {path}")
    if args.json is not None:
        out = {**result.to_dict(), "plausibility": verdict.to_dict()}
        atomic_write(args.json, json_text(out))
        print(f"written to {args.json}")
    return 0
