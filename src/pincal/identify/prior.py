"""The pull toward the URDF, its strength chosen from the data: type-II maximum likelihood.

Each fit holds its geometric corrections ``δ`` (in natural units: metres, or the rotation that
moves the workspace by 1 m, see :func:`pincal.identify.identifiability.natural_scale`) near the URDF by rows
``w · δ`` beside the residuals. Read as a Gaussian model, residuals ``r ~ N(0, σ²)`` and
corrections ``δ ~ N(0, (σ/w)²)``, the weight ``w`` is the ratio of the noise to the size the
corrections are expected to have. Where the data pin a direction of the model down, ``w`` hardly
matters; where they leave it weakly determined (one placement of a socket pair, a few poses), the
fit in that direction is ``w``'s choice alone, and too weak a pull follows the noise.

:func:`choose_weight` scores each weight of :data:`WEIGHTS` by its evidence (marginal
likelihood, MacKay 1992), ``σ`` profiled out, and fits the model at the one of largest evidence.
Linearised at a fit (the default pull's; each weight's fit a Gauss-Newton step from it), with
``J`` the Jacobian of the residuals in natural units over the ``k`` fitted unknowns
(``p`` of them pulled), ``n`` residuals and ``S = |r|² + w²|δ|²``::

    log evidence(w) = -(n + p - k)/2 · log S + p · log w - ½ log det(JᵀJ + w² P) + const

(``P`` selects the pulled unknowns; the registration, tool, fixed points and effects have flat
priors). Noisy data or many weakly determined directions raise the chosen weight; clean, rich
data lower it. No held-out data is used: the training rows alone decide.

Distance data count their pairs by their effective number (:func:`counted_rows`): the
``N(N-1)/2`` distances of ``N`` measured points carry at most ``3N - 6`` independent pieces of
information (a rigid motion of all the points changes none of them), and their errors are
correlated through the points. Counting the pairs as ``n`` independent residuals overweights the
data against the prior. With every row scaled by the same factor ``c = n_eff / n`` (the
effective-number approximation of whitening), the formula keeps its form with ``n_eff`` for
``n``: the factor moves the weight's scale and the log determinant by constants.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from pincal.errors import DataError
from pincal.identify.chunked import normal_terms
from pincal.identify.lm import OptimizeResult
from pincal.identify.records import PriorChoice
from pincal.identify.rows import ProblemRows
from pincal.identify.solver import Setup, solve

#: Weights tried [per natural unit]: 1e-3 to 10, four per decade (0.1 m of correction then
#: weighs as a residual of 0.1 mm to 1 m).
WEIGHTS = tuple(float(w) for w in np.geomspace(1e-3, 10.0, 17))


def parse_prior(prior: float | str) -> float | None:
    """``"auto"`` -> None (chosen from the data); a number -> that weight (> 0).

    Raises:
        DataError: neither ``auto`` nor a positive number.
    """
    if isinstance(prior, str) and prior == "auto":
        return None
    try:
        weight = float(prior)
    except (TypeError, ValueError):
        raise DataError(f"prior={prior!r}: use auto or a weight > 0 (per natural unit)") from None
    if not np.isfinite(weight) or weight <= 0:
        raise DataError(f"prior={prior!r}: use auto or a weight > 0 (per natural unit)")
    return weight


def pulled(setup: Setup, free: np.ndarray) -> np.ndarray:
    """Of the free unknowns (in their order), those the prior pulls: the geometric ones."""
    return np.arange(int(free.sum())) < int(free[: setup.model.n_params].sum())


def counted_rows(problem: ProblemRows, n_rows: int) -> int:
    """The residual rows the evidence counts: ``n_rows``, but for distance data at most
    ``3 N - 6`` for ``N`` measured points (see the module)."""
    if not problem.measurement.measure.by_pairs:
        return n_rows
    return max(1, min(n_rows, 3 * len(problem.data) - 6))


def log_evidence(setup: Setup, theta: np.ndarray, free: np.ndarray) -> float:
    """Log evidence of the fit ``theta`` (free unknowns ``free``) at ``setup.prior_weight``,
    ``σ`` profiled out, up to a constant shared by every weight (see the module's formula)."""
    problem, weight = setup.problem, setup.prior_weight
    jac = problem.jacobian(theta, free) * setup.scale[free]
    res = problem.residuals(theta)
    pen = pulled(setup, free)
    geometric = np.flatnonzero(free)[pen]
    delta = (theta[geometric] - problem.initial_theta()[geometric]) / setup.scale[geometric]
    total = float(res @ res + weight**2 * delta @ delta)
    normal = jac.T @ jac + weight**2 * np.diag(pen.astype(float))
    logdet = float(np.linalg.slogdet(normal)[1])
    return _score(counted_rows(problem, len(res)), int(pen.sum()), int(free.sum()), total, weight, logdet)


def choose_weight(
    setup: Setup,
    start: np.ndarray,
    free: np.ndarray,
    prior: float | str = "auto",
    loss: str = "linear",
    terms: tuple[np.ndarray, np.ndarray, float, int] | None = None,
) -> tuple[PriorChoice, Setup, np.ndarray, OptimizeResult]:
    """The pull's weight (``prior``: ``auto`` or a weight), the setup carrying it, and the fit.

    Args:
        setup: the problem.
        start: the fit at ``setup.prior_weight`` (the default pull): the scan's linearisation
            point and the start of the fit at the chosen weight.
        free: mask of the unknowns to fit.
        prior: ``auto`` (maximum evidence over :data:`WEIGHTS`) or a weight [per natural unit].
        loss: the fit's loss: the evidence is that of Gaussian residuals, so with a robust loss
            ``auto`` keeps :data:`pincal.identify.solver.PRIOR_WEIGHT` (said in ``chosen_by``).
        terms: :func:`pincal.identify.chunked.normal_terms` at ``start``, when already made.
    """
    fixed = fixed_weight(setup, free, prior, loss)
    if fixed is not None:
        return _fixed(setup, start, free, *fixed)
    scores, steps = _curve(setup, start, free, WEIGHTS, terms)
    best = int(np.argmax(scores))
    chosen = replace(setup, prior_weight=WEIGHTS[best])
    stepped = start.copy()  # the chosen weight's Gauss-Newton step: the fit begins at its minimum
    stepped[free] += steps[best] * setup.scale[free]
    theta, result = solve(chosen, stepped, free)
    return PriorChoice(chosen.prior_weight, "evidence", tuple(zip(WEIGHTS, scores))), chosen, theta, result


def fixed_weight(setup: Setup, free: np.ndarray, prior: float | str, loss: str) -> tuple[float, str] | None:
    """The pull's weight and how it was set, when the evidence does not choose it (as
    :func:`choose_weight` says; None: the evidence chooses it)."""
    given = parse_prior(prior)
    if given is not None:
        return given, "given"
    if not free[: setup.model.n_params].any():
        return setup.prior_weight, "nothing pulled"
    if loss != "linear":
        return setup.prior_weight, "default (robust loss: no Gaussian evidence)"
    return None


def evidence_curve(
    setup: Setup,
    theta: np.ndarray,
    free: np.ndarray,
    weights: Sequence[float],
    terms: tuple[np.ndarray, np.ndarray, float, int] | None = None,
) -> list[float]:
    """Log evidence of each weight (as :func:`log_evidence`), linearised at the fit ``theta``:
    each weight's fit is the Gauss-Newton step from ``theta`` (two solves in all, not one per
    weight; the corrections are small enough for the residuals to be nearly linear in them).
    ``terms``: :func:`pincal.identify.chunked.normal_terms` at ``theta``, when already computed."""
    return _curve(setup, theta, free, weights, terms)[0]


def _curve(
    setup: Setup,
    theta: np.ndarray,
    free: np.ndarray,
    weights: Sequence[float],
    terms: tuple[np.ndarray, np.ndarray, float, int] | None = None,
) -> tuple[list[float], list[np.ndarray]]:
    """:func:`evidence_curve`, and each weight's Gauss-Newton step from ``theta`` (natural units,
    over the free unknowns)."""
    problem = setup.problem
    terms = normal_terms(problem, theta, free) if terms is None else terms  # by blocks on large data
    unscaled, unscaled_grad, rr, n_rows = terms
    scale = setup.scale[free]
    gram, grad = unscaled * np.outer(scale, scale), unscaled_grad * scale
    pen = pulled(setup, free).astype(float)
    geometric = np.flatnonzero(free)[pen > 0]
    delta = np.zeros(len(pen))
    delta[pen > 0] = (theta[geometric] - problem.initial_theta()[geometric]) / setup.scale[geometric]
    n_pulled, n_rows = int(pen.sum()), counted_rows(problem, n_rows)
    steps = _ridge_steps(gram, grad, pen > 0, delta, np.asarray(weights, dtype=float))
    out = []
    for weight, (step, logdet) in zip(weights, steps):
        held = pen * (delta + step)
        moved = rr + 2.0 * float(step @ grad) + float(step @ gram @ step)  # |r + J step|²
        total = moved + weight**2 * float(held @ held)
        out.append(_score(n_rows, n_pulled, len(pen), total, weight, logdet))
    return out, [step for step, _ in steps]


def _ridge_steps(
    gram: np.ndarray, grad: np.ndarray, pen: np.ndarray, delta: np.ndarray, weights: np.ndarray
) -> list[tuple[np.ndarray, float]]:
    """For each weight ``w``: the Gauss-Newton step of the pulled problem, ``-(G + w²P)⁻¹ (g + w² P δ)``,
    and ``log det(G + w²P)``, ``P`` the mask ``pen``.

    One eigendecomposition serves every weight: with the unpulled unknowns ``b`` eliminated
    (``S = G_aa - G_ab G_bb⁻¹ G_ba`` = ``V Λ Vᵀ``), ``det(G + w²P) = det(G_bb) Π (λ + w²)`` and the
    step's pulled part is ``-V (Λ + w²)⁻¹ Vᵀ (g_a - G_ab G_bb⁻¹ g_b + w² δ_a)``. When ``G_bb`` is
    singular, each weight is solved on its own (least squares).
    """
    a, b = np.flatnonzero(pen), np.flatnonzero(~pen)
    try:
        chol = np.linalg.cholesky(gram[np.ix_(b, b)]) if b.size else np.zeros((0, 0))
    except np.linalg.LinAlgError:
        return [_ridge_step(gram, grad, pen, delta, w) for w in weights]
    cross = gram[np.ix_(a, b)]
    against = np.linalg.solve(chol.T, np.linalg.solve(chol, np.column_stack([cross.T, grad[b]])))
    through, z = against[:, :-1], against[:, -1]  # G_bb⁻¹ G_ba and G_bb⁻¹ g_b
    lam, vec = np.linalg.eigh(gram[np.ix_(a, a)] - cross @ through)
    sq = weights**2
    coef = (vec.T @ (grad[a] - cross @ z))[:, None] + (vec.T @ delta[a])[:, None] * sq[None, :]
    step_a = -vec @ (coef / (lam[:, None] + sq[None, :]))  # (a, weights)
    steps = np.zeros((len(grad), len(weights)))
    steps[a], steps[b] = step_a, -z[:, None] - through @ step_a
    base = 2.0 * float(np.sum(np.log(np.diag(chol))))
    logdets = base + np.sum(np.log(lam[:, None] + sq[None, :]), axis=0)
    return [(steps[:, k], float(logdets[k])) for k in range(len(weights))]


def _ridge_step(
    gram: np.ndarray, grad: np.ndarray, pen: np.ndarray, delta: np.ndarray, weight: float
) -> tuple[np.ndarray, float]:
    """:func:`_ridge_steps` for one weight, by least squares (any ``G``)."""
    normal = gram + weight**2 * np.diag(pen.astype(float))
    step = -np.linalg.lstsq(normal, grad + weight**2 * pen * delta, rcond=None)[0]
    return step, float(np.linalg.slogdet(normal)[1])


def _score(n: int, n_pulled: int, n_free: int, total: float, weight: float, logdet: float) -> float:
    """The module's formula: ``n`` residuals, ``n_free`` unknowns of which ``n_pulled`` pulled,
    ``S = total`` [m²], the weight, and ``log det(JᵀJ + w² P)``."""
    return float(-(n + n_pulled - n_free) / 2 * np.log(total) + n_pulled * np.log(weight) - logdet / 2)


def _fixed(
    setup: Setup, start: np.ndarray, free: np.ndarray, weight: float, how: str
) -> tuple[PriorChoice, Setup, np.ndarray, OptimizeResult]:
    """The fit at a weight not chosen by the evidence."""
    chosen = replace(setup, prior_weight=weight)
    theta, result = solve(chosen, start, free)
    return PriorChoice(weight, how), chosen, theta, result
