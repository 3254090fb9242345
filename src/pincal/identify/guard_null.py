"""The guard's threshold after a forward selection: the null of the whole procedure.

Forward selection (:mod:`pincal.identify.forward_selection`) picks the parameters whose linearised
leave-one-pose-out error is lowest; the guard (:func:`pincal.identify.guard.judge`) then asks
whether that same statistic, on the same poses, beats the nominal model by :data:`Z_MIN
<pincal.identify.guard.Z_MIN>` standard errors. On pure noise the choice already made the gain
look good: with an exact URDF, 15 poses and a fixed threshold of 2, the guard exported the fit in
about one session in five.

:func:`null_threshold` repeats the whole procedure on pure noise through the same closed-form
machinery: the problem linearised at the registration-only fit, noise of the size the nominal
model's residual gives (so under the null hypothesis it *is* the noise), the selection's walk and
stopping rule over the same candidates, then the guard's statistic of the chosen set (its
leave-one-pose-out errors with the fit's pull, against the registration's alone). The guard's
threshold is the ``k``-th largest of those ``D`` values of ``z``, never below the fixed one, with
``k = max(1, ⌊ALPHA (D + 1)⌋)``: a Monte Carlo test. Under the null the data's ``z`` and the
draws' are exchangeable, so the data's ``z`` exceeds that threshold with probability at most
``k / (D + 1)`` (4.8 % with 20 draws, the largest the threshold), whatever the number of draws.

Distance data with given parameters get the same test without the selection (the fit's columns
are the given ones in every draw): their pairs share their poses' noise, so the guard's ``z``
spreads wider than a normal statistic: with every parameter given, 15 or 30 poses and an exact
URDF, the fixed threshold of 2 exported 11-28 % of the fits instead of 2.3 %
(``benchmarks/guard_rates.py --measure distance --params all``).

The statistic ``z`` (the mean over poses of the log ratio of the nominal model's squared
held-out error to the fit's, over its standard error: :func:`log_gains`) and the selection's
relative rules do not depend on the noise's size; only the pull's weight, relative to the noise, does.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from pincal.identify.folds import held_out_squares
from pincal.identify.forward_selection import KEEP_ALL, MIN_GAIN, choose_step
from pincal.identify.selection_walk import Design, design, draw_batches, walks
from pincal.identify.solver import Setup
from pincal.workers import parallel_map

#: Draws of pure noise through the selection and the guard: with the largest as the threshold,
#: false exports on pure noise at most 1/21 = 4.8 % (each draw costs a selection's walk).
NULL_DRAWS = 20
#: Draws for given parameters (no selection's walk: each draw is cheap): the largest of 43 as the
#: threshold makes false exports on pure noise at most 1/44 = 2.3 %, the fixed threshold's rate.
GIVEN_DRAWS = 43
#: The guard's largest false-export rate on pure noise: that of the fixed threshold of 2
#: standard errors on a normal statistic (2.3 %).
ALPHA = 0.5 * math.erfc(2.0 / math.sqrt(2.0))
#: Above this many poses the null is not drawn (its walks would take long): the fixed threshold.
NULL_MAX_POSES = 400


@dataclass(frozen=True)
class NullThreshold:
    """The guard's threshold from the null of selection + guard.

    Attributes:
        z: the ``rank``-th largest of the guard's ``z`` over the draws [standard errors].
        draws: the number of draws.
        rank: ``k``: the false-export rate on pure noise is ``k / (draws + 1)``.
        noise_mm: the noise drawn, RMS per residual row [mm] (the nominal model's residual).
    """

    z: float
    draws: int
    rank: int
    noise_mm: float

    @property
    def alpha(self) -> float:
        """The false-export rate on pure noise of the test."""
        return self.rank / (self.draws + 1)


def null_threshold(
    setup: Setup,
    nominal: np.ndarray,
    draws: int = NULL_DRAWS,
    seed: int = 0,
    given: np.ndarray | None = None,
) -> NullThreshold | None:
    """The threshold of the guard after a forward selection on ``setup`` (see the module), or
    after the fit of the ``given`` unknowns.

    Args:
        setup: the problem, carrying the pull's weight the fit used.
        nominal: the registration-only θ (with the extension's fit, when one is fitted).
        draws: draws of pure noise.
        seed: their seed.
        given: mask of the fitted unknowns when they were given, not selected (the geometric
            ones of them are the fit's columns in every draw).

    Returns:
        The threshold, or None when the data are too many for the null (:data:`NULL_MAX_POSES`)
        or leave no room for it.
    """
    if len(setup.data) > NULL_MAX_POSES:
        return None
    plan = design(setup, nominal)
    free = len(plan.jac) - plan.basis.shape[1]
    chosen = None if given is None else [k for k in plan.candidates if given[k]]
    if free <= 0 or not plan.candidates or chosen == []:
        return None
    res = plan.project(setup.linearised(nominal)[0])
    sigma = float(np.sqrt(res @ res / free))

    eps = np.column_stack(
        [noise_rows(setup, len(plan.jac), sigma, np.random.default_rng([seed, k])) for k in range(draws)]
    )
    if chosen is None:  # the walks in fixed batches: the same answer on one core or two
        batches = draw_batches(plan, draws)
        zs = np.sort(
            np.concatenate(
                parallel_map(functools.partial(_selected_zs, setup, plan, eps, batches), len(batches))
            )
        )
    else:  # the same columns in every draw: their leave-one-out algebra once, for all draws
        zs = np.sort(_zs(setup, plan, chosen, eps))
    rank = max(1, int(ALPHA * (draws + 1)))
    return NullThreshold(float(zs[-rank]), draws, rank, sigma * 1e3)


def noise_rows(setup: Setup, n_rows: int, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """``n_rows`` residual rows of pure noise [m]: ``sigma`` per row, or for distance data noise
    of ``sigma / √2`` per axis on each measured point, carried to every pair's distance."""
    problem = setup.problem
    if not problem.measurement.measure.by_pairs:
        return rng.normal(0.0, sigma, n_rows)
    eps = rng.normal(0.0, sigma / np.sqrt(2.0), setup.data.points.shape)
    return problem.measurement.measure.noise_rows(problem, n_rows, eps[:, :, None])[:, 0]


def _selected_zs(
    setup: Setup, plan: Design, eps: np.ndarray, batches: list[np.ndarray], k: int
) -> np.ndarray:
    """The guard's ``z`` of the set the selection chooses on each draw of pure noise of batch ``k``
    (the columns ``batches[k]`` of ``eps``, walked together)."""
    draws = eps[:, batches[k]]
    chosen = (
        added[: choose_step(path, done, MIN_GAIN, KEEP_ALL)] for path, done, added in walks(plan, draws)
    )
    return np.array([_zs(setup, plan, cols, draws[:, [j]])[0] for j, cols in enumerate(chosen)])


def _zs(setup: Setup, plan: Design, chosen: list[int], eps: np.ndarray) -> np.ndarray:
    """The guard's ``z`` of the fit of the columns ``chosen`` on each draw of pure noise ``eps``
    (R, D): (D,)."""
    fit = press(plan.jac[:, chosen], plan.basis, setup.prior_weight, eps, plan.groups)
    base = press(plan.jac[:, :0], plan.basis, 0.0, eps, plan.groups)
    return np.array([z_of(log_gains(base[:, k], fit[:, k])) for k in range(eps.shape[1])])


def press(
    geometric: np.ndarray, basis: np.ndarray, weight: float, res: np.ndarray, groups: list[np.ndarray]
) -> np.ndarray:
    """Each group's squared leave-one-out error [m²] of the linear fit of ``res`` on the pulled
    columns ``geometric`` (natural units, pull ``weight``) and the free columns ``basis``: (G,),
    or (G, D) for ``D`` residual vectors at once (``res`` (R, D): the fit and its hat matrices
    are shared by them)."""
    jac = np.column_stack([geometric, basis])
    pen = np.r_[np.ones(geometric.shape[1]), np.zeros(basis.shape[1])]
    spread = np.linalg.lstsq(jac.T @ jac + weight**2 * np.diag(pen), jac.T, rcond=None)[0].T
    fitted = res - jac @ (spread.T @ res)
    return held_out_squares(jac, spread, fitted, groups)


def log_gains(base: np.ndarray, fit: np.ndarray) -> np.ndarray:
    """Each group's gain of the fit over the nominal model: the log of the ratio of their squared
    held-out errors (``base`` over ``fit``, [m²] each; positive where the fit does better).

    A ratio, not a difference: where the nominal model is far off, the differences are its own
    squared errors, which spread over the poses as widely as they are large, so their mean could
    not pass many standard errors on a few poses however much better the fit was (20 poses whose
    nominal errors spread by 110 % of their mean give 3.9 standard errors, for a fit 18 times
    better in RMS), while a selection on pure noise makes small, even gains that pass as many.
    The ratios of a fit that is better by much stay large and even. Errors are floored at 1e-12
    of the larger mean, so that an exact zero does not make the log infinite."""
    floor = 1e-12 * max(float(np.mean(base)), float(np.mean(fit)), 1e-300)
    return np.log(np.maximum(base, floor)) - np.log(np.maximum(fit, floor))


def z_of(gain: np.ndarray) -> float:
    """Mean of the per-group gains over its standard error (0 when they do not spread)."""
    if len(gain) < 2:
        return 0.0
    stderr = float(np.std(gain, ddof=1) / np.sqrt(len(gain)))
    return float(np.mean(gain) / stderr) if stderr > 0 else 0.0
