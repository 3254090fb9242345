"""The guard: a calibration is exported only when its own validation says it beats the URDF.

On the fitted poses alone, :func:`judge` compares two models by linearised leave-one-pose-out
cross-validation (each pose's residuals predicted by the fit without it: ``e = (I - H)⁻¹ r`` on
that pose's rows, ``H`` the hat matrix of the fit with its pull toward the URDF; for distance
data, a pose's rows are those of every pair holding it):

- the fit (the chosen geometry, with its registration, tool, fixed points or effect);
- the nominal model: URDF geometry, only the registration, tool and fixed points fitted.

The fit is kept when it is *reliably* better: the mean over poses of the log ratio of the
nominal's squared validation error to the fit's is above :data:`Z_MIN` standard errors
(:func:`pincal.identify.guard_null.log_gains` says why a ratio). Otherwise the data cannot
support a calibration better than the nominal model, and :func:`pincal.calibrate` exports the
nominal geometry (with its fitted registration and tool: no worse than the URDF on these data),
and says so; ``force_fit=True`` (``--force-fit``) exports the fit anyway.

A fit that passes is then checked across the joint limits (:mod:`pincal.identify.extrapolation`):
unless it is expected to beat the nominal model outside the poses it was fitted on (by
:data:`~pincal.identify.validity.Z_SPREAD` standard deviations of that expectation, for distance
data :data:`~pincal.identify.validity.Z_SPREAD_PAIRS`), the nominal geometry is exported in the
same way (unless ``force_fit``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from pincal.data.dataset import Dataset
from pincal.identify import chunked
from pincal.identify.calibration import Calibration
from pincal.identify.extrapolation import check
from pincal.identify.folds import held_out_rows, held_out_squares
from pincal.identify.guard_null import (
    GIVEN_DRAWS,
    NULL_DRAWS,
    NULL_MAX_POSES,
    log_gains,
    null_threshold,
    z_of,
)
from pincal.identify.identifiability import Identifiability
from pincal.identify.lm import OptimizeResult
from pincal.identify.measurements import Problem
from pincal.identify.prior import choose_weight, pulled
from pincal.identify.records import Guard, PriorChoice
from pincal.identify.solver import Setup, assess, solve
from pincal.identify.uncertainty import RowSums, row_sums
from pincal.identify.validity import joint_ranges

#: The fit is kept when its validation gain over the nominal model (the mean log ratio of squared
#: errors, :func:`~pincal.identify.guard_null.log_gains`) is this many standard errors.
Z_MIN = 2.0


def loo_squared_errors(setup: Setup, theta: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Each pose's squared leave-one-pose-out validation error [m²] of the fit ``theta`` over
    the unknowns ``free``, with the pull of ``setup.prior_weight`` on the geometric ones."""
    problem = setup.problem
    jac = problem.jacobian(theta, free) * setup.scale[free]
    res = problem.residuals(theta)
    pen = pulled(setup, free).astype(float)
    gram = jac.T @ jac + setup.prior_weight**2 * np.diag(pen)
    spread = np.linalg.lstsq(gram, jac.T, rcond=None)[0].T  # J (JᵀJ + w²P)⁻¹, (rows, k)
    return held_out_squares(jac, spread, res, held_out_rows(problem, None, 0))


def judge(
    setup: Setup,
    theta: np.ndarray,
    nominal: np.ndarray,
    free: np.ndarray,
    forced: bool = False,
    selected: bool = False,
) -> Guard:
    """Compare the fit ``theta`` (unknowns ``free``) with the registration-only θ ``nominal``.

    Args:
        setup: the problem, with the pull's weight the fit used.
        theta: the fit.
        nominal: the nominal model with its registration, tool and points fitted.
        free: mask of the fitted unknowns.
        forced: export the fit whatever the verdict (``--force-fit``).
        selected: the parameters were chosen by forward selection on these poses: the threshold
            is the null of selection + guard (:func:`threshold`).
    """
    z_min, how = threshold(setup, nominal, selected, free)
    setup = judged_on(setup)
    n_model = setup.problem.n_model
    registration = free & (np.arange(len(free)) >= n_model)
    fit = loo_squared_errors(setup, theta, free)
    base = loo_squared_errors(setup, nominal, registration) if registration.any() else _plain(setup, nominal)
    z = z_of(log_gains(base, fit))  # 0 when the gains do not spread: nothing but the registration moved
    reliable = z > z_min
    return Guard(_rms_mm(fit), _rms_mm(base), z, z_min, reliable or forced, forced, how)


def threshold(setup: Setup, nominal: np.ndarray, selected: bool, free: np.ndarray) -> tuple[float, str]:
    """The guard's threshold [standard errors] and how it was set: :data:`Z_MIN`, or when higher
    the null quantile of the guard's ``z`` on pure noise
    (:func:`pincal.identify.guard_null.null_threshold`): after a forward selection, of selection
    + guard; for distance data with given parameters (``free``, a mask), of the guard alone, as
    pairs that share their poses' noise spread ``z`` wider than a normal statistic."""
    given = free if setup.problem.measurement.measure.by_pairs and not selected else None
    if not selected and given is None:
        return Z_MIN, Guard.threshold_from
    draws = NULL_DRAWS if given is None else GIVEN_DRAWS
    null = null_threshold(setup, nominal, draws, given=given)
    what = "the same forward selection" if given is None else "the fit of the given parameters"
    if null is None:
        return Z_MIN, f"fixed: above {NULL_MAX_POSES} poses no null of {what} is drawn"
    said = (
        f"the {null.rank}. largest ({null.z:.2f}) of the guard's z after {what} on "
        f"{null.draws} draws of pure noise ({null.noise_mm:.3f} mm per row), at least {Z_MIN:g}: "
        f"false export on pure noise {null.alpha:.1%}"
    )
    return max(Z_MIN, null.z), said


#: Above this many poses (position or pose data), the guard judges a random subset of them
#: (seed 0): its leave-one-pose-out loop would take minutes on 10⁶ poses for a verdict that many
#: poses settle long before.
JUDGED_POSES = 5_000


def judged_on(setup: Setup) -> Setup:
    """``setup``, or the same on :data:`JUDGED_POSES` random poses of a large position or pose set."""
    problem = setup.problem
    if len(problem.data) <= JUDGED_POSES or not problem.measurement.measure.registered:
        return setup
    keep = np.sort(np.random.default_rng(0).choice(len(problem.data), JUDGED_POSES, replace=False))
    sub = Problem(problem.model, problem.measurement, problem.data.subset(keep), problem.extension)
    return replace(setup, problem=sub)


def _plain(setup: Setup, nominal: np.ndarray) -> np.ndarray:
    """Each pose's squared residual of the nominal model when nothing of it is fitted [m²]."""
    res = setup.problem.residuals(nominal)
    return np.array([float(res[rows] @ res[rows]) for rows in held_out_rows(setup.problem, None, 0)])


def _rms_mm(squared: np.ndarray) -> float:
    """RMS over poses of the validation error norm [mm], from the squared norms [m²]."""
    return float(np.sqrt(np.mean(squared))) * 1e3


@dataclass(frozen=True)
class Pull:
    """How :func:`pincal.calibrate` holds the geometric corrections near the URDF, and when it
    exports the fit.

    Attributes:
        weight: ``"auto"`` (chosen by maximum evidence on the fitted poses, :mod:`pincal.identify.prior`)
            or a weight [per natural unit: 0.1 m of correction weighs as a residual of 0.1 m x
            weight].
        force_fit: export the fit even when the guard finds it not reliably better than the
            nominal model on its own validation (:func:`judge`).
        selected: the parameters were chosen by forward selection on the fitted poses (set by
            :func:`pincal.calibrate` for ``params="auto"``): the guard's threshold is then the null
            of selection + guard (:mod:`pincal.identify.guard_null`).
    """

    weight: float | str = "auto"
    force_fit: bool = False
    selected: bool = False


#: ``pincal calibrate``'s default: the weight chosen from the data, the guard on.
DEFAULT_PULL = Pull()


@dataclass(frozen=True, eq=False)
class Protected:
    """A fit with its pull chosen and judged: what :func:`pincal.calibrate` exports.

    Attributes:
        setup: the problem carrying the chosen pull's weight.
        theta: the exported θ: the fit, or ``nominal`` when the guard refused the fit.
        nominal: the registration-only θ (nominal geometry; registration, tool, points fitted).
        identifiability: the identifiable set the fit used.
        result: the solver's result of the fit.
        prior: the pull's weight and how it was chosen.
        guard: the fit judged against the nominal model.
        screening: the problem and fit the outliers are screened on: the default pull's fit
            (:data:`pincal.identify.solver.PRIOR_WEIGHT`) when the weight is chosen, as its choice is made
            for Gaussian residuals and gross outliers would inflate it; else the fit.
        base: the fit at the default pull, from which the fit at the chosen weight was solved.
        sums: on a large problem (:func:`pincal.identify.chunked.is_large`) with the plain least
            squares, the rows' sums at ``base`` (one pass over a million poses): the pull's
            evidence and, when the fit is kept, its standard deviations read them.
    """

    setup: Setup
    theta: np.ndarray
    nominal: np.ndarray
    identifiability: Identifiability
    result: OptimizeResult
    prior: PriorChoice
    guard: Guard
    screening: tuple[Setup, np.ndarray]
    base: np.ndarray
    sums: RowSums | None = None

    @property
    def free(self) -> np.ndarray:
        """Mask of the fitted unknowns."""
        return self.identifiability.identifiable

    def assessed(self, test: Dataset | None = None) -> Calibration:
        """The calibration record (:func:`pincal.identify.solver.assess`) with the pull and the guard."""
        sums = self.sums if self.guard.kept_fit else None  # at the fit, not at the nominal model
        cal = assess(self.setup, self.theta, self.nominal, self.identifiability, self.result, test, sums)
        return replace(cal, prior=self.prior, guard=self.guard, default_pull_theta=self.base)


def protect(
    setup: Setup,
    nominal: np.ndarray,
    ident: Identifiability,
    base: np.ndarray,
    pull: Pull = DEFAULT_PULL,
    loss: str = "linear",
    f_scale: float = 1e-4,
) -> Protected:
    """Choose the pull toward the URDF (:func:`pincal.identify.prior.choose_weight`), fit, and keep the
    fit only when it reliably beats the nominal model (:func:`judge`), or when ``force_fit``.

    Args:
        setup: the problem.
        nominal: the registration-only θ.
        ident: the identifiable set: the unknowns to fit.
        base: the fit at the default pull (:data:`pincal.identify.solver.PRIOR_WEIGHT`) with ``loss``.
        pull: the weight (``auto`` or given) and ``force_fit``.
        loss, f_scale: the fit's loss and where it down-weights [m] (the weight is chosen with
            the plain least squares of the evidence's Gaussian model).
    """
    free = ident.identifiable
    sums = (
        row_sums(setup.problem, base, free) if chunked.is_large(setup.problem) and loss == "linear" else None
    )
    terms = None if sums is None else sums.normal_terms()
    choice, chosen, theta, result = choose_weight(setup, base, free, pull.weight, loss, terms)
    if loss != "linear":
        theta, result = solve(chosen, base, free, loss, f_scale)
    region = joint_ranges(setup.model.robot, setup.data.q)
    verdict = replace(judge(chosen, theta, nominal, free, pull.force_fit, pull.selected), region=region)
    if verdict.reliable:  # validated on its poses: is it expected to hold beyond them?
        verdict = replace(verdict, extrapolation=check(chosen, theta, nominal, free))
        verdict = replace(verdict, kept_fit=verdict.holds or pull.force_fit)
    kept = theta if verdict.kept_fit else nominal
    screening = (setup, base) if choice.chosen_by == "evidence" else (chosen, theta)
    return Protected(chosen, kept, nominal, ident, result, choice, verdict, screening, base, sums)
