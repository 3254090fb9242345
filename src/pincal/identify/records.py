"""How a calibration was reached: the records a :class:`~pincal.identify.calibration.Calibration` keeps.

The pull toward the URDF (:mod:`pincal.identify.prior`), the guard's judgement
(:mod:`pincal.identify.guard`), the plausibility verdict (:mod:`pincal.plausibility.judge`), the
weights of the delivered fit (:mod:`pincal.auto.balance`) and the choice of parameters and cause
(:mod:`pincal.auto.choice`) are decided above the calibration in the layers; their records are
declared here, below it, so that the calibration that keeps them imports nothing above it. The
choice's record is a protocol: :class:`~pincal.auto.choice.ModelChoice` holds diagnoses and
cross-validations that hold calibrations in turn (:func:`pincal.auto.choice.choice_of` gives it back
with its type).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from pincal.identify.validity import Extrapolation, JointRange


class Choice(Protocol):
    """What :func:`pincal.auto.choice.choose` decided (a :class:`~pincal.auto.choice.ModelChoice`)."""

    @property
    def params(self) -> tuple[str, ...] | None:
        """The chosen model parameters (None: every identifiable one)."""

    def to_dict(self) -> dict[str, Any]:
        """The report's ``choice`` object."""


class Judgement(Protocol):
    """Whether a calibration can describe a real arm (a :class:`~pincal.plausibility.verdict.Verdict`,
    judged by :func:`pincal.plausibility.judge.judge_calibration`)."""

    @property
    def plausible(self) -> bool:
        """Whether every check passed."""

    @property
    def hint(self) -> str | None:
        """The likely cause, its fix and the evidence; None when plausible."""

    def message(self) -> str:
        """The one-line refusal."""

    def to_dict(self) -> dict[str, Any]:
        """The report's ``plausibility`` object."""


@dataclass(frozen=True)
class Balance:
    """The weight chosen and what each weight's cross-validation gave.

    Attributes:
        weight: λ (``inf``: geometry first).
        weights: the λ tried (:data:`pincal.auto.balance.WEIGHTS`).
        alone_cv_rms_mm: per λ, the URDF alone's linearised cross-validated RMS [mm].
        full_cv_rms_mm: per λ, the model with its sidecar's [mm].
    """

    weight: float
    weights: tuple[float, ...]
    alone_cv_rms_mm: tuple[float, ...]
    full_cv_rms_mm: tuple[float, ...]

    def to_dict(self) -> dict[str, object]:
        """JSON-ready (``inf`` written as None)."""
        return {
            "weight": None if np.isinf(self.weight) else self.weight,
            "weights": [None if np.isinf(w) else w for w in self.weights],
            "alone_cv_rms_mm": list(self.alone_cv_rms_mm),
            "full_cv_rms_mm": list(self.full_cv_rms_mm),
            "by": "K-fold cross-validation, linearised at the joint fit: of the weights whose URDF alone is "
            "no worse than the geometry alone, the one whose URDF with its sidecar is best",
        }


@dataclass(frozen=True)
class PriorChoice:
    """The strength of the pull toward the URDF and how it was chosen.

    Attributes:
        weight: the weight of the rows ``w · δ`` [per natural unit: 1/m of correction, or per
            rotation moving the workspace by 1 m].
        chosen_by: ``evidence`` (type-II maximum likelihood over :data:`WEIGHTS`), ``given``,
            or why the default was kept (nothing geometric fitted, a robust loss).
        log_evidence: (weight, log evidence) of each weight tried (empty when given).
    """

    weight: float
    chosen_by: str
    log_evidence: tuple[tuple[float, float], ...] = ()

    @property
    def at_edge(self) -> bool:
        """The evidence's optimum is the smallest or largest weight tried: the best weight may lie
        beyond the grid (and the data hardly tell what the corrections are: under the null,
        distance data pick the top)."""
        tried = [w for w, _ in self.log_evidence]
        return self.chosen_by == "evidence" and bool(tried) and self.weight in (min(tried), max(tried))

    def to_dict(self) -> dict[str, Any]:
        """The report's ``prior`` object."""
        return {
            "weight": self.weight,
            "chosen_by": self.chosen_by,
            "at_grid_edge": self.at_edge,
            "means": "weight of the rows holding each geometric correction near the URDF, per "
            "natural unit (0.1 m of correction weighs as a residual of 0.1 m x weight)",
            "log_evidence": [{"weight": w, "log_evidence": e} for w, e in self.log_evidence],
        }

    def text(self) -> str:
        """One line for the summary."""
        how = self.chosen_by
        if how == "evidence":
            how = "chosen by maximum evidence over the fitted poses"
        edge = "; at the edge of the weights tried: the optimum may lie beyond them" if self.at_edge else ""
        return (
            "pull toward the URDF (what the data hardly see stays near it): a correction of 1 mm "
            f"(a rotation: 1 mm across the workspace) weighs as a residual of {self.weight:.3g} mm "
            f"(weight {self.weight:.3g}, {how}{edge})"
        )


@dataclass(frozen=True)
class Guard:
    """The guard's judgement of a fit against the nominal model, on the fitted poses.

    Attributes:
        fit_cv_rms_mm: the fit's leave-one-pose-out RMS over poses of the error norm [mm]
            (all the pose's residual rows: positions, weighted rotations, its pairs' distances).
        nominal_cv_rms_mm: the nominal model's (registration, tool, points fitted) [mm].
        z: the mean over poses of the log ratio of the nominal's squared validation error to the
            fit's, over its standard error (large: reliable).
        z_min: the gain above which it is reliable: :data:`pincal.identify.guard.Z_MIN`, or
            after a forward selection the quantile of the null of selection + guard when higher
            (:mod:`pincal.identify.guard_null`).
        kept_fit: the fit is exported (reliably better, or forced).
        forced: ``force_fit`` was asked for.
        threshold_from: how ``z_min`` was set, in words.
        extrapolation: the fit's expected gain across the joint limits, checked when the fit is
            reliable (:mod:`pincal.identify.extrapolation`); None when not checked. A reliable fit
            that does not hold there is not exported unless forced.
        region: each joint's range among the fitted poses.
    """

    fit_cv_rms_mm: float
    nominal_cv_rms_mm: float
    z: float
    z_min: float
    kept_fit: bool
    forced: bool = False
    threshold_from: str = "fixed (no choice was made on these poses before the guard)"
    extrapolation: Extrapolation | None = None
    region: tuple[JointRange, ...] = ()

    @property
    def reliable(self) -> bool:
        """The fit's validation error is reliably below the nominal's."""
        return self.z > self.z_min

    @property
    def holds(self) -> bool:
        """The fit is expected to beat the nominal model across the joint limits (or was not checked)."""
        return self.extrapolation is None or self.extrapolation.holds

    def text(self) -> str:
        """The verdict's line."""
        said = (
            f"validation (leave-one-pose-out) RMS {self.fit_cv_rms_mm:.3f} mm calibrated, "
            f"{self.nominal_cv_rms_mm:.3f} mm nominal; per pose, the log ratio of the nominal's squared "
            f"error to the fit's is {self.z:.1f} times its standard error above zero "
            f"(reliable above {self.z_min:g})"
        )
        if self.reliable and self.holds:
            beyond = "" if self.extrapolation is None else f"; {self.extrapolation.text()}"
            return f"guard: the fit is reliably better than the nominal model: {said}{beyond}"
        if self.reliable and self.extrapolation is not None:
            what = (
                "the fit is exported anyway (force_fit=True)"
                if self.forced
                else "the nominal geometry is exported, with only the registration and tool fitted "
                "(force_fit=True exports the fit)"
            )
            return (
                f"guard: the fit is reliably better than the nominal model on the fitted poses ({said}), "
                f"but not across the joint limits ({self.extrapolation.text()}): {what}"
            )
        if self.forced:
            return (
                f"guard: the data do not support a calibration better than the nominal model ({said}); "
                "the fit is exported anyway (force_fit=True)"
            )
        return (
            f"guard: the data do not support a calibration better than the nominal model ({said}): "
            "the nominal geometry is exported, with only the registration and tool fitted "
            "(force_fit=True exports the fit)"
        )

    def to_dict(self) -> dict[str, Any]:
        """The report's ``guard`` object."""
        return {
            "fit_cv_rms_mm": self.fit_cv_rms_mm,
            "nominal_cv_rms_mm": self.nominal_cv_rms_mm,
            "z": self.z,
            "z_min": self.z_min,
            "reliable": self.reliable,
            "exported": "fit" if self.kept_fit else "nominal",
            "forced": self.forced,
            "z_min_from": self.threshold_from,
            "by": "linearised leave-one-pose-out cross-validation on the fitted poses",
            "extrapolation": None if self.extrapolation is None else self.extrapolation.to_dict(),
        }
