"""Whether an identified effect can be what it is named: a compliance read as a stiffness.

A compliance as a stiffness (:func:`compliance_stiffness`). ``τ`` is the torque the motor holds
against gravity; an elastic joint's link lags its motor by ``τ / K`` (link angle = motor angle
- ``τ / K``, stiffness ``K > 0``), so a joint that sags under its load has ``c = -1/K < 0``. A
coefficient is *plausible* as a stiffness when (1) the joint sags (``K > 0``; ``c > 0`` would
make it rise against its load) and (2) its deflection at the largest gravity torque it carries
over the data, ``|c| · max |τ_j|``, lies within :data:`PLAUSIBLE_DEFLECTION` (0.01 to 20 mrad).
Why: harmonic-drive and cycloidal gearboxes of any size deflect about 1-2 mrad at their rated
torque (catalogue torsional stiffness ÷ rated torque), cobot joints with torque sensors up to a
few mrad; gravity loads a joint at most to about its rated torque. Relating ``K`` to the load the
joint actually carries makes the range independent of the joint's size, where a range of ``K``
itself would not be (a wrist's 500 N·m/rad and a shoulder's 50 000 N·m/rad are both real).
Below 0.01 mrad the effect is far below what position data can identify; above 20 mrad (over
1°) no working arm sags. An implausible coefficient still locates an error that follows the
load (wrong URDF inertias, a payload left out, a bent link...), but not an elasticity. For a
prismatic joint the same rule holds in metres: :data:`PLAUSIBLE_DEFLECTION_PRISMATIC`, 1 µm to
1 mm (linear axes on ball screws or belts).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from pincal.kinematics.effects import Extension

#: Deflection of a revolute joint at its largest gravity torque that a real joint shows [rad].
PLAUSIBLE_DEFLECTION = (1e-5, 2e-2)
#: The same for a prismatic joint [m].
PLAUSIBLE_DEFLECTION_PRISMATIC = (1e-6, 1e-3)
#: The least stiffness a real joint has [N·m/rad; N/m for a prismatic joint]: the smallest
#: harmonic drives are stiffer than 100 N·m/rad, hobby servos about 20; below it, an error that
#: follows the load is something else (a bent tool on an unloaded wrist, wrong inertias).
LEAST_STIFFNESS = (20.0, 2e4)
#: The largest joint error an effect other than compliance plausibly makes over the data [rad;
#: m for a prismatic joint]: gear transmission errors, backlash and encoder scale errors of
#: working arms stay below about 1 degree (harmonic drives: arc-minutes).
PLAUSIBLE_JOINT_ERROR = (2e-2, 2e-3)


@dataclass(frozen=True)
class Stiffness:
    """A ``joint_compliance`` coefficient read as a joint stiffness (see the module docstring).

    Attributes:
        coefficient: ``c`` [rad/(N·m), or m/N for a prismatic joint].
        stiffness: ``K = -1/c`` [N·m/rad or N/m]; inf when ``c == 0``.
        max_torque: largest ``|τ_j|`` over the data [N·m or N].
        deflection: ``|c| · max_torque``, how far the joint deflects at its largest load [rad or m].
        sags: the joint yields to its load, ``0 < K < inf`` (``c < 0``).
        plausible: it sags and its deflection is within :data:`PLAUSIBLE_DEFLECTION` (or
            :data:`PLAUSIBLE_DEFLECTION_PRISMATIC`).
        verdict: one short sentence.
        prismatic: the joint is prismatic (units N/m, m and N).
    """

    coefficient: float
    stiffness: float
    max_torque: float
    deflection: float
    sags: bool
    plausible: bool
    verdict: str
    prismatic: bool = False

    @property
    def unit(self) -> str:
        """Unit of :attr:`stiffness`."""
        return "N/m" if self.prismatic else "N·m/rad"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (no inf or NaN: an infinite ``K`` is None)."""
        k = self.stiffness
        return {
            "coefficient": self.coefficient,
            "K": k if np.isfinite(k) else None,
            "unit_K": self.unit,
            "max_torque": self.max_torque,
            "deflection": self.deflection,
            "sags": self.sags,
            "plausible": self.plausible,
            "verdict": self.verdict,
        }


def compliance_stiffness(extension: Extension, coefficient: float, q: np.ndarray) -> Stiffness:
    """Read a ``joint_compliance`` coefficient as a stiffness, over the commanded configurations
    ``q`` (N, n) of the data (for the largest gravity torque the joint carries)."""
    if extension.effect != "joint_compliance":
        raise ValueError(f"{extension.label} is no joint_compliance")
    c = float(coefficient)
    prismatic = bool(extension.robot.prismatic[extension.index])
    torque = float(np.abs(extension.regressors(q)).max()) if len(np.atleast_2d(q)) else 0.0
    k = -1.0 / c if c != 0 else np.inf
    deflection = abs(c) * torque
    lo, hi = PLAUSIBLE_DEFLECTION_PRISMATIC if prismatic else PLAUSIBLE_DEFLECTION
    sags = c < 0
    stiff = k >= LEAST_STIFFNESS[1 if prismatic else 0]
    plausible = sags and stiff and lo <= deflection <= hi
    # Deflections in mrad (or mm), torques in N·m (or N).
    unit_k, unit_d, unit_t = ("N/m", "mm", "N") if prismatic else ("N·m/rad", "mrad", "N·m")
    shown = f"{_short(deflection * 1e3)} {unit_d}"
    if torque == 0:
        verdict = "no stiffness: the joint carries no gravity torque over the data"
    elif c == 0:
        verdict = "no deflection under gravity (c = 0): infinitely stiff"
    elif not sags:
        verdict = (
            f"implausible as a stiffness: the joint would rise against its load (K = {k:.3g} {unit_k}"
            " < 0); an error that follows the load, not an elasticity"
        )
    elif not stiff and deflection <= hi:
        verdict = (
            f"implausible as a stiffness: K = {k:.3g} {unit_k} is below any real joint's "
            f"({LEAST_STIFFNESS[1 if prismatic else 0]:g} {unit_k}); an error that follows the load "
            "(a bent tool, wrong inertias), not an elasticity"
        )
    elif plausible:
        verdict = (
            f"sags under gravity: K = {k:.3g} {unit_k} "
            f"(deflects {shown} at its largest load, {_short(torque)} {unit_t})"
        )
    else:
        why = "another error follows the load" if deflection > hi else "the effect is too small to identify"
        verdict = (
            f"implausible as a stiffness: K = {k:.3g} {unit_k} deflects {shown} at its largest load "
            f"(plausible: {lo * 1e3:g}–{hi * 1e3:g} {unit_d}); the URDF's inertias may be wrong, or {why}"
        )
    return Stiffness(c, k, torque, deflection, sags, plausible, verdict, prismatic)


def _short(x: float) -> str:
    """Two significant digits, without an exponent up to 10⁵."""
    return f"{x:.2g}" if x < 100 or x >= 1e5 else f"{x:.0f}"


def implausible(extension: Extension, params: np.ndarray, q: np.ndarray) -> str | None:
    """Why an identified effect cannot be what it is named (None: plausible) over the commanded
    configurations ``q`` (N, n): a compliance must read as a stiffness (:func:`compliance_stiffness`),
    any other effect must move its joint by less than :data:`PLAUSIBLE_JOINT_ERROR`."""
    if extension.effect == "joint_compliance":
        stiffness = compliance_stiffness(extension, float(params[0]), q)
        return None if stiffness.plausible else stiffness.verdict
    prismatic = bool(extension.robot.prismatic[extension.index])
    largest = float(np.abs(extension.regressors(q) @ np.asarray(params, float)).max()) if len(q) else 0.0
    bound, unit = PLAUSIBLE_JOINT_ERROR[1 if prismatic else 0], "mm" if prismatic else "mrad"
    if largest <= bound:
        return None
    return (
        f"implausible as {extension.effect.replace('_', ' ')}: it moves {extension.joint} by up to "
        f"{largest * 1e3:.3g} {unit} (a working arm's: below {bound * 1e3:g} {unit}); "
        "an error of another kind follows this variable"
    )
