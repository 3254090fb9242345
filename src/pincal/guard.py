"""The guard: a calibration is exported only when its own validation says it beats the URDF.

On the fitted poses alone, :func:`judge` compares two models by linearised leave-one-pose-out
cross-validation (each pose's residuals predicted by the fit without it: ``e = (I - H)⁻¹ r`` on
that pose's rows, ``H`` the hat matrix of the fit with its pull toward the URDF; for distance
data, a pose's rows are those of every pair holding it):

- the fit (the chosen geometry, with its registration, tool, fixed points or effect);
- the nominal model: URDF geometry, only the registration, tool and fixed points fitted.

The fit is kept when it is *reliably* better: the mean over poses of (nominal's squared
validation error - the fit's) is above :data:`Z_MIN` standard errors. Otherwise the data cannot
support a calibration better than the nominal model, and :func:`pincal.calibrate` exports the
nominal geometry (with its fitted registration and tool: no worse than the URDF on these data),
and says so; ``force_fit=True`` (``--force-fit``) exports the fit anyway.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import OptimizeResult

from .crossval import held_out_rows
from .prior import PriorChoice, choose_weight, pulled
from .solver import Setup, solve

#: The fit is kept when its validation gain over the nominal model is this many standard errors.
Z_MIN = 2.0


@dataclass(frozen=True)
class Guard:
    """The guard's judgement of a fit against the nominal model, on the fitted poses.

    Attributes:
        fit_cv_rms_mm: the fit's leave-one-pose-out RMS over poses of the error norm [mm]
            (all the pose's residual rows: positions, weighted rotations, its pairs' distances).
        nominal_cv_rms_mm: the nominal model's (registration, tool, points fitted) [mm].
        z: mean gain in squared validation error over its standard error (large: reliable).
        kept_fit: the fit is exported (reliably better, or forced).
        forced: ``force_fit`` was asked for.
    """

    fit_cv_rms_mm: float
    nominal_cv_rms_mm: float
    z: float
    kept_fit: bool
    forced: bool = False

    @property
    def reliable(self) -> bool:
        """The fit's validation error is reliably below the nominal's."""
        return self.z > Z_MIN

    def text(self) -> str:
        """The verdict's line."""
        said = (
            f"validation (leave-one-pose-out) RMS {self.fit_cv_rms_mm:.3f} mm calibrated, "
            f"{self.nominal_cv_rms_mm:.3f} mm nominal (gain {self.z:.1f} standard errors)"
        )
        if self.reliable:
            return f"guard: the fit is reliably better than the nominal model: {said}"
        if self.forced:
            return (
                f"guard: the data do not support a calibration better than the nominal model ({said}); "
                "the fit is exported anyway (--force-fit)"
            )
        return (
            f"guard: the data do not support a calibration better than the nominal model ({said}): "
            "the nominal geometry is exported, with only the registration and tool fitted "
            "(--force-fit exports the fit)"
        )

    def to_dict(self) -> dict[str, Any]:
        """The report's ``guard`` object."""
        return {
            "fit_cv_rms_mm": self.fit_cv_rms_mm,
            "nominal_cv_rms_mm": self.nominal_cv_rms_mm,
            "z": self.z,
            "z_min": Z_MIN,
            "reliable": self.reliable,
            "exported": "fit" if self.kept_fit else "nominal",
            "forced": self.forced,
            "by": "linearised leave-one-pose-out cross-validation on the fitted poses",
        }


def loo_squared_errors(setup: Setup, theta: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Each pose's squared leave-one-pose-out validation error [m²] of the fit ``theta`` over
    the unknowns ``free``, with the pull of ``setup.prior_weight`` on the geometric ones."""
    problem = setup.problem
    jac = problem.jacobian(theta, free) * setup.scale[free]
    res = problem.residuals(theta)
    pen = pulled(setup, free).astype(float)
    gram = jac.T @ jac + setup.prior_weight**2 * np.diag(pen)
    spread = np.linalg.lstsq(gram, jac.T, rcond=None)[0].T  # J (JᵀJ + w²P)⁻¹, (rows, k)
    out = []
    for rows in held_out_rows(problem, None, 0):
        hat = jac[rows] @ spread[rows].T
        err = np.linalg.lstsq(np.eye(len(rows)) - hat, res[rows], rcond=None)[0]
        out.append(float(err @ err))
    return np.array(out)


def judge(
    setup: Setup, theta: np.ndarray, nominal: np.ndarray, free: np.ndarray, forced: bool = False
) -> Guard:
    """Compare the fit ``theta`` (unknowns ``free``) with the registration-only θ ``nominal``.

    Args:
        setup: the problem, with the pull's weight the fit used.
        theta: the fit.
        nominal: the nominal model with its registration, tool and points fitted.
        free: mask of the fitted unknowns.
        forced: export the fit whatever the verdict (``--force-fit``).
    """
    n_model = setup.problem.n_model
    registration = free & (np.arange(len(free)) >= n_model)
    fit = loo_squared_errors(setup, theta, free)
    base = loo_squared_errors(setup, nominal, registration) if registration.any() else _plain(setup, nominal)
    gain = base - fit
    stderr = float(np.std(gain, ddof=1) / np.sqrt(len(gain))) if len(gain) > 1 else 0.0
    z = float(np.mean(gain) / stderr) if stderr > 0 else (np.inf if np.mean(gain) > 0 else 0.0)
    reliable = z > Z_MIN
    return Guard(_rms_mm(fit), _rms_mm(base), z, reliable or forced, forced)


def _plain(setup: Setup, nominal: np.ndarray) -> np.ndarray:
    """Each pose's squared residual of the nominal model when nothing of it is fitted [m²]."""
    res = setup.problem.residuals(nominal)
    return np.array([float(res[rows] @ res[rows]) for rows in held_out_rows(setup.problem, None, 0)])


def _rms_mm(squared: np.ndarray) -> float:
    """RMS over poses of the validation error norm [mm], from the squared norms [m²]."""
    return float(np.sqrt(np.mean(squared))) * 1e3


@dataclass(frozen=True, eq=False)
class Protected:
    """A fit with its pull chosen and judged: what :func:`pincal.calibrate` exports.

    Attributes:
        setup: the problem carrying the chosen pull's weight.
        theta: the exported θ: the fit, or the nominal one when the guard refused the fit.
        result: the solver's result of the fit.
        prior: the pull's weight and how it was chosen.
        guard: the fit judged against the nominal model.
    """

    setup: Setup
    theta: np.ndarray
    result: OptimizeResult
    prior: PriorChoice
    guard: Guard


def protect(
    setup: Setup,
    nominal: np.ndarray,
    free: np.ndarray,
    prior: float | str = "auto",
    force_fit: bool = False,
    loss: str = "linear",
    f_scale: float = 1e-4,
) -> Protected:
    """Choose the pull toward the URDF (:func:`pincal.prior.choose_weight`), fit, and keep the
    fit only when it reliably beats the nominal model (:func:`judge`), or when ``force_fit``.

    Args:
        setup: the problem.
        nominal: the registration-only θ (the start).
        free: mask of the unknowns to fit.
        prior: ``auto`` or a weight [per natural unit].
        force_fit: export the fit whatever the guard says.
        loss, f_scale: the fit's loss and where it down-weights [m] (the weight is chosen with
            the plain least squares of the evidence's Gaussian model).
    """
    choice, chosen, theta, result = choose_weight(setup, nominal, free, prior, loss)
    if loss != "linear":
        theta, result = solve(chosen, nominal, free, loss, f_scale)
    verdict = judge(chosen, theta, nominal, free, force_fit)
    return Protected(chosen, theta if verdict.kept_fit else nominal, result, choice, verdict)
