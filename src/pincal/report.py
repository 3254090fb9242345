"""The calibration report: the JSON of ``contracts.md`` and a table a person reads.

Parameter values are written in mm and mrad. Model parameters are corrections to the nominal
geometry; ``instrument.*`` is the identified ``instrument_T_base`` (translation [mm] and
rotation vector [mrad]) and ``tool.*`` the measured point or frame on the tip, both absolute.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pinocchio as pin

from .calibration import Calibration
from .data import Dataset
from .effects import compliance_stiffness
from .evaluation import ErrorStats, Misplaced, PlacementErrors, misplaced_rows, placement_errors, point_spread
from .models import PoeModel

_TO_DISPLAY = {"m": (1e3, "mm"), "rad": (1e3, "mrad")}


def parameter_rows(cal: Calibration) -> list[dict[str, Any]]:
    """One row per unknown: name, value, std, unit, identifiable and, if held, why."""
    _, reg, tool = cal.split()
    absolute: dict[str, float] = {}
    for prefix, se3 in (("instrument", reg), ("tool", tool)):
        rotvec = pin.log3(se3.rotation)
        for k, axis in enumerate("xyz"):
            absolute[f"{prefix}.t{axis}"] = float(se3.translation[k])
            absolute[f"{prefix}.r{axis}"] = float(rotvec[k])
            absolute[f"{prefix}.{axis}"] = float(se3.translation[k])
    rows = []
    reasons = cal.identifiability.reasons
    for i, (name, unit) in enumerate(zip(cal.names, cal.units)):
        factor, shown = _TO_DISPLAY.get(unit, (1.0, unit))
        value = absolute.get(name, float(cal.theta[i]))
        row: dict[str, Any] = {
            "name": name,
            "value": value * factor,
            "std": float(cal.std[i]) * factor,
            "unit": shown,
            "identifiable": bool(cal.identifiability.identifiable[i]),
        }
        if name in reasons:
            row["reason"] = reasons[name]
        rows.append(row)
    return rows


def extension_dict(cal: Calibration, data: Dataset | None = None) -> dict[str, Any] | None:
    """The extension identified with the geometry: its label, parameters and, for a joint
    compliance with the fitted poses ``data`` given, the stiffness it implies."""
    ext = cal.extension
    if ext is None:
        return None
    out: dict[str, Any] = {
        "effect": ext.effect,
        "joint": ext.joint,
        "label": ext.label,
        "parameters": {
            n: {"value": float(v), "unit": u} for n, v, u in zip(ext.names, cal.effect_params, ext.units)
        },
    }
    if ext.effect == "joint_compliance" and data is not None:
        out["stiffness"] = compliance_stiffness(ext, float(cal.effect_params[0]), data.q).to_dict()
    return out


def report_dict(cal: Calibration, data: Dataset | None = None, test: Dataset | None = None) -> dict[str, Any]:
    """The report of ``contracts.md`` (and more); ``data``, ``test``: the fitted and held-out
    poses, for the stiffness a compliance implies and the warnings."""

    def pair(before: ErrorStats | None, after: ErrorStats | None, urdf: ErrorStats | None) -> Any:
        if before is None or after is None:
            return None
        out = {"before": before.to_dict(), "after": after.to_dict()}
        if urdf is not None:
            out["urdf"] = urdf.to_dict()
        return out

    ident, found = cal.identifiability, _findings(cal, data)
    extra: dict[str, Any] = {}
    if isinstance(cal.model, PoeModel):
        _, _, tool = cal.split()
        rot, pos = cal.base_T_tip(np.zeros(cal.robot.n_joints))
        home = pin.SE3(rot[0], pos[0])
        extra["twists"] = [
            {"joint": j, "omega": [float(v) for v in xi[3:]], "v_mm": [float(v) * 1e3 for v in xi[:3]]}
            for j, xi in zip(cal.robot.joint_names, cal.model.joint_twists(cal.x))
        ]
        extra["p_E0_mm"] = [float(v) * 1e3 for v in home.act(tool.translation)]
    return {
        "robot": cal.robot.name,
        "tip": cal.robot.tip,
        "joints": list(cal.robot.joint_names),
        "model": cal.model.kind,
        "measure": cal.measurement.kind,
        "n_poses": cal.n_poses,
        "n_params": len(cal.names),
        "n_identifiable": ident.n_identifiable,
        "condition_number": ident.condition_number,
        "singular_values": [float(s) for s in ident.singular_values],
        "held": dict(sorted(ident.reasons.items())),
        "not_identifiable": list(ident.gauges),
        "rotation_weight_m_per_rad": cal.measurement.rotation_weight
        if cal.measurement.kind == "pose"
        else None,
        "before_means": "nominal kinematics with the instrument registration and tool fitted",
        "urdf_means": "the URDF as it is: nominal tool, only the instrument registration fitted",
        "train": pair(cal.train_before, cal.train_after, cal.train_urdf),
        "test": pair(cal.test_before, cal.test_after, cal.test_urdf),
        "solver": {"jacobian_evaluations": cal.n_evaluations, "message": cal.message},
        "excluded_poses": [{"row": row, "residual_mm": size} for row, size in cal.excluded],
        "parameters": parameter_rows(cal),
        "placements": [p.to_dict() for p in found[0]],
        "warnings": report_warnings(cal, data, test, found),
        "choice": None if cal.choice is None else cal.choice.to_dict(),
        "extension": extension_dict(cal, data),
        **extra,
    }


def report_json(
    cal: Calibration, data: Dataset | None = None, test: Dataset | None = None, **extra: Any
) -> str:
    """The report as JSON text (no NaN or infinity: those become null), with ``extra`` keys."""

    def clean(obj: Any) -> Any:
        if isinstance(obj, float) and not np.isfinite(obj):
            return None
        if isinstance(obj, dict):
            return {k: clean(v) for k, v in obj.items()}
        if isinstance(obj, list):
            return [clean(v) for v in obj]
        return obj

    return json.dumps(clean({**report_dict(cal, data, test), **extra}), indent=2) + "\n"


#: What the report says of fitted fixed-point data: each placement's errors, the misplaced rows.
Findings = tuple[list[PlacementErrors], list[Misplaced]]


def _findings(cal: Calibration, data: Dataset | None) -> Findings:
    """Each placement's errors and the misplaced rows of the fitted ``data``, found once."""
    if data is None:
        return [], []
    found = misplaced_rows(cal.model, cal.measurement, cal.theta, data, cal.extension)
    left_out, misplaced = tuple(row for row, _ in cal.excluded), tuple(m.row for m in found)
    each = placement_errors(cal.model, cal.measurement, cal.theta, data, cal.extension, left_out, misplaced)
    return each, found


def placements(cal: Calibration, data: Dataset | None) -> list[PlacementErrors]:
    """Each placement's errors after calibration, for fixed-point data of several placements
    (``data``: the fitted data); else an empty list."""
    return _findings(cal, data)[0]


#: Fixed points within this distance of each other are one placement of a fixture [m].
SMALL = 0.2


def _spread(cal: Calibration, data: Dataset) -> float:
    """How far apart the fixed points of ``data`` are, by the calibrated model [m]."""
    return point_spread(cal.model, cal.measurement, cal.theta, data, cal.extension)


#: A held-out error this many times the nominal kinematics' is "worse" (not a tie to rounding).
WORSE = 1.01


def report_warnings(
    cal: Calibration, data: Dataset | None = None, test: Dataset | None = None, found: Findings | None = None
) -> list[str]:
    """What the user should know before trusting the result: held-out poses predicted worse
    than by the nominal kinematics, placements whose rows disagree with themselves, fixed-point
    rows (fitted ``data`` or held-out ``test``) that sit at another point than their own;
    ``found``: :func:`_findings` of ``data`` when already computed."""
    each, misplaced = _findings(cal, data) if found is None else found
    out = []
    if cal.test_after is not None and cal.test_before is not None:
        after, before = cal.test_after.headline_mm, cal.test_before.headline_mm
        if after > before * WORSE:
            out.append(
                f"the calibrated model predicts the held-out poses worse than the nominal kinematics "
                f"({after:.3f} against {before:.3f} mm): what the fitted poses determine does not carry "
                "over to them; fit poses that cover where the robot works (sockets: several placements "
                "at once), or keep the URDF"
            )
    for p in each:
        if p.suspect:
            mae = float(p.after.point_mae_mm or 0.0)
            out.append(
                f"placement {p.name}: its rows scatter {mae:.3f} mm from their points after calibration "
                f"(the other placements' median {p.others_mae_mm:.3f} mm) and {p.left_out} of {p.rows} were "
                "left out as outliers: the fixture may have moved, or the ball slipped, while it was "
                "recorded; record it again, or calibrate without its folder"
            )
    if data is not None:
        out += _misplaced(misplaced, data, "fitted")
    if test is not None:
        out += _misplaced(
            misplaced_rows(cal.model, cal.measurement, cal.theta, test, cal.extension), test, "held-out"
        )
    return out


def _misplaced(found: list[Misplaced], data: Dataset, which: str) -> list[str]:
    """One warning per pair of points (filed under, at) that has misplaced rows of ``data``."""
    out = []
    for point, near in dict.fromkeys((m.point, m.near) for m in found):
        group = [m for m in found if (m.point, m.near) == (point, near)]
        names = _names(tuple(data.row_name(m.row) for m in group), 6)
        off, at = (f"{min(v):.2f}-{max(v):.2f}" for v in zip(*((m.off_mm, m.at_mm) for m in group)))
        out.append(
            f"{len(group)} {which} rows filed under point {point} sit at point {near} ({at} mm from its "
            f"rows, {off} mm from {point}'s): the ball was in the other socket, or the rows were saved "
            f"in the wrong file; move them to point {near}'s file: {names}"
        )
    return out


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


def _names(names: tuple[str, ...], most: int = 10) -> str:
    return ", ".join(names[:most]) + (f" and {len(names) - most} more" if len(names) > most else "")


def choice_lines(cal: Calibration, data: Dataset | None = None) -> list[str]:
    """What was chosen and why, a line or a few."""
    choice, lines = cal.choice, list[str]()
    if choice is None:
        return lines
    sel = choice.selection
    if sel is not None:
        n_all = len(sel.path) - 1
        how = "by leave-one-out cross-validation on the fitted poses (linearised)"
        if choice.params is None:
            lines.append(
                f"parameters: all {n_all} {sel.model} parameters kept {how}: CV RMS "
                f"{sel.all_cv_rms_mm:.3f} mm, within {sel.keep_all:.0%} of the best subset's"
            )
        else:
            lines.append(
                f"parameters: {len(choice.params)} of {n_all} {sel.model} parameters chosen {how}: "
                f"CV RMS {sel.cv_rms_mm:.3f} mm (all {n_all}: {sel.all_cv_rms_mm:.3f} mm)"
            )
            lines.append(f"  kept: {_names(choice.params)}")
            lines.append(f"  left out (stay nominal): {_names(choice.left_out)}")
    if choice.extension_mode == "auto":
        diag = choice.diagnosis
        if choice.extension is None or diag is None:
            best = diag.candidates[0].extension.label if diag is not None and diag.candidates else "none"
            why = choice.skipped or f"the diagnosis' test passed no candidate; best {best}"
            lines.append(f"cause: none ({why})")
        else:
            lines.append(
                f"cause: {choice.extension.label}, {choice.folds}-fold CV RMS "
                f"{diag.baseline_cv_rms_mm:.3f} → {diag.extended_cv_rms_mm:.3f} mm (gain {diag.gain:.2f})"
            )
        if diag is not None and diag.untried:
            lines.append(f"  {diag.untried}")
        if len(choice.rounds) > 1:
            each = (f"{r.cause or 'none'} on {len(r.params or ()) or 'all'} parameters"
                    for r in choice.rounds)
            scores = (f" ({r.extended_cv_rms_mm:.3f} mm)" for r in choice.rounds)
            lines.append("  rounds: " + "; ".join(a + b for a, b in zip(each, scores)))
    ext = extension_dict(cal, data)
    if ext is not None and "stiffness" in ext:
        lines.append(f"  {ext['joint']}: {ext['stiffness']['verdict']}")
    if choice.nested is not None:
        cv = choice.nested
        lines.append(
            f"whole procedure, nested {cv.folds}-fold CV (the call re-run without each fold): held-out RMS "
            f"{cv.after.rms_mm:.3f} mm (before {cv.before.rms_mm:.3f} mm)"
        )
    elif choice.params_mode == "auto" and choice.nested_note != "not asked for":
        lines.append(f"nested cross-validation {choice.nested_note}")
    return lines


def summary(cal: Calibration, data: Dataset | None = None, test: Dataset | None = None) -> str:
    """A readable before/after table, the identifiability summary and what was chosen."""
    ident = cal.identifiability
    kind = cal.measurement.kind
    names = {"distance": "abs. distance error over pairs", "points": "fixed points"}
    what = names.get(kind, "position error")
    stat = "mean from the point's mean / distance error" if kind == "points" else "RMS / max"
    lines = [
        f"robot {cal.robot.name} ({cal.robot.n_joints} joints, tip {cal.robot.tip}), model {cal.model.kind}, "
        f"measure {cal.measurement.kind}, {cal.n_poses} poses",
        f"parameters: {ident.n_identifiable} identifiable of {len(cal.names)}, "
        f"condition number {ident.condition_number:.3g}",
        f"{what} [mm], {stat}:",
        f"  {'':10s} {'URDF as is':>21s} {'before':>21s} {'after':>21s}",
        _row("fitted", cal.train_urdf, cal.train_before, cal.train_after),
    ]
    if cal.test_after is not None:
        lines.append(_row("held out", cal.test_urdf, cal.test_before, cal.test_after))
    fitted = "tool and points" if kind == "points" else "registration and tool"
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
    found = _findings(cal, data)
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
    elif kind == "points" and data is not None and _spread(cal, data) < SMALL:
        lines.append(
            f"note: the points lie within {SMALL:.1f} m of each other (one placement of a fixture): the fit "
            "sees the arm around them only; record placements spread over where the robot works and "
            "calibrate their folder at once (MUKCa's Pandas: 0.39 mm on other placements from one, 0.25 from "
            "all the others)"
        )
    lines += choice_lines(cal, data)
    return "\n".join(lines + [f"warning: {w}" for w in report_warnings(cal, data, test, found)])
