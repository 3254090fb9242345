"""The outcome a user acts on: what the exported files give, what remains, in one verdict line."""

from __future__ import annotations

from dataclasses import dataclass

from pincal.auto.choice import choice_of
from pincal.auto.delivery import Exported, exported_errors
from pincal.auto.residual import ResidualVerdict, residual_verdict
from pincal.data.dataset import Dataset
from pincal.identify.calibration import Calibration
from pincal.identify.evaluation import ErrorStats


@dataclass(frozen=True)
class Outcome:
    """What the exported files give and what the final model leaves.

    Attributes:
        exported: the written URDF (alone, and with its sidecar), scored as loaded back.
        residual: the residual verdict on the fitted poses.
        cause: the cause kept in the sidecar (``EFFECT:JOINT``), or None.
    """

    exported: Exported
    residual: ResidualVerdict
    cause: str | None
    joint_cv_rms_mm: float | None = None

    def caveat(self) -> str | None:
        """When a named cause explains only part of the structure: why, and what else to try."""
        if self.cause is None or self.residual.verdict != "unexplained":
            return None
        head = f"{self.cause} explains part of the structure; {self.residual.unexplained_mm:.3g} mm remains"
        joint = self.joint_cv_rms_mm
        outside = (
            "an effect outside pincal's list (link bending, drift over time, another period, a nonlinear "
            "stiffness) or a second cause"
        )
        if joint is not None and joint < 0.8 * self.residual.cv_rms_mm:
            said = (
                f"{head}: part of it is what the URDF alone cannot share with the sidecar: fitted together "
                f"with the geometry (deliver=joint) the cause leaves {joint:.3g} mm (cross-validated), "
                "but that URDF is worse alone"
            )
            floor = self.residual.floor_mm
            if joint < 1.5 * floor:
                return said
            return f"{said}; above the noise floor ({floor:.3g} mm), {outside}"
        return (
            f"{head} unexplained: the named cause may stand in for an effect outside pincal's list (link "
            "bending, drift over time, another period, a nonlinear stiffness), or a second cause remains"
        )

    def verdict_line(self, output: str | None = None, warnings: tuple[str, ...] = ()) -> str:
        """One line: what to load and what it gives, what remains, what to act on."""
        held = self.exported.test is not None
        alone = self.exported.test if held else self.exported.train
        full = self.exported.full_test if held else self.exported.full_train
        where = "held out" if held else "on the fitted poses"
        if output:
            load = f"{output} alone gives {_rms(alone)} mm RMS {where}"
        else:  # nothing written: say what would be, and how to write it
            load = (
                "the corrected URDF (not written; pincal calibrate -o FILE.urdf writes it) alone would "
                f"give {_rms(alone)} mm RMS {where}"
            )
        if self.cause is not None:
            load += f", with its sidecar ({self.cause}) {_rms(full)} mm"
        parts = [load, f"what remains: {self.residual.sentence()}", *warnings]
        return "verdict: " + "; ".join(parts)


def _rms(stats: ErrorStats | None) -> str:
    return "n/a" if stats is None else f"{stats.rms_mm:.3g}"


def outcome(
    cal: Calibration,
    data: Dataset,
    test: Dataset | None = None,
    noise_mm: float | None = None,
    folds: int = 5,
    seed: int = 0,
) -> Outcome:
    """Score the files ``cal`` exports and judge its residual (see :mod:`pincal.auto.residual`).

    Args:
        cal: the calibration.
        data, test: its fitted and held-out poses.
        noise_mm: the instrument's noise, RMS per axis [mm], if known.
        folds, seed: the residual verdict's cross-validation.
    """
    exported = exported_errors(cal, data, test)
    verdict = residual_verdict(cal, data, noise_mm, folds, seed)
    cause = cal.extension.label if cal.extension is not None else None
    choice = choice_of(cal)
    diagnosis = choice.diagnosis if choice is not None else None
    joint = diagnosis.extended_cv_rms_mm if diagnosis is not None and diagnosis.cause is not None else None
    return Outcome(exported, verdict, cause, joint if cal.balance is not None else None)
