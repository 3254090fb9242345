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

from .evaluation import ErrorStats
from .models import PoeModel
from .solver import Calibration

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


def report_dict(cal: Calibration) -> dict[str, Any]:
    """The report of ``contracts.md`` (and more)."""

    def pair(before: ErrorStats | None, after: ErrorStats | None, urdf: ErrorStats | None) -> Any:
        if before is None or after is None:
            return None
        out = {"before": before.to_dict(), "after": after.to_dict()}
        if urdf is not None:
            out["urdf"] = urdf.to_dict()
        return out

    ident = cal.identifiability
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
        **extra,
    }


def report_json(cal: Calibration, **extra: Any) -> str:
    """The report as JSON text (no NaN or infinity: those become null), with ``extra`` keys."""

    def clean(obj: Any) -> Any:
        if isinstance(obj, float) and not np.isfinite(obj):
            return None
        if isinstance(obj, dict):
            return {k: clean(v) for k, v in obj.items()}
        if isinstance(obj, list):
            return [clean(v) for v in obj]
        return obj

    return json.dumps(clean({**report_dict(cal), **extra}), indent=2) + "\n"


def _fmt(stats: ErrorStats | None) -> str:
    if stats is None:
        return "-"
    text = f"{stats.rms_mm:8.4f} / {stats.max_mm:8.4f}"
    if stats.rot_rms_mrad is not None:
        text += f"  ({stats.rot_rms_mrad:.3f} mrad)"
    return text


def _row(label: str, *stats: ErrorStats | None) -> str:
    return f"  {label:10s} " + " ".join(f"{_fmt(s):>21s}" for s in stats)


def summary(cal: Calibration) -> str:
    """A readable before/after table and the identifiability summary."""
    ident = cal.identifiability
    what = "abs. distance error over pairs" if cal.measurement.kind == "distance" else "position error"
    lines = [
        f"robot {cal.robot.name} ({cal.robot.n_joints} joints, tip {cal.robot.tip}), model {cal.model.kind}, "
        f"measure {cal.measurement.kind}, {cal.n_poses} poses",
        f"parameters: {ident.n_identifiable} identifiable of {len(cal.names)}, "
        f"condition number {ident.condition_number:.3g}",
        f"{what} [mm], RMS / max:",
        f"  {'':10s} {'URDF as is':>21s} {'before':>21s} {'after':>21s}",
        _row("fitted", cal.train_urdf, cal.train_before, cal.train_after),
    ]
    if cal.test_after is not None:
        lines.append(_row("held out", cal.test_urdf, cal.test_before, cal.test_after))
    lines.append("  (before: nominal kinematics, registration and tool fitted; URDF as is: nominal tool)")
    if cal.excluded:
        rows = ", ".join(f"row {row} ({size:.3f} mm)" for row, size in cal.excluded)
        lines.append(f"outliers left out of the fit (residual far outside the others'): {rows}")
    return "\n".join(lines)
