"""The sidecar's ``extension``: the effects of the full model as JSON, written and read back.

``null`` without effects, one object for one, a list of objects for several (``contracts.md``):
each ``{"effect", "joint", "harmonic", "payload", "parameters": {NAME: {"value", "unit"}}}``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pincal.kinematics.effects import AnyEffect, Extension, combined, split_params
from pincal.kinematics.gravity import Payload
from pincal.robot.robots import Robot

#: What an entry says to a reader of the sidecar.
NOTE = "a joint-angle error the URDF cannot hold: command q, the joint reaches q + the sum of the effects"


def effect_entry(extension: Extension, params: np.ndarray) -> dict[str, Any]:
    """One effect and its parameters as the sidecar writes it."""
    load = extension.payload
    return {
        "effect": extension.effect,
        "joint": extension.joint,
        "harmonic": extension.harmonic,
        "payload": None if load is None else {"mass_kg": load.mass, "com_m": list(load.com)},
        "parameters": {
            n: {"value": float(v), "unit": u} for n, v, u in zip(extension.names, params, extension.units)
        },
        "note": NOTE,
    }


def effects_json(extension: AnyEffect | None, params: np.ndarray) -> Any:
    """None, one entry, or a list of entries (several effects)."""
    if extension is None:
        return None
    entries = [effect_entry(e, p) for e, p in split_params(extension, params)]
    return entries[0] if len(entries) == 1 else entries


def _payload(spec: dict[str, Any]) -> Payload | None:
    load = spec.get("payload")
    if load is None:
        return None
    com = [float(c) for c in load["com_m"]]
    return Payload(float(load["mass_kg"]), (com[0], com[1], com[2]))


def read_effects(robot: Robot, spec: Any) -> tuple[AnyEffect | None, np.ndarray]:
    """The effects a sidecar's ``extension`` holds (null, one object or a list) on ``robot``, and
    their parameters.

    Raises:
        ValueError, KeyError, TypeError: an entry of another shape, or a parameter that is not a
            finite number (the loader names the file).
    """
    entries = [] if spec is None else [spec] if isinstance(spec, dict) else list(spec)
    parts, params = [], []
    for entry in entries:
        ext = Extension(
            robot, entry["effect"], entry["joint"], int(entry.get("harmonic") or 1), _payload(entry)
        )
        values = [float(entry["parameters"][n]["value"]) for n in ext.names]
        if not np.all(np.isfinite(values)):
            raise ValueError("extension: a parameter that is not a finite number")
        parts.append(ext)
        params += values
    return combined(parts), np.array(params, dtype=float)
