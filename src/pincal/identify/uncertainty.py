"""The standard deviations a calibration reports: the posterior ones with the pull toward the
URDF, each measurement kind's rows counted for the noise they carry (position rows alike;
pose data's position and orientation rows apart; distance pairs for the 3N coordinates they come
from). Scales are the unknowns' natural sizes (:class:`pincal.identify.solver.Setup`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pincal.identify import chunked
from pincal.identify.kinds import pair_directions
from pincal.identify.measurements import Problem

#: What the reported standard deviations are.
STD_MEANS = (
    "posterior standard deviation: sigma^2 (J^T J + w^2 P)^-1 with the pull toward the URDF "
    "(weight w on the geometric corrections, P), sigma^2 = |r|^2 / (n - tr H), H = J (J^T J + w^2 P)^-1 J^T; "
    "for pose data, the estimator's covariance M J^T D J M (D: each row's noise variance, position "
    "and orientation rows apart); for distance data, the estimator's covariance "
    "M J^T A A^T J M sigma^2 (M = (J^T J + w^2 P)^-1, "
    "A carries noise on the measured points to the pairs, sigma per axis from "
    "E|r|^2 = sigma^2 tr((I-H) A A^T))"
)


@dataclass(frozen=True, eq=False)
class RowSums:
    """Sums over a problem's rows at one θ, its two kinds of rows apart (a pose's position rows,
    then its orientation rows; position data has only the first): all the standard deviations
    read of the rows, and the normal equations of the pull's evidence (:meth:`normal_terms`).

    Attributes:
        grams: ``JᵀJ`` of each kind (2, k, k), over the ``k`` free unknowns, unscaled.
        grad: ``Jᵀr`` (k,).
        squares: ``|r|²`` of each kind (2,).
        counts: rows of each kind (2,).
    """

    grams: np.ndarray
    grad: np.ndarray
    squares: np.ndarray
    counts: np.ndarray

    def normal_terms(self) -> tuple[np.ndarray, np.ndarray, float, int]:
        """``JᵀJ``, ``Jᵀr``, ``rᵀr`` and the rows, as :func:`pincal.identify.chunked.normal_terms`."""
        return self.grams.sum(axis=0), self.grad, float(self.squares.sum()), int(self.counts.sum())


def row_sums(problem: Problem, theta: np.ndarray, free: np.ndarray) -> RowSums:
    """:class:`RowSums` of ``problem`` at ``theta`` over the unknowns ``free``, block by block on a
    large problem (:func:`pincal.identify.chunked.block_sums`: one pass over its rows)."""
    width = problem.measurement.measure.width

    def by_kind(res: np.ndarray, jac: np.ndarray) -> tuple[np.ndarray, ...]:
        turned = (np.arange(len(res)) % width) >= 3  # a block's rows start at a pose's first row
        if not turned.any():  # position rows only
            empty = np.zeros((jac.shape[1], jac.shape[1]))
            grams, squares = np.stack([jac.T @ jac, empty]), np.array([float(res @ res), 0.0])
            return grams, jac.T @ res, squares, np.array([float(len(res)), 0.0])
        kinds = (~turned, turned)
        grams = np.stack([jac[rows].T @ jac[rows] for rows in kinds])
        squares = np.array([float(res[rows] @ res[rows]) for rows in kinds])
        return grams, jac.T @ res, squares, np.array([float(np.count_nonzero(rows)) for rows in kinds])

    cols = np.arange(problem.n_params)[free]
    return RowSums(*chunked.block_sums(problem, theta, cols, by_kind))


def posterior_std(
    problem: Problem,
    scale: np.ndarray,
    weight: float,
    theta: np.ndarray,
    free: np.ndarray,
    sums: RowSums | None = None,
) -> np.ndarray:
    """Each unknown's posterior standard deviation at the fit ``theta`` (0 where not free) [m or rad].

    The linearised Gaussian model of :mod:`pincal.identify.prior`: residuals ``N(0, σ²)``,
    geometric corrections ``N(0, (σ/w)²)`` in natural units (``w = weight``), so the
    covariance is ``σ² (JᵀJ + w²P)⁻¹``, and ``σ² = |r|² / (n - tr H)``, ``H = J (JᵀJ + w²P)⁻¹ Jᵀ``
    the fit's hat matrix (``tr H`` the unknowns the data fit: ``k`` without the pull, fewer with
    it). At the weight of largest evidence this is close to the evidence's profiled value
    ``(|r|² + w²|δ|²) / (n + p - k)`` (``p`` pulled of the ``k`` free unknowns); at another
    weight that one is not: with the pull off (a weight of 1e-9) it counted the ``p`` rows of a
    pull that holds nothing, and the standard deviations of 25 poses of positions were 24 % too
    small for some parameters (``benchmarks/std_spread.py``). Distance rows are
    not independent (N points make N(N-1)/2 pairs): :func:`pair_std`. ``sums``: the rows' sums
    (:func:`row_sums`) when already made, at ``theta`` or at a fit as close (on a large problem,
    the pull's evidence's: a million poses' fit moves with the pull by far less than its
    standard deviations); by default made at ``theta``.
    """
    if problem.measurement.measure.by_pairs:
        return pair_std(problem, scale, weight, theta, free)
    sums = row_sums(problem, theta, free) if sums is None else sums
    if problem.measurement.measure.orientation:
        return pose_std(problem, scale, weight, free, sums)
    std = np.zeros(problem.n_params)
    scale = scale[free]
    gram, _, squares, rows = sums.normal_terms()
    gram = gram * np.outer(scale, scale)
    pen = np.arange(int(free.sum())) < int(free[: problem.model.n_params].sum())
    inverse = np.linalg.pinv(gram + weight**2 * np.diag(pen.astype(float)))
    sigma2 = squares / max(rows - float(np.trace(inverse @ gram)), 1.0)
    std[free] = np.sqrt(np.clip(np.diag(inverse * sigma2), 0.0, None)) * scale
    return std


def pose_std(
    problem: Problem, scale: np.ndarray, weight: float, free: np.ndarray, sums: RowSums
) -> np.ndarray:
    """Standard deviations [m or rad] of a pose fit, whose position and orientation rows carry
    noise of different sizes: the estimator's covariance ``M Jᵀ D J M`` (``M = (JᵀJ + w²P)⁻¹``,
    ``D`` each row's noise variance), each kind's variance from its residual rows
    ``Σ r² / Σ (1 - h)`` (``h`` the hat matrix's diagonal, ``Σ h = tr(M J_kᵀ J_k)`` over the
    kind's rows ``J_k``): ``J_kᵀ J_k`` and ``Σ r²`` of each kind, summed block by block
    (:func:`row_sums`)."""
    std = np.zeros(problem.n_params)
    scale = scale[free]
    grams, squares, counts = sums.grams * np.outer(scale, scale), sums.squares, sums.counts
    pen = np.arange(int(free.sum())) < int(free[: problem.model.n_params].sum())
    inverse = np.linalg.pinv(grams.sum(axis=0) + weight**2 * np.diag(pen.astype(float)))
    left = counts - np.einsum("ij,kji->k", inverse, grams)  # Σ (1 - h) of each kind
    variance = squares / np.maximum(left, 1e-12)
    cov = inverse @ np.einsum("k,kij->ij", variance, grams) @ inverse
    std[free] = np.sqrt(np.clip(np.diag(cov), 0.0, None)) * scale
    return std


def _pulled_normal(
    problem: Problem, scale: np.ndarray, weight: float, theta: np.ndarray, free: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Jacobian of the unknowns ``free`` in natural units (``scale``, theirs), the residual,
    and ``M = (JᵀJ + w²P)⁻¹`` (``P`` the pulled geometric corrections)."""
    jac = problem.jacobian(theta, free) * scale
    pen = np.arange(int(free.sum())) < int(free[: problem.model.n_params].sum())
    inverse = np.linalg.pinv(jac.T @ jac + weight**2 * np.diag(pen.astype(float)))
    return jac, problem.residuals(theta), inverse


def carried_to_points(problem: Problem, jac: np.ndarray) -> np.ndarray:
    """``Aᵀ J`` (3N, k) for the map ``A`` (pairs, 3N) from noise on the measured points to the
    pairs' distance rows (row ``p`` holds the pair's unit vector ``u_p`` at its first point's
    coordinates and ``-u_p`` at its second's), without forming ``A``."""
    pairs, points = problem.pairs, problem.data.points
    along = pair_directions(points, pairs)
    out = np.zeros((len(points), 3, jac.shape[1]))
    each = along[:, :, None] * jac[:, None, :]  # (pairs, 3, k)
    np.add.at(out, pairs[:, 0], each)
    np.add.at(out, pairs[:, 1], -each)
    return out.reshape(3 * len(points), jac.shape[1])


#: Above this many measured points, :func:`whitened_pair_terms` is not formed (its eigenproblem
#: grows as the cube of the points): the pairs are then counted by their effective number.
WHITENED_POINTS = 400


def points_gram(problem: Problem) -> np.ndarray:
    """``AᵀA`` (3N, 3N) for the map ``A`` (pairs, 3N) from noise on the measured points to the
    pairs' distance rows (:func:`carried_to_points`)."""
    pairs, n = problem.pairs, len(problem.data)
    outer = np.einsum("pi,pj->pij", *(2 * [pair_directions(problem.data.points, pairs)]))
    gram = np.zeros((n, n, 3, 3))
    for a, b, sign in ((0, 0, 1.0), (1, 1, 1.0), (0, 1, -1.0), (1, 0, -1.0)):
        np.add.at(gram, (pairs[:, a], pairs[:, b]), sign * outer)
    return gram.transpose(0, 2, 1, 3).reshape(3 * n, 3 * n)


def whitened_pair_terms(
    problem: Problem, theta: np.ndarray, free: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float, int] | None:
    """The normal terms of distance data whitened (generalised least squares): ``JᵀWJ``,
    ``JᵀWr``, ``rᵀWr`` and the rank of ``W = (A Aᵀ)⁺``, the pairs' rows weighted by the inverse
    of their covariance under equal noise on every axis of every measured point (``A`` as in
    :func:`carried_to_points`; ``W = A (AᵀA)⁺² Aᵀ``, formed in the 3N coordinates of the points);
    the pairs then count for the coordinates they come from (at most ``3N - 6``: a rigid motion
    of every point changes no distance), not as N(N-1)/2 independent rows. The unit of ``r``
    after whitening is the noise per axis. None above :data:`WHITENED_POINTS` points."""
    if len(problem.data) > WHITENED_POINTS:
        return None
    values, vectors = np.linalg.eigh(points_gram(problem))
    kept = values > 1e-9 * max(float(values[-1]), 1e-300)
    whiten = vectors[:, kept].T / values[kept, None]  # Λ⁻¹ Vᵀ: (rank, 3N)
    res, jac = problem.rows(theta, np.flatnonzero(free))  # one pass, both carried to the points at once
    carried = whiten @ carried_to_points(problem, np.column_stack([jac, res]))
    jac, res = carried[:, :-1], carried[:, -1]
    return jac.T @ jac, jac.T @ res, float(res @ res), int(kept.sum())


def pair_std(
    problem: Problem, scale: np.ndarray, weight: float, theta: np.ndarray, free: np.ndarray
) -> np.ndarray:
    """Standard deviations [m or rad] of a distance fit: the estimator's covariance under noise of
    ``σ`` per axis on the measured points, carried to the pairs by ``A`` (:func:`carried_to_points`):
    ``M Jᵀ A Aᵀ J M σ²`` with ``M = (JᵀJ + w²P)⁻¹``, and ``σ²`` from the residual's expected
    size ``E|r|² = σ² tr((I - H) A Aᵀ)`` (``H = J M Jᵀ``): the pairs counted for the 3N coordinates they
    come from, not as N(N-1)/2 independent rows."""
    std = np.zeros(problem.n_params)
    scale = scale[free]
    jac, res, inverse = _pulled_normal(problem, scale, weight, theta, free)
    carried = carried_to_points(problem, jac)  # Aᵀ J; tr(A Aᵀ) = 2 per pair (two unit vectors)
    left = 2.0 * len(res) - float(np.trace(inverse @ carried.T @ carried))
    sigma2 = float(res @ res) / max(left, 1e-12)
    cov = inverse @ (carried.T @ carried) @ inverse * sigma2
    std[free] = np.sqrt(np.clip(np.diag(cov), 0.0, None)) * scale
    return std
