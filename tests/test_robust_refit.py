"""The outlier screen's ``soft_l1`` refit (:func:`pincal.identify.lm.soft_l1_roots`): least squares
on residuals that square to the robust cost is SciPy's robust fit, without ``scipy.optimize``."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from pincal.identify.lm import soft_l1_roots
from pincal.identify.outliers import pose_scores
from pincal.identify.solver import MAX_EVALUATIONS, register, set_up, solve
from pincal.simulation.truth import simulate


def test_the_roots_square_to_the_soft_l1_cost_and_their_jacobian_is_theirs() -> None:
    """Each row squares to ``2 f² (√(1 + r²/f²) - 1)`` (SciPy's ``soft_l1`` times 2), small or
    large against ``f``, and the Jacobian matches central differences."""
    rng = np.random.default_rng(0)
    matrix = rng.normal(size=(40, 3))
    f_scale = 0.3

    def residuals(x: np.ndarray) -> np.ndarray:
        return np.sin(matrix @ x) * np.geomspace(1e-4, 30.0, 40)

    def jacobian(x: np.ndarray) -> np.ndarray:
        return (np.cos(matrix @ x) * np.geomspace(1e-4, 30.0, 40))[:, None] * matrix

    rooted, rooted_jacobian = soft_l1_roots(residuals, jacobian, f_scale)
    x = rng.normal(size=3)
    r = residuals(x)
    assert np.allclose(
        rooted(x) ** 2, 2.0 * f_scale**2 * (np.sqrt(1.0 + (r / f_scale) ** 2) - 1.0), rtol=1e-12
    )
    step = 1e-6
    numeric = np.column_stack(
        [(rooted(x + step * e) - rooted(x - step * e)) / (2.0 * step) for e in np.eye(3)]
    )
    assert np.allclose(rooted_jacobian(x), numeric, rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize(("name", "n"), [("ur5", 15), ("ur5", 60), ("panda", 200)])
def test_the_robust_refit_is_scipys(get_robot, name: str, n: int) -> None:
    """A pose 4 mm off among tracker poses: the refit reaches SciPy's trust-region reflective
    ``soft_l1`` cost to 1e-10 relative, and every pose's outlier score to 1e-4."""
    robot = get_robot(name)
    _, fit, _ = simulate(robot, n, 0, 1, 3e-5)
    fit.points[3] += 0.004
    setup = set_up(robot, fit)
    start = register(setup)
    problem = setup.problem
    free = np.ones(problem.n_params, dtype=bool)
    f_scale = float(np.median(np.abs(problem.residuals(start))))
    ours, answer = solve(setup, start, free, "soft_l1", f_scale)
    geometric = np.arange(problem.model.n_params)
    prior = setup.prior_weight / setup.scale[geometric]
    nominal = problem.initial_theta()

    def residuals(x: np.ndarray) -> np.ndarray:
        return np.concatenate([problem.residuals(x), prior * (x[geometric] - nominal[geometric])])

    def jacobian(x: np.ndarray) -> np.ndarray:
        return np.vstack([problem.jacobian(x, free), np.eye(len(geometric), len(x)) * prior[:, None]])

    tight = dict.fromkeys(("xtol", "ftol", "gtol"), 1e-12)
    scipy = least_squares(
        residuals,
        start,
        jac=jacobian,
        loss="soft_l1",
        f_scale=f_scale,
        x_scale=setup.scale * 1e-3,
        max_nfev=MAX_EVALUATIONS,
        **tight,
    )
    assert answer.cost == pytest.approx(scipy.cost, rel=1e-10)
    assert np.allclose(pose_scores(problem, ours), pose_scores(problem, scipy.x), rtol=1e-4)
    assert np.argmax(pose_scores(problem, ours)) == 3
