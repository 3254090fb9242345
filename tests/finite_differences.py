"""Central finite differences of a model's tip pose, the reference the analytic Jacobians of
:func:`pincal.kinematics.chain.tip_jacobian` are checked against (test_jacobians, test_rounds),
and of a problem's residuals (test_markers)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

import pincal
from pincal.identify.measurements import Problem


def tip_jacobian_fd(
    model: pincal.kinematics.models.Model, x: np.ndarray, q: np.ndarray, step: float = 1e-6
) -> np.ndarray:
    """(N, 6, n) derivative of the tip's position [m] and orientation (log3 of the rotation
    between the two sides, [rad]) at configurations ``q`` with respect to the parameters at
    ``x``, by central differences of ``step`` per parameter."""
    jac = np.empty((len(q), 6, model.n_params))
    for k in range(model.n_params):
        dx = np.zeros(model.n_params)
        dx[k] = step
        plus = pincal.kinematics.chain.forward(model.chain(x + dx), q)
        minus = pincal.kinematics.chain.forward(model.chain(x - dx), q)
        jac[:, :3, k] = (plus.tip_translation - minus.tip_translation) / (2 * step)
        rel = plus.tip_rotation @ np.transpose(minus.tip_rotation, (0, 2, 1))
        jac[:, 3:, k] = np.array([pin.log3(r) for r in rel]) / (2 * step)
    return jac


def residual_jacobian_fd(problem: Problem, theta: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """(rows, P) derivative of ``problem``'s residuals [m] at ``theta`` by central differences of
    ``step`` per unknown."""
    jac = np.empty((len(problem.residuals(theta)), problem.n_params))
    for k in range(problem.n_params):
        dx = np.zeros(problem.n_params)
        dx[k] = step
        jac[:, k] = (problem.residuals(theta + dx) - problem.residuals(theta - dx)) / (2 * step)
    return jac
