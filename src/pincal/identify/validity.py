"""Where a fit holds: the joint ranges its poses cover, and its expected gain beyond them.

The records of :mod:`pincal.identify.extrapolation`, kept below the calibration that holds them
(through :class:`pincal.identify.records.Guard`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from pincal.robot.robots import Robot

#: A joint's range counts as narrower than its limits when the poses cover less than this share
#: of it (limits wider than a turn, or none, counted as one turn).
NARROW_SHARE = 0.5


@dataclass(frozen=True)
class JointRange:
    """The range of one joint the fitted poses cover, beside its limits.

    Attributes:
        joint: the joint's name.
        low, high: the smallest and largest value among the fitted poses [rad or m].
        lower, upper: the joint's limits [rad or m] (None: unlimited).
        unit: ``rad`` or ``m``.
    """

    joint: str
    low: float
    high: float
    lower: float | None
    upper: float | None
    unit: str

    @property
    def share(self) -> float:
        """The covered span over the limits' span (a turn at most, for a revolute joint), at most 1."""
        lo = -math.inf if self.lower is None else self.lower
        hi = math.inf if self.upper is None else self.upper
        span = hi - lo
        if self.unit == "rad":
            span = min(span, 2.0 * math.pi)
        return 1.0 if not math.isfinite(span) or span <= 0 else min(1.0, (self.high - self.low) / span)

    @property
    def narrow(self) -> bool:
        """The poses cover less than :data:`NARROW_SHARE` of the joint's range."""
        return self.share < NARROW_SHARE

    def to_dict(self) -> dict[str, Any]:
        """The report's entry for the joint."""
        return {
            "joint": self.joint,
            "min": self.low,
            "max": self.high,
            "lower_limit": self.lower,
            "upper_limit": self.upper,
            "unit": self.unit,
            "share_of_range": self.share,
        }


def joint_ranges(robot: Robot, q: np.ndarray) -> tuple[JointRange, ...]:
    """Each joint's range over the poses ``q`` (N, n) [rad or m], with its limits."""
    out = []
    for j, name in enumerate(robot.joint_names):
        lo, hi = float(robot.lower[j]), float(robot.upper[j])
        unit = "m" if robot.prismatic[j] else "rad"
        low, high = float(np.min(q[:, j])), float(np.max(q[:, j]))
        out.append(
            JointRange(
                name, low, high, lo if math.isfinite(lo) else None, hi if math.isfinite(hi) else None, unit
            )
        )
    return tuple(out)


#: The fit holds across the joint limits when its expected gain there is above this many of the
#: gain's posterior standard deviations (chosen on 200 simulated sessions per case, measured on
#: 200 others: ``benchmarks/extrapolation.py``).
Z_SPREAD = 2.0
#: The same for distance data, whose posterior whitens the pairs (chosen on 100 sessions per
#: case, measured on 100 others: ``benchmarks/extrapolation.py --measure distance``): at 1 the
#: check exported no fit more than 5 % worse than the nominal model, where 2 refused 40 of 99
#: fits of real errors on narrow ranges that were better than it.
Z_SPREAD_PAIRS = 1.0


@dataclass(frozen=True)
class Extrapolation:
    """The fit's expected gain over the nominal model across the joint limits and on its own poses.

    The expected gain at a configuration ``q`` is ``|m(q) - n(q)|² - |m(q) - f(q)|²``: ``n``,
    ``f`` and ``m`` the rows (tip positions; for pose data the weighted rotation rows too; for
    distance data the distances between every two configurations) that the nominal model, the fit
    and the posterior mean of every correction predict (:mod:`pincal.identify.extrapolation`).

    Attributes:
        whole_gain_mm2: mean expected gain over configurations drawn across the joint limits [mm²].
        data_gain_mm2: the same over the fitted poses [mm²].
        samples: the configurations drawn across the limits.
        weight: the pull's weight of the posterior the gains are expected under (every
            correction fitted, the weight of largest evidence) [per natural unit].
        whole_gain_sd_mm2: the posterior standard deviation of ``whole_gain_mm2`` [mm²].
        z_min: the fit holds above this many of those standard deviations (:data:`Z_SPREAD`;
            for distance data :data:`Z_SPREAD_PAIRS`).
    """

    whole_gain_mm2: float
    data_gain_mm2: float
    samples: int
    weight: float
    whole_gain_sd_mm2: float = 0.0
    z_min: float = Z_SPREAD

    @property
    def holds(self) -> bool:
        """The fit is expected to beat the nominal model across the joint limits, by more than
        :attr:`z_min` standard deviations of that expectation."""
        return self.whole_gain_mm2 > self.z_min * self.whole_gain_sd_mm2

    def text(self) -> str:
        """The verdict, for the guard's line."""
        said = (
            f"expected gain over the nominal model {self.whole_gain_mm2:.3g} ± "
            f"{self.whole_gain_sd_mm2:.2g} mm² across the joint limits, {self.data_gain_mm2:.3g} mm² "
            "on the fitted poses"
        )
        if self.holds:
            return said
        return (
            f"{said}: the fit is not expected to beat the nominal model outside the data by "
            f"{self.z_min:g} standard deviation{'' if self.z_min == 1 else 's'}"
        )

    def to_dict(self) -> dict[str, Any]:
        """The report's ``guard.extrapolation`` object."""
        return {
            "whole_gain_mm2": self.whole_gain_mm2,
            "data_gain_mm2": self.data_gain_mm2,
            "whole_gain_sd_mm2": self.whole_gain_sd_mm2,
            "samples": self.samples,
            "posterior_weight": self.weight,
            "holds": self.holds,
            "threshold_sd": self.z_min,
            "by": "mean over configurations drawn across the joint limits of |m - n|^2 - |m - f|^2: n, f "
            "and m the rows the nominal model, the fit and the posterior mean of every correction "
            "(pulled with posterior_weight) predict: tip positions, for pose data with the weighted "
            "rotation rows, for distance data the distances between every two configurations (the gain "
            "then per pair); holds above threshold_sd of its posterior standard deviations",
        }


def region_dict(region: tuple[JointRange, ...]) -> dict[str, Any] | None:
    """The report's and the sidecar's ``validity_region`` object (None without a region)."""
    if not region:
        return None
    return {
        "joints": [r.to_dict() for r in region],
        "narrower_than_limits": [r.joint for r in region if r.narrow],
        "means": "the range of each joint among the fitted poses [rad or m]: the calibration is validated "
        "there; a joint covering less than half its limits (a turn at most) is listed as narrower",
    }


def region_text(region: tuple[JointRange, ...]) -> str | None:
    """The summary's line when a joint's range is narrower than its limits, else None."""
    narrow = [r for r in region if r.narrow]
    if not narrow:
        return None
    said = ", ".join(f"{r.joint} {r.low:.3g} to {r.high:.3g} {r.unit}" for r in narrow)
    return (
        f"validity: the calibration holds for joint ranges {said} (the data's, under half of each "
        "joint's limits); measure poses across the limits to calibrate beyond them"
    )
