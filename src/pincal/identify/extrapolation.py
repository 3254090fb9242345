"""Whether a fit the guard keeps is expected to beat the nominal model across the joint limits.

The guard (:mod:`pincal.identify.guard`) validates a fit on the poses it was fitted on: a fit on
poses that cover a small part of each joint's range can pass it and still predict the rest of
the workspace worse than the nominal model. :func:`check` estimates the fit's gain where the data
are not.

The yardstick is the posterior of *every* geometric correction (with the registration, tool and
the fit's effect), pulled toward the URDF with the weight of largest evidence
(:mod:`pincal.identify.prior`), linearised at the nominal model: the true rows at a configuration
``q`` (the tip position in the instrument's frame; for pose data the weighted rotation rows too)
are ``t(q) ~ N(m(q), V(q))``, ``m`` the posterior mean's prediction. With ``n(q)`` and ``f(q)``
the rows the nominal model and the fit predict (each with its own registration and tool), the
fit's gain in squared error, ``|t - n|² - |t - f|²``, has the posterior expectation
``|m - n|² - |m - f|²`` (``V`` cancels). The fit holds when the mean of it over configurations
drawn across the joint limits is above :data:`~pincal.identify.validity.Z_SPREAD` of its
posterior standard deviations (:func:`expected_gain`): where the data leave the posterior wide,
its mean is a poor yardstick too. Distance data have no instrument frame: their rows are the
distances between every two of the configurations, which no registration changes.

Distance data's posterior whitens the pairs (generalised least squares,
:func:`pincal.identify.uncertainty.whitened_pair_terms`): the N(N-1)/2 distances of N measured
points share the points' noise. Counted as independent rows, they made the posterior confident
and its mean follow the noise: with an exact URDF, each of the 7 fits of every parameter to the
pairs' noise that passed the guard in 400 sessions (13-24 % worse on new poses,
``benchmarks/guard_rates.py --measure distance --params all``) was expected to gain by 2.9 to 6.0
standard deviations; whitened, by -0.4 to 0.4. Its threshold is
:data:`~pincal.identify.validity.Z_SPREAD_PAIRS`.

Why not the fit's own covariance: ``|Δ̂|² - 2 tr(J Σ Jᵀ)`` (``Δ̂ = f - n``, ``Σ`` the fit's
posterior covariance) is unbiased only for parameters not chosen on the same data. After the
forward selection (``params="auto"``) the chosen corrections are those the noise made large, and
on the exported sessions with an exact URDF ``|Δ̂|²`` was 5 to 7 times ``tr(J Σ Jᵀ)`` across the
limits: that estimate kept all 6 of the fits that were 1.3 to 5.3 times worse than the nominal
model. The posterior of every correction knows nothing of the choice, and refused all 6.

Fixed-point data are not checked: their rows belong to the sockets the poses were measured in.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pincal.identify.chunked import normal_terms
from pincal.identify.measurements import Problem
from pincal.identify.prior import WEIGHTS, counted_rows, evidence_curve, pulled
from pincal.identify.solver import Setup
from pincal.identify.uncertainty import whitened_pair_terms
from pincal.identify.validity import Z_SPREAD, Z_SPREAD_PAIRS, Extrapolation

#: Configurations drawn across the joint limits: at least this many, and two per unknown.
SAMPLES = 60
#: Above this many fitted poses, the gain on them is the mean over a random subset of them.
OWN_POSES = 5_000
#: For distance data (rows for every two poses), at most this many of the fitted poses.
PAIRED_POSES = 200
#: The posterior's weights: the pull's grid (:data:`pincal.identify.prior.WEIGHTS`, up to 10)
#: and on, in the same steps, to 10⁴, where the posterior mean is the nominal model to a
#: thousandth. The data of an exact URDF often give the top of the pull's grid the largest
#: evidence: the best weight lies beyond it, and a posterior held at 10 still moves the model
#: toward a fit of the noise (on pairwise distances of 30 poses it passed fits up to 15 % worse
#: than the nominal model).
POSTERIOR_WEIGHTS = WEIGHTS + tuple(float(w) for w in WEIGHTS[-1] * np.geomspace(1.0, 1e3, 13)[1:])


def check(setup: Setup, theta: np.ndarray, nominal: np.ndarray, free: np.ndarray) -> Extrapolation | None:
    """The fit ``theta`` (unknowns ``free``) against the ``nominal`` model (its registration and
    tool fitted) across the joint limits and on the fitted poses; None for fixed-point data.

    Args:
        setup: the problem.
        theta: the fit.
        nominal: the nominal model with its registration and tool fitted.
        free: mask of the fitted unknowns.
    """
    problem = setup.problem
    robot, data = problem.model.robot, problem.data
    if problem.measurement.measure.fixed_points:
        return None
    every = free | (np.arange(problem.n_params) < problem.model.n_params)  # every correction, pulled
    post = Posterior.of(setup, nominal, every)
    n = max(SAMPLES, 2 * problem.n_params)
    rng = np.random.default_rng(0)
    q_whole = robot.random_configurations(n, rng)
    own_cap = PAIRED_POSES if problem.measurement.measure.by_pairs else OWN_POSES
    q_own = data.q if len(data) <= own_cap else data.q[rng.choice(len(data), own_cap, replace=False)]
    whole, spread = expected_gain(problem, theta, post, q_whole, spread=True)
    own, _ = expected_gain(problem, theta, post, q_own)
    z_min = Z_SPREAD_PAIRS if problem.measurement.measure.by_pairs else Z_SPREAD
    return Extrapolation(whole * 1e6, own * 1e6, n, post.weight, spread * 1e6, z_min)


@dataclass(frozen=True)
class Posterior:
    """The posterior of every correction with the pull of largest evidence (:mod:`pincal.identify.prior`),
    linearised at the nominal model.

    Attributes:
        nominal: θ of the nominal model (registration and tool fitted).
        mean: θ of the posterior mean (the Gauss-Newton step from ``nominal``).
        weight: the pull's weight [per natural unit].
        every: mask of the unknowns the posterior holds.
        covariance: their posterior covariance, in θ's units: ``σ² S (JᵀJ + w²P)⁻¹ S`` (``S`` the
            natural scales, ``σ²`` the residual's mean square at the mean).
    """

    nominal: np.ndarray
    mean: np.ndarray
    weight: float
    every: np.ndarray
    covariance: np.ndarray

    @classmethod
    def of(cls, setup: Setup, nominal: np.ndarray, every: np.ndarray) -> Posterior:
        """The posterior of the unknowns ``every`` of ``setup`` from ``nominal``."""
        terms = _terms(setup.problem, nominal, every)
        scores = evidence_curve(setup, nominal, every, POSTERIOR_WEIGHTS, terms)
        weight = POSTERIOR_WEIGHTS[int(np.argmax(scores))]
        unscaled, unscaled_grad, rr, n_rows = terms
        scale = setup.scale[every]
        gram, grad = unscaled * np.outer(scale, scale), unscaled_grad * scale
        pen = pulled(setup, every).astype(float)
        inverse = np.linalg.pinv(gram + weight**2 * np.diag(pen))
        step = -inverse @ grad
        mean = nominal.copy()
        mean[every] += step * scale
        held = weight**2 * float(step @ (pen * step))  # the pull's rows
        moved = rr + 2.0 * float(step @ grad) + float(step @ gram @ step) + held
        sigma2 = max(moved, 0.0) / max(n_rows - int(np.count_nonzero(every)), 1)
        return cls(nominal, mean, weight, every, sigma2 * inverse * np.outer(scale, scale))


def _terms(
    problem: Problem, nominal: np.ndarray, every: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float, int]:
    """The normal terms the posterior is made of: for distance data whitened (their pairs share
    the noise of their points: counted as independent rows, the posterior followed the noise and
    kept fits of pure noise 13-24 % worse than the nominal model across the limits); above
    :data:`~pincal.identify.uncertainty.WHITENED_POINTS` points, every row scaled by
    ``c = n_eff / n`` (:func:`pincal.identify.prior.counted_rows`: the effective-number
    approximation of whitening); else plain."""
    if not problem.measurement.measure.by_pairs:
        return normal_terms(problem, nominal, every)
    whitened = whitened_pair_terms(problem, nominal, every)
    if whitened is not None:
        return whitened
    gram, grad, rr, n_rows = normal_terms(problem, nominal, every)
    counted = counted_rows(problem, n_rows)
    c = counted / max(n_rows, 1)
    return c * gram, c * grad, c * rr, counted


def expected_gain(
    problem: Problem, fit: np.ndarray, post: Posterior, q: np.ndarray, spread: bool = False
) -> tuple[float, float]:
    """Mean over the configurations ``q`` (N, n) [rad or m] of the fit's gain over the nominal model
    in squared error of the measured rows, expected under the posterior: ``|m - n|² - |m - f|²``
    [m²], ``n``, ``f`` and ``m`` the rows (tip positions; with orientation data the weighted
    rotation rows too; for distance data the distances between every two of the configurations)
    that the nominal model, the fit and the posterior mean predict (see the module); a mean per
    configuration, for distance data per pair. With ``spread``, its posterior standard deviation
    [m²] (else 0).

    The mean gain is linear in the true rows ``t``: ``2 Σ (f - n)·t / N`` plus what does not
    depend on ``t``; with ``t = m + J δ``, ``δ`` the posterior's spread of the unknowns, its
    variance is ``4 gᵀ Σ g / N²`` with ``g = Jᵀ (f - n)`` summed over the rows.
    """
    sampled = problem.measuring(post.mean, q)
    off_nominal, off_fit = sampled.residuals(post.nominal), sampled.residuals(fit)  # n - m, f - m
    count = len(sampled.pairs) if problem.measurement.measure.by_pairs else len(q)
    gain = float((off_nominal @ off_nominal - off_fit @ off_fit) / count)
    if not spread:
        return gain, 0.0
    along = sampled.jacobian(post.mean, post.every).T @ (off_fit - off_nominal)
    return gain, float(2.0 * np.sqrt(max(along @ post.covariance @ along, 0.0)) / count)
