"""The table a person reads: ``pincal calibrate``'s summary of a calibration (errors before and
after, identifiability, outliers, each placement of a fixture, what was chosen, warnings).
:mod:`pincal.report.report` holds the JSON and the findings both print."""

from __future__ import annotations

from pincal.auto.choice import choice_of
from pincal.data.dataset import Dataset
from pincal.identify.calibration import Calibration
from pincal.identify.evaluation import ErrorStats, point_spread
from pincal.identify.groups import MODEL_WORDS, parameter_groups
from pincal.identify.validity import region_text
from pincal.report.outcome import Outcome
from pincal.report.report import extension_dict, findings, listed_names, report_warnings

#: Fixed points within this distance of each other are one placement of a fixture [m].
SMALL = 0.2


def _spread(cal: Calibration, data: Dataset) -> float:
    """How far apart the fixed points of ``data`` are, by the calibrated model [m]."""
    return point_spread(cal.model, cal.measurement, cal.theta, data, cal.extension)


#: Said of a cause named with ``model=offsets``, which fits no geometry.
OFFSETS_CAUSE = (
    "model=offsets fits no geometry: the effect may stand in for joint placement errors; "
    "see whether model=placements names it too"
)


def _others(cal: Calibration) -> str:
    """The unknowns beside the model's that every fit holds, e.g. ``the 9 of instrument
    registration and tool``; empty when there are none."""
    model = MODEL_WORDS.get(cal.model.kind, cal.model.kind)
    others = [(w, n) for w, n, _ in parameter_groups(cal) if w not in (model, "effect") and n]
    if not others:
        return ""
    return f"the {sum(n for _, n in others)} of {' and '.join(w for w, _ in others)}"


def _fmt(stats: ErrorStats | None) -> str:
    if stats is None:
        return "-"
    if stats.point_mae_mm is not None:
        off = stats.point_distance_error_mm
        return f"{stats.point_mae_mm:8.4f} / " + ("       -" if off is None else f"{off:8.4f}")
    text = f"{stats.rms_mm:8.4f} / {stats.max_mm:8.4f}"
    if stats.rot_rms_mrad is not None:
        text += f"  ({stats.rot_rms_mrad:.3f} mrad)"
    return text


def _row(label: str, *stats: ErrorStats | None) -> str:
    return f"  {label:10s} " + " ".join(f"{_fmt(s):>21s}" for s in stats)


def _markers_said(cal: Calibration) -> str:
    """``, 3 markers (1, 2, 3)`` for several markers, else nothing."""
    labels = cal.measurement.markers
    return f", {len(labels)} markers ({', '.join(labels)})" if labels else ""


def choice_lines(cal: Calibration, data: Dataset | None = None) -> list[str]:
    """What was chosen and why, a line or a few."""
    choice, lines = choice_of(cal), list[str]()
    if choice is None:
        return lines
    sel = choice.selection
    if sel is not None:
        n_all = len(sel.path) - 1
        words = MODEL_WORDS.get(sel.model, sel.model)
        how = "by leave-one-out cross-validation on the fitted poses (linearised)"
        others = _others(cal)
        always = f"; {others} are always fitted" if others else ""
        if choice.params is None:
            lines.append(
                f"parameters: all {n_all} identifiable {words} parameters kept {how}: CV RMS "
                f"{sel.all_cv_rms_mm:.3f} mm, within {sel.keep_all:.0%} of the best subset's{always}"
            )
        else:
            lines.append(
                f"parameters: {len(choice.params)} of the {n_all} identifiable {words} parameters chosen "
                f"{how}: CV RMS {sel.cv_rms_mm:.3f} mm (all {n_all}: {sel.all_cv_rms_mm:.3f} mm){always}"
            )
            lines.append(f"  kept: {listed_names(choice.params)}")
            lines.append(f"  left out (stay nominal): {listed_names(choice.left_out)}")
    if choice.extension_mode == "auto":
        diag = choice.diagnosis
        if choice.extension is None or diag is None:
            why = choice.skipped or (
                "no effect on any joint lowered the cross-validated error enough to pass the diagnosis' "
                "test; pincal diagnose lists the candidates"
            )
            lines.append(f"cause: none ({why})")
        else:
            steps = choice.steps()
            first, last = steps[0][1], steps[-1][2]
            named = f"cause{'s' if len(steps) > 1 else ''}: {' + '.join(s[0] for s in steps)}"
            lines.append(
                f"{named}, {choice.folds}-fold CV RMS {first:.3f} → {last:.3f} mm (gain {first / last:.2f})"
            )
            if len(steps) > 1:  # each cause's own evidence and share of the gain
                total = first - last
                lines += [
                    f"  {label}: {before:.3f} → {after:.3f} mm ({(before - after) / total:.0%} of the gain)"
                    for label, before, after in steps
                ]
            if cal.model.kind == "offsets":  # its geometry is the URDF's: an effect may stand in for it
                lines.append(f"  {OFFSETS_CAUSE}")
        if diag is not None and diag.untried:
            lines.append(f"  {diag.untried}")
        lines += [f"  rejected {c.extension.label}: {c.implausible}" for c in (diag.rejected if diag else ())]
        if cal.balance is not None:
            weight = "∞: the geometry alone, the effect on top" if cal.balance.weight == float("inf") else ""
            lines.append(
                f"  URDF kept the best URDF alone: weight of the rows without the effect "
                f"{weight or f'{cal.balance.weight:g}'} (cross-validated)"
            )
        if len(choice.rounds) > 1:
            each = (
                f"{r.cause or 'none'} on {len(r.params or ()) or 'all'} parameters" for r in choice.rounds
            )
            scores = (f" ({r.extended_cv_rms_mm:.3f} mm)" for r in choice.rounds)
            lines.append("  rounds: " + "; ".join(a + b for a, b in zip(each, scores)))
    ext = extension_dict(cal, data)
    for part in [ext] if isinstance(ext, dict) else ext or []:
        if "stiffness" in part:
            lines.append(f"  {part['joint']}: {part['stiffness']['verdict']}")
    if choice.nested is not None:
        cv = choice.nested
        lines.append(
            f"whole procedure, nested {cv.folds}-fold CV (the call re-run without each fold): held-out RMS "
            f"{cv.after.rms_mm:.3f} mm (before {cv.before.rms_mm:.3f} mm)"
        )
    elif choice.params_mode == "auto" and choice.nested_note != "not asked for":
        lines.append(f"nested cross-validation {choice.nested_note}")
    return lines


def _exported_rows(cal: Calibration, outcome: Outcome | None) -> list[str]:
    """The URDF alone's errors, as written and loaded back, where they differ from ``after``."""
    if outcome is None:
        return []
    ex, rows = outcome.exported, []
    for label, alone, after in (("fitted", ex.train, cal.train_after), ("held out", ex.test, cal.test_after)):
        if alone is not None and after is not None and abs(alone.rms_mm - after.rms_mm) > 1e-6:
            rows.append(f"  {label:10s} {'':>21s} {'URDF alone:':>21s} {_fmt(alone)}")
    if rows:
        rows.append(
            "  (URDF alone: the written URDF with the sidecar's registration and tool, without its "
            f"{cal.extension.label if cal.extension else 'extension'})"
        )
    return rows


def marker_rows(cal: Calibration) -> list[str]:
    """Several markers: one row per marker, its error after on the fitted and held-out poses."""
    if not cal.train_markers:
        return []
    lines = [f"  per marker, after: {'fitted':>21s} {'held out':>21s}"]
    for label, fitted in cal.train_markers.items():
        held = cal.test_markers.get(label)
        lines.append(f"  marker {label:10s} {_fmt(fitted):>21s} {_fmt(held):>21s}")
    return lines


def summary(
    cal: Calibration, data: Dataset | None = None, test: Dataset | None = None, outcome: Outcome | None = None
) -> str:
    """A readable before/after table, the identifiability summary and what was chosen; with
    ``outcome``, the exported URDF alone's row where it differs from ``after``, and what remains."""
    ident = cal.identifiability
    kind = cal.measurement.measure
    what, stat = kind.error, kind.statistic
    lines = [
        f"robot {cal.robot.name} ({cal.robot.n_joints} joints, tip {cal.robot.tip}), model {cal.model.kind}, "
        f"measure {cal.measurement.kind}, {cal.n_poses} poses{_markers_said(cal)}",
        f"parameters: {ident.n_identifiable} of {len(cal.names)} identifiable from this data ("
        + ", ".join(f"{words} {n} of {total}" for words, n, total in parameter_groups(cal))
        + f"), condition number {ident.condition_number:.3g}",
        f"{what} [mm], {stat}:",
        f"  {'':10s} {'URDF as is':>21s} {'before':>21s} {'after':>21s}",
        _row("fitted", cal.train_urdf, cal.train_before, cal.train_after),
    ]
    if cal.test_after is not None:
        lines.append(_row("held out", cal.test_urdf, cal.test_before, cal.test_after))
    lines += _exported_rows(cal, outcome)
    lines += marker_rows(cal)
    fitted = kind.fitted
    lines.append(f"  (before: nominal kinematics, {fitted} fitted; URDF as is: nominal tool)")
    if ident.gauges:
        lines.append(
            f"not identifiable from fixed points, a parameter held for each: the whole set-up's "
            f"{', '.join(ident.gauges)} (base axes)"
        )
    if cal.excluded:
        name = data.row_name if data is not None else (lambda row: f"row {row}")
        rows = ", ".join(f"{name(row)} ({size:.3f} mm)" for row, size in cal.excluded)
        lines.append(f"outliers left out of the fit (residual far outside the others'): {rows}")
    found = findings(cal, data)
    each = found[0]
    if each:
        lines.append(f"per placement, after [mm], {stat}:")
        width = max(len(p.name) for p in each)
        lines += [
            f"  {p.name:{width}s} {_fmt(p.after)}  {p.rows} rows"
            + (f", {p.left_out} left out" if p.left_out else "")
            + (f" ({p.misplaced} at another point)" if p.misplaced else "")
            + ("  <- suspect" if p.suspect else "")
            for p in each
        ]
    elif kind.fixed_points and data is not None and _spread(cal, data) < SMALL:
        lines.append(
            f"note: the points lie within {SMALL:.1f} m of each other (one placement of a fixture): the fit "
            "sees the arm around them only; record placements spread over where the robot works and "
            "calibrate their folder at once (MUKCa's Pandas: 0.39 mm on other placements from one, 0.25 from "
            "all the others)"
        )
    lines += choice_lines(cal, data)
    lines += [part.text() for part in (cal.prior, cal.guard) if part is not None]
    said = None if cal.guard is None else region_text(cal.guard.region)
    lines += [said] if said else []
    if cal.plausibility is not None and not cal.plausibility.plausible:
        lines.append(f"plausibility: this calibration cannot be right: {cal.plausibility.hint}")
    if outcome is not None:
        lines.append(f"residual: {outcome.residual.sentence()}; {outcome.residual.how}")
        caveat = outcome.caveat()
        lines += [f"note: {caveat}"] if caveat else []
    return "\n".join(lines + [f"warning: {w}" for w in report_warnings(cal, data, test, found)])
