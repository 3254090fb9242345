"""Levenberg-Marquardt with LAPACK's QR: the fits without a robust loss.

Why not ``scipy.optimize.least_squares(method="lm")``: MINPACK's ``lmder`` factors each Jacobian
with its own unblocked Householder QR, which costs 2.5-3 × NumPy's (LAPACK's blocked) QR of the
same matrix: 4.8 against 2.7 ms for 3,000 × 45, 68 against 26 ms for 30,000 × 45 (one thread,
this machine kind), and that QR is most of an iteration. This is the same method (Moré 1978:
scaled variables, the Gauss-Newton step when it lowers the cost, else a damped one) with one
LAPACK QR of ``[J r]`` per Jacobian; damped steps only need the small ``n × n`` triangle.
The outlier screen's ``soft_l1`` refit is least squares on residuals that square to its cost
(:func:`soft_l1_roots`); other robust losses keep ``least_squares`` (trust-region reflective).

The damping follows the step's gain ratio ``ρ`` (actual over predicted fall of the cost; Nielsen
1999, Madsen, Nielsen & Tingleff 2004 §3.1): after a step that lowers the cost it is multiplied
by ``max(1/3, 1 - (2ρ - 1)³)``, after one that does not by 2, 4, 8... A fixed factor of 10 each
way makes every third step fail in a curved, narrow valley (a selection that keeps two nearly
equivalent rotations: a joint's and the registration's) and crawls along it: on TIAGo's day,
about 50 Jacobians where this takes 15 (MINPACK 12) to the same minimum.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np


class OptimizeResult(dict[str, Any]):
    """A fit's answer, as ``scipy.optimize.OptimizeResult``: a dict whose keys are attributes
    too (``x``, ``cost``, ``fun``, ``nfev``, ``njev``, ``status``, ``success``, ``message``).

    Defined here so that a calibration does not import ``scipy.optimize`` (0.3 s of start-up,
    FFTs and linear programming included) unless a robust loss needs ``least_squares``.
    """

    def __getattr__(self, name: str) -> Any:
        try:
            return self[name]
        except KeyError as exc:
            raise AttributeError(name) from exc

    __setattr__ = dict.__setitem__
    __delattr__ = dict.__delitem__


#: First damping, relative to the largest diagonal entry of ``JᵀJ``, when the Gauss-Newton step fails.
FIRST_DAMPING = 1e-4
#: Damping grows by this factor after a first failed step, and the factor doubles after each
#: further one (reset by a successful step).
DAMPING_GROWTH = 2.0
#: A successful step divides the damping by at most this factor (when ``ρ`` is near 1).
DAMPING_FALL = 3.0
#: Damping beyond this, relative to the largest diagonal entry of ``JᵀJ``, moves x by less than
#: any tolerance: the search stops there (the growth would otherwise overflow on a flat cost).
MAX_DAMPING = 1e20


def damped_less(damping: float, ratio: float) -> float:
    """The damping after a step that lowered the cost, its gain ratio ``ratio`` (actual over
    predicted fall): a third of it when the linear model predicted well, more when it did not."""
    return damping * max(1.0 / DAMPING_FALL, 1.0 - (2.0 * ratio - 1.0) ** 3)


#: Rows of each piece a tall matrix's QR takes at a time (:func:`triangle_of`).
QR_ROWS = 2000


def triangle_of(matrix: np.ndarray, below: np.ndarray | None = None) -> np.ndarray:
    """The triangle R of the QR of ``matrix`` (m, n) stacked on ``below``'s rows (a triangle
    already found, or None), :data:`QR_ROWS` rows at a time: the same R (up to its rows' signs,
    which no step depends on) as one LAPACK QR of every row, 2-3 × faster on tall matrices,
    whose Householder vectors no longer fit the cache."""
    tri = np.empty((0, matrix.shape[1])) if below is None else below
    for first in range(0, max(len(matrix), 1), QR_ROWS):
        tri = np.asarray(np.linalg.qr(np.vstack([tri, matrix[first : first + QR_ROWS]]), mode="r"))
    return tri


def _step(tri: np.ndarray, qtr: np.ndarray, damping: float) -> np.ndarray:
    """argmin ‖R δ + Qᵀr‖² + λ ‖δ‖² (minimum norm where R is singular)."""
    if damping > 0.0:
        n = len(qtr)
        tri = np.vstack([tri, np.sqrt(damping) * np.eye(n)])
        qtr = np.concatenate([qtr, np.zeros(n)])
    return -np.linalg.lstsq(tri, qtr, rcond=None)[0]


def levenberg_marquardt(
    fun: Callable[[np.ndarray], np.ndarray],
    jac: Callable[[np.ndarray], np.ndarray],
    x0: np.ndarray,
    x_scale: np.ndarray,
    xtol: float = 1e-12,
    ftol: float = 1e-12,
    gtol: float = 1e-12,
    max_nfev: int = 200,
    triangle: Callable[[np.ndarray], np.ndarray] | None = None,
) -> OptimizeResult:
    """Minimise ``½‖fun(x)‖²``; arguments and result as ``scipy.optimize.least_squares``.

    Args:
        fun, jac: residuals (m,) and their Jacobian (m, n) at ``x``.
        x0: the start (n,).
        x_scale: each variable's characteristic size (the step is taken in ``x / x_scale``).
        xtol, ftol, gtol: stop when the scaled step is below ``xtol`` relative to ``x``, when
            the cost falls by less than ``ftol`` relative (and is predicted to), or when no
            column of the Jacobian is more than ``gtol`` from orthogonal to the residuals.
        max_nfev: most evaluations of ``fun``.
        triangle: if given, ``triangle(x)`` is the triangle R of the QR of ``[jac(x) · x_scale,
            fun(x)]`` (built block by block for large data, :mod:`pincal.identify.chunked`), and ``jac`` is
            not called: every step needs only R.
    """
    x, res = np.array(x0, dtype=float), fun(x0)
    cost, nfev, njev, damping, growth = 0.5 * float(res @ res), 1, 0, 0.0, DAMPING_GROWTH
    status, message = 0, "the maximum number of function evaluations is exceeded"
    while nfev < max_nfev and status == 0:
        tri_all = triangle_of(np.column_stack([jac(x) * x_scale, res])) if triangle is None else triangle(x)
        njev += 1
        n = len(x)
        tri, qtr = tri_all[:n, :n], tri_all[:n, n]
        columns = np.linalg.norm(tri, axis=0)  # JᵀJ = RᵀR and Jᵀr = Rᵀ(Qᵀr): R says all
        res_norm = np.sqrt(2.0 * cost)
        cosines = np.abs(tri.T @ qtr) / np.where(columns > 0, columns, 1.0)
        if res_norm == 0.0 or np.max(cosines) <= gtol * res_norm:
            status, message = 1, "gtol: the residuals are orthogonal to the Jacobian's columns"
            break
        largest = float(np.max(np.sum(tri**2, axis=0)))
        while nfev < max_nfev:
            step = _step(tri, qtr, damping)
            trial = x + step * x_scale
            res_trial = fun(trial)
            nfev += 1
            cost_trial = 0.5 * float(res_trial @ res_trial)
            small = np.linalg.norm(step) <= xtol * (xtol + np.linalg.norm(x / x_scale))
            predicted = 0.5 * float(qtr @ qtr - np.sum((tri @ step + qtr) ** 2))  # by the linear model
            if cost_trial < cost:
                converged = cost - cost_trial <= ftol * cost and predicted <= ftol * cost
                ratio = (cost - cost_trial) / predicted if predicted > 0.0 else 1.0
                x, res, cost = trial, res_trial, cost_trial
                damping = damped_less(damping, ratio) if damping > 1e-12 * largest else 0.0
                growth = DAMPING_GROWTH
                if converged:
                    status, message = 2, "ftol: the cost no longer falls"
                elif small:
                    status, message = 3, "xtol: the step is below the tolerance"
                break
            if small:  # no lower cost within the tolerance of x: x is the minimum
                status, message = 3, "xtol: the step is below the tolerance"
                break
            if predicted <= ftol * cost:  # even the linear model has nothing left to gain
                status, message = 2, "ftol: the cost no longer falls"
                break
            damping, growth = max(damping * growth, FIRST_DAMPING * largest), 2.0 * growth
            if damping > MAX_DAMPING * largest:  # no step short enough to trust lowers the cost
                status, message = 3, "xtol: the step is below the tolerance"
                break
    return OptimizeResult(
        x=x, cost=cost, fun=res, nfev=nfev, njev=njev, status=status, success=status > 0, message=message
    )


Vector = Callable[[np.ndarray], np.ndarray]


def soft_l1_roots(residuals: Vector, jacobian: Vector, f_scale: float) -> tuple[Vector, Vector]:
    """Residuals whose sum of squares is the ``soft_l1`` cost of ``residuals``, and their Jacobian.

    ``soft_l1`` (as ``scipy.optimize.least_squares`` defines it, on every row) costs
    ``f² ρ(r²/f²)`` a row, ``ρ(z) = 2(√(1+z) - 1) = 2z / (√(1+z) + 1)``; the rows ``r √(2 / (s + 1))``,
    ``s = √(1 + r²/f²)``, square to it, and their derivative is ``√((s + 1) / 2) / s`` times
    ``r``'s. Least squares on them is that robust fit (the same minimum as SciPy's trust-region
    reflective, to the solvers' tolerances), without importing ``scipy.optimize`` (0.3 s).
    """

    def rooted(x: np.ndarray) -> np.ndarray:
        return soft_l1_rows(residuals(x), f_scale)

    def rooted_jacobian(x: np.ndarray) -> np.ndarray:
        return jacobian(x) * soft_l1_slopes(residuals(x), f_scale)[:, None]

    return rooted, rooted_jacobian


def soft_l1_rows(res: np.ndarray, f_scale: float) -> np.ndarray:
    """The rows of :func:`soft_l1_roots` of the residuals ``res``: ``r √(2 / (s + 1))``."""
    return res * np.sqrt(2.0 / (np.sqrt(1.0 + (res / f_scale) ** 2) + 1.0))


def soft_l1_slopes(res: np.ndarray, f_scale: float) -> np.ndarray:
    """Each of those rows' derivative over its residual's, ``√((s + 1) / 2) / s``."""
    root = np.sqrt(1.0 + (res / f_scale) ** 2)
    return np.sqrt((root + 1.0) / 2.0) / root
