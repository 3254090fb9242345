"""The calibration report: the JSON of ``contracts.md`` and a table a person reads.

Parameter values are written in mm and mrad. Model parameters are corrections to the nominal
geometry; ``instrument.*`` is the identified ``instrument_T_base`` (translation [mm] and
rotation vector [mrad]) and ``tool.*`` the measured point or frame on the tip, both absolute.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from pincal.data.dataset import Dataset
from pincal.export.urdf_writer import origin_changes
from pincal.identify.calibration import Calibration
from pincal.identify.evaluation import (
    ErrorStats,
    Misplaced,
    PlacementErrors,
    misplaced_rows,
    placement_errors,
)
from pincal.identify.uncertainty import STD_MEANS
from pincal.identify.validity import region_dict
from pincal.json_text import json_text
from pincal.kinematics.effects import Extension, split_params
from pincal.kinematics.models import PoeModel
from pincal.kinematics.stiffness import compliance_stiffness
from pincal.report.outcome import Outcome

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


def effect_dict(ext: Extension, params: np.ndarray, data: Dataset | None = None) -> dict[str, Any]:
    """One effect: its label, parameters and, for a joint compliance with the fitted poses ``data``
    given, the stiffness it implies."""
    out: dict[str, Any] = {
        "effect": ext.effect,
        "joint": ext.joint,
        "label": ext.label,
        "parameters": {n: {"value": float(v), "unit": u} for n, v, u in zip(ext.names, params, ext.units)},
    }
    if ext.effect == "joint_compliance" and data is not None:
        out["stiffness"] = compliance_stiffness(ext, float(params[0]), data.q).to_dict()
    return out


def extension_dict(cal: Calibration, data: Dataset | None = None) -> dict[str, Any] | list[Any] | None:
    """The effects identified with the geometry: None, one :func:`effect_dict`, or a list of them."""
    if cal.extension is None:
        return None
    each = [effect_dict(e, p, data) for e, p in split_params(cal.extension, cal.effect_params)]
    return each[0] if len(each) == 1 else each


def _choice_dict(cal: Calibration) -> dict[str, Any] | None:
    """The choice of the full model, with ``urdf_kept``: the parameters the URDF alone holds
    (``kept`` when the URDF holds the full model's geometry; None: every identifiable one)."""
    if cal.choice is None:
        return None
    out = cal.choice.to_dict()
    written = cal.written.choice
    out["urdf_kept"] = out["kept"] if written is None else written.to_dict()["kept"]
    return out


def _pair(
    before: ErrorStats | None,
    after: ErrorStats | None,
    urdf: ErrorStats | None,
    alone: ErrorStats | None,
    rows: list[int] | None = None,
) -> Any:
    """The report's ``train`` or ``test``: ERR before and after, the URDF as is, the URDF alone as
    exported, and the rows scored (None without poses)."""
    if before is None or after is None:
        return None
    out: dict[str, Any] = {"before": before.to_dict(), "after": after.to_dict(), "rows": rows}
    if urdf is not None:
        out["urdf"] = urdf.to_dict()
    if alone is not None:
        out["exported"] = alone.to_dict()
    return out


def _poe_dict(cal: Calibration) -> dict[str, Any]:
    """For a POE model, the calibrated twists [mm for v] and the tool point at zero angles [mm]."""
    if not isinstance(cal.model, PoeModel):
        return {}
    _, _, tool = cal.split()
    rot, pos = cal.base_T_tip(np.zeros(cal.robot.n_joints))
    home = pin.SE3(rot[0], pos[0])
    twists = [
        {"joint": j, "omega": [float(v) for v in xi[3:]], "v_mm": [float(v) * 1e3 for v in xi[:3]]}
        for j, xi in zip(cal.robot.joint_names, cal.model.joint_twists(cal.x))
    ]
    return {"twists": twists, "p_E0_mm": [float(v) * 1e3 for v in home.act(tool.translation)]}


def report_dict(
    cal: Calibration, data: Dataset | None = None, test: Dataset | None = None, outcome: Outcome | None = None
) -> dict[str, Any]:
    """The report of ``contracts.md`` (and more); ``data``, ``test``: the fitted and held-out
    poses, for the stiffness a compliance implies and the warnings; ``outcome``: the exported
    files' errors and the residual verdict (:func:`pincal.report.outcome.outcome`)."""
    exported = outcome.exported if outcome is not None else None

    ident, found = cal.identifiability, findings(cal, data)
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
        if cal.measurement.measure.orientation
        else None,
        "before_means": "nominal kinematics with the instrument registration and tool fitted",
        "urdf_means": "the URDF as it is: nominal tool, only the instrument registration fitted",
        "exported_means": "the written URDF alone, with the sidecar's registration and tool (as a URDF "
        "consumer loads it); after: the URDF with the whole sidecar",
        "train": with_markers(
            _pair(
                cal.train_before,
                cal.train_after,
                cal.train_urdf,
                exported.train if exported else None,
                scored_rows(data, cal.excluded),
            ),
            cal.train_markers,
        ),
        "test": with_markers(
            _pair(
                cal.test_before,
                cal.test_after,
                cal.test_urdf,
                exported.test if exported else None,
                scored_rows(test),
            ),
            cal.test_markers,
        ),
        "residual": None if outcome is None else outcome.residual.to_dict(),
        "balance": None if cal.balance is None else cal.balance.to_dict(),
        "solver": {
            "jacobian_evaluations": cal.n_evaluations,
            "message": cal.message,
            "converged": cal.converged,
        },
        "std_means": STD_MEANS,
        "excluded_poses": [{"row": row, "residual_mm": size} for row, size in cal.excluded],
        "joint_changes": [change.to_dict() for change in origin_changes(cal)],
        "parameters": parameter_rows(cal),
        "placements": [p.to_dict() for p in found[0]],
        "warnings": report_warnings(cal, data, test, found),
        "choice": _choice_dict(cal),
        "prior": None if cal.prior is None else cal.prior.to_dict(),
        "guard": None if cal.guard is None else cal.guard.to_dict(),
        "validity_region": None if cal.guard is None else region_dict(cal.guard.region),
        "plausibility": None if cal.plausibility is None else cal.plausibility.to_dict(),
        "extension": extension_dict(cal, data),
        **_poe_dict(cal),
    }


def scored_rows(data: Dataset | None, excluded: tuple[tuple[int, float], ...] = ()) -> list[int] | None:
    """The 1-based data rows (as ``excluded_poses`` numbers them) of the poses of ``data`` a set's
    figures score: the rows the outlier screen left out are not among them (None without data)."""
    if data is None:
        return None
    left_out = {int(row) for row, _ in excluded}
    rows = dict.fromkeys(int(row) for row in data.row_numbers)  # several markers: a pose's row once
    return [row for row in rows if row not in left_out]


def with_markers(entry: dict[str, Any] | None, markers: dict[str, ErrorStats]) -> dict[str, Any] | None:
    """A ``train`` or ``test`` entry with ``markers`` (several markers: the full model's ERR of each)."""
    if entry is None or not markers:
        return entry
    return {**entry, "markers": {label: stats.to_dict() for label, stats in markers.items()}}


def report_json(
    cal: Calibration,
    data: Dataset | None = None,
    test: Dataset | None = None,
    outcome: Outcome | None = None,
    **extra: Any,
) -> str:
    """The report as JSON text (no NaN or infinity: those become null), with ``extra`` keys."""

    return json_text({**report_dict(cal, data, test, outcome), **extra})


#: What the report says of fitted fixed-point data: each placement's errors, the misplaced rows.
Findings = tuple[list[PlacementErrors], list[Misplaced]]


def findings(cal: Calibration, data: Dataset | None) -> Findings:
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
    return findings(cal, data)[0]


#: A held-out error this many times the nominal kinematics' is "worse" (not a tie to rounding).
WORSE = 1.01


def _fit_warnings(cal: Calibration) -> list[str]:
    """The fit's own warnings: a solver stopped at its evaluation limit, a pull's weight at the
    edge of the grid the evidence scanned."""
    out = []
    if not cal.converged:
        out.append(
            f"the solver stopped at its evaluation limit ({cal.message}): the fit is not a minimum; "
            "check the data and units, or fit fewer parameters"
        )
    if cal.prior is not None and cal.prior.at_edge:
        out.append(
            f"the pull's weight {cal.prior.weight:.3g} is at the edge of the weights the evidence scanned: "
            "the data hardly determine the corrections (give --prior to set it)"
        )
    return out


def report_warnings(
    cal: Calibration, data: Dataset | None = None, test: Dataset | None = None, found: Findings | None = None
) -> list[str]:
    """What the user should know before trusting the result: held-out poses predicted worse
    than by the nominal kinematics, placements whose rows disagree with themselves, fixed-point
    rows (fitted ``data`` or held-out ``test``) that sit at another point than their own,
    held-out points that hold no known distance (its error is not judged);
    ``found``: :func:`findings` of ``data`` when already computed."""
    each, misplaced = findings(cal, data) if found is None else found
    out = _fit_warnings(cal)
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
    known = cal.measurement.point_distances if cal.measurement.measure.fixed_points else ()
    unjudged = cal.test_after is not None and cal.test_after.point_distance_error_mm is None
    if test is not None and known and unjudged:
        pairs = ", ".join(f"{a}-{b}" for a, b, _ in known)
        out.append(
            f"the held-out points ({', '.join(test.point_names)}) hold no pair of a known distance "
            f"({pairs}): their distance error is not judged; name them as the fitted data's points"
        )
    return out


def _misplaced(found: list[Misplaced], data: Dataset, which: str) -> list[str]:
    """One warning per pair of points (filed under, at) that has misplaced rows of ``data``."""
    out = []
    for point, near in dict.fromkeys((m.point, m.near) for m in found):
        group = [m for m in found if (m.point, m.near) == (point, near)]
        names = listed_names(tuple(data.row_name(m.row) for m in group), 6)
        off, at = (f"{min(v):.2f}-{max(v):.2f}" for v in zip(*((m.off_mm, m.at_mm) for m in group)))
        out.append(
            f"{len(group)} {which} rows filed under point {point} sit at point {near} ({at} mm from its "
            f"rows, {off} mm from {point}'s): the ball was in the other socket, or the rows were saved "
            f"in the wrong file; move them to point {near}'s file: {names}"
        )
    return out


def listed_names(names: tuple[str, ...], most: int = 10) -> str:
    """The first ``most`` names, comma-separated, and how many more."""
    return ", ".join(names[:most]) + (f" and {len(names) - most} more" if len(names) > most else "")
