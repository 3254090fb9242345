"""``pincal diagnose``: name what the rigid model gets wrong, and the gain."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from pincal.auto.choice import ModelChoice, choice_of
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
    urdf_path,
    warn,
)
from pincal.cli.flags import as_flags
from pincal.data.dataset import Dataset
from pincal.errors import DataError, IdentifiabilityError, OutputError
from pincal.files import atomic_write
from pincal.identify.calibration import Calibration
from pincal.json_text import json_text
from pincal.report.outcome import Outcome, outcome


def run(args: argparse.Namespace) -> int:
    """Run the command; 0 on success: the diagnosis of ``pincal calibrate --extend auto`` (one
    shared pipeline, so that both name the same cause), its candidates, and what remains."""
    if args.plot is not None and args.plots is not None:
        raise DataError("give either --plot FILE.png or --plots DIR, not both")
    if args.plots is not None and args.plots.exists() and not args.plots.is_dir():
        raise DataError(
            f"--plots {args.plots} is a file, not a folder: give a folder, or --plot {args.plots}"
        )
    check_outputs(args, [args.json, args.plot], {"data file": args.data, "input URDF": urdf_path(args.robot)})
    robot = chain(args)
    data = load_data(args.data, robot, args)
    check_applicable(args, data)
    progress = progress_line("candidates")
    cal = calibrate_choosing(  # above 20,000 poses the diagnosis runs on a subset, as calibrate's
        calibrate,
        robot,
        data,
        print,
        model=args.model,
        measure=args.measure,
        params=args.params,
        extension="auto",
        payload=args.payload,
        outliers=args.outliers or None,
        folds=args.folds,
        seed=args.seed,
        nested=False,
        progress=progress,
        **fit_options(args),
    )
    end_progress(progress)
    if cal.excluded:
        named = ", ".join(data.row_name(row) for row, _ in cal.excluded)
        print(f"outliers left out (residual far outside the others'): {named}")
        rows = [row for row, _ in cal.excluded]
        data = data.subset(np.flatnonzero(~np.isin(data.row_numbers, rows)))
    choice = choice_of(cal)
    if choice is None or choice.diagnosis is None:
        raise IdentifiabilityError(f"the diagnosis did not run: {choice.skipped if choice else 'no choice'}")
    result = choice.diagnosis
    how = f"{args.folds} folds" + (", linearised" if result.baseline_by == "linearised" else "")
    print(f"baseline {args.model}: cross-validated RMS {result.baseline_cv_rms_mm:.4f} mm ({how})")
    for cand in result.candidates[:5]:
        chance = _p_text(cand.p_value, result.null_draws)
        print(f"  {cand.extension.label:42s} CV RMS {cand.cv_rms_mm:.4f} mm  {chance}")
    print(as_flags(result.summary()))
    for step in choice.more:  # each further cause, sought with the ones before it held
        assert step.cause is not None
        print(as_flags(f"and {step.cause.extension.label}: {step.summary()}"))
    cal = plausible(cal, data, args)  # the model calibrate would export, as calibrate judges it
    found = outcome(cal, data, None, args.noise, args.folds, args.seed)
    print(as_flags(f"residual: {found.residual.sentence()}; {found.residual.how}"))
    if found.caveat():
        print(as_flags(f"note: {found.caveat()}"))
    _plots(args, choice, data, found)
    if args.json is not None:
        _write_json(args.json, cal, choice, found)
    print(as_flags(found.verdict_line()))
    return 0


def _plots(args: argparse.Namespace, choice: ModelChoice, data: Dataset, found: Outcome) -> None:
    """``--plot FILE`` or ``--plots DIR``: each cause with its own evidence (a second cause beside
    ``FILE`` as ``FILE_2.png``), or what remains when none is named."""
    from pincal.report.plots import plot_diagnosis

    assert choice.diagnosis is not None
    if args.plot is None and args.plots is None:
        return
    if choice.diagnosis.baseline.measurement.measure.by_pairs:
        warn(args, "no plot written: distance data has no per-pose residual to plot")
        return
    for k, step in enumerate((choice.diagnosis, *choice.more)):
        name = step.cause.extension.effect if step.cause else found.residual.verdict
        suffix = f"_{k + 1}" if k else ""
        if args.plot is not None:
            plot = args.plot.with_name(f"{args.plot.stem}{suffix}{args.plot.suffix}")
        else:
            plot = _created(args.plots) / f"diagnose_{name}{suffix}.png"
        check_outputs(args, [plot], {"data file": args.data, "input URDF": urdf_path(args.robot)})
        path = plot_diagnosis(step, data, plot, found.residual, as_flags)
        print(f"plot written to {path}")


def _write_json(path: Path, cal: Calibration, choice: ModelChoice, found: Outcome) -> None:
    """The JSON of contracts.md, with every cause (``causes``) and the gain of all of them."""
    result = choice.diagnosis
    last = choice.last_diagnosis
    assert cal.plausibility is not None  # plausible() gives every fit its verdict
    assert result is not None and last is not None
    out = {
        **result.to_dict(),
        "extended": {"cv_rms_mm": last.extended_cv_rms_mm},
        "gain": choice.gain if result.cause is not None else 1.0,
        "causes": choice.causes(),
        "plausibility": cal.plausibility.to_dict(),
        "residual": found.residual.to_dict(),
    }
    atomic_write(path, as_flags(json_text(out)))
    print(f"written to {path}")


def _created(folder: Path) -> Path:
    """``--plots DIR``, created (with its parents) when missing.

    Raises:
        OutputError: the folder cannot be created.
    """
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create the --plots folder {folder}: {exc.strerror or exc}") from None
    return folder


def _p_text(p_value: float, draws: int) -> str:
    """A candidate's family-wise p-value in words: ``p <= 1/(D+1)`` when none of the ``D`` draws of
    noise reached its gain (the smallest a Monte Carlo test can say)."""
    if draws == 0:
        return "no null drawn"
    floor = 1.0 / (draws + 1)
    return f"p <= {floor:.2g} (family-wise)" if p_value <= floor else f"p = {p_value:.2g} (family-wise)"
