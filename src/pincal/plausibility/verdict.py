"""The verdict of :mod:`pincal.plausibility.judge`: checks with their limits and margins, the likely
cause and the one line that says it, and the sizes the checks compare with."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from pincal.identify.evaluation import ErrorStats
from pincal.robot.robots import Robot

#: Distance of the measured point (or the TCP) from the tip frame / robot size.
TOOL = 2.0


@dataclass(frozen=True)
class Check:
    """One comparison of a result with what a rigid arm can be.

    Attributes:
        name: ``outliers``, ``fit``, ``orientation``, ``before``, ``distance``, ``correction``, ``gain``,
            ``tool``.
        value: what the calibration shows, in ``unit``.
        limit: the largest plausible value.
        unit: ``ratio`` (a share or a factor) or ``rad``.
        text: what the value means, in words.
    """

    name: str
    value: float
    limit: float
    unit: str
    text: str

    @property
    def passed(self) -> bool:
        """Whether the value is within the limit."""
        return bool(self.value <= self.limit)

    @property
    def margin(self) -> float:
        """``limit / value``: how many times the value could grow before the check fails."""
        return float(self.limit / self.value) if self.value > 0 else float("inf")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary."""
        return {
            "name": self.name,
            "value": self.value,
            "limit": self.limit,
            "unit": self.unit,
            "passed": self.passed,
            "margin": self.margin,
            "text": self.text,
        }


@dataclass(frozen=True)
class Verdict:
    """Whether a calibration (or a TCP) is plausible, and if not, why.

    Attributes:
        checks: every comparison made, in the order of the module docstring.
        size_m: the robot's size the lengths are compared with [m] (:func:`robot_size`; 0 for a
            TCP calibration without a robot).
        cause: a short key of the likely cause, None when plausible: ``degrees``, ``radians``,
            ``swapped_xy`` (``_xz``, ``_yz``), ``quaternion_xyzw``, ``quaternion_wxyz``,
            ``instrument_frame``, ``tool_point``, ``model`` (the model does not reproduce the
            URDF), or else the name of the first failed check.
        hint: one line: the likely cause, its fix and the evidence; None when plausible.
        what: what was judged, for the messages (``calibration``, ``TCP``).
    """

    checks: tuple[Check, ...]
    size_m: float
    cause: str | None = None
    hint: str | None = None
    what: str = "calibration"

    @property
    def plausible(self) -> bool:
        """Whether every check passed."""
        return all(c.passed for c in self.checks)

    @property
    def failed(self) -> tuple[Check, ...]:
        """The checks that failed."""
        return tuple(c for c in self.checks if not c.passed)

    def message(self) -> str:
        """The one-line refusal."""
        return f"the {self.what} cannot be right: {self.hint}; pass accept_implausible=True to keep it anyway"

    def warning(self) -> str:
        """The one-line warning when the result is kept anyway (``accept_implausible=True``)."""
        return f"the {self.what} cannot be right, kept as asked (accept_implausible=True): {self.hint}"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary (the report's ``plausibility``)."""
        return {
            "plausible": self.plausible,
            "cause": self.cause,
            "hint": self.hint,
            "robot_size_mm": self.size_m * 1e3 if self.size_m else None,
            "checks": [c.to_dict() for c in self.checks],
        }


def robot_size(robot: Robot) -> float:
    """The robot's size [m]: the lengths of its chain's joint origins and tip placement, plus the
    strokes of its prismatic joints (at least 0.1 m)."""
    length = sum(float(np.linalg.norm(c.translation)) for c in robot.placements)
    strokes = np.where(np.asarray(robot.prismatic, dtype=bool), robot.upper - robot.lower, 0.0)
    length += float(np.sum(strokes[np.isfinite(strokes)]))
    return max(0.1, length)


def score_mm(stats: ErrorStats, weight: float) -> float:
    """The fit's own measure of an error [mm]: position RMS and the weighted orientation RMS."""
    return float(np.hypot(stats.rms_mm, (stats.rot_rms_mrad or 0.0) * weight))


def err_text(stats: ErrorStats) -> str:
    """An error in words: position RMS, and the orientation's when there is one."""
    text = f"{mm_text(stats.rms_mm * 1e-3)} RMS"
    if stats.rot_rms_mrad is not None:
        text += f" and {stats.rot_rms_mrad:.4g} mrad"
    return text


def mm_text(length_m: float) -> str:
    """A length [m] in millimetres, to three digits (whole millimetres from 100 mm)."""
    mm = length_m * 1e3
    return f"{mm:.0f} mm" if mm >= 100 else f"{mm:.3g} mm"


def share_text(length_m: float, size: float) -> str:
    """A length [m] as a share of the robot's size."""
    pct = 100 * length_m / size
    return (
        f"{pct:.0f} % of the robot's size ({size:.3g} m)"
        if pct >= 10
        else f"{pct:.2g} % of the robot's size ({size:.3g} m)"
    )
