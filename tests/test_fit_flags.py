"""What a fit reports of itself (issue 40, point 6).

- The standard deviations with the pull toward the URDF are the posterior ones
  ``σ² (JᵀJ + w²P)⁻¹``: never above the prior's ``σ/w`` in natural units (the plain
  ``σ² (JᵀJ)⁻¹`` is far above it where the data hardly determine a correction), and the report
  says what they are.
- A fit stopped at the solver's evaluation limit is flagged, and the report warns.
- An evidence optimum at the edge of the weights scanned is flagged, and the report warns.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import pincal
import pincal.identify.identifiability
import pincal.identify.solver as solver
from pincal.identify.measurements import Problem
from pincal.identify.prior import WEIGHTS
from pincal.identify.records import PriorChoice
from pincal.report.report import report_warnings
from pincal.simulation.truth import points_truth, simulate_points

SOCKETS = np.array([[0.45, 0.0, 0.25], [0.45, 0.05, 0.25]])


def _socket_fit(weight: float) -> tuple[pincal.Calibration, pincal.Dataset]:
    """Fifteen rows at one placement of two sockets: many corrections hardly determined."""
    robot = pincal.load_robot("ur5")
    data = simulate_points(points_truth(robot, 0), SOCKETS, 15, 5e-5, np.random.default_rng(1))
    distances = (("0", "1", 0.05),)
    cal = pincal.calibrate(
        robot, data, "placements", point_distances=distances, pull=pincal.Pull(weight, True)
    )
    return cal, data


@pytest.mark.parametrize("weight", [0.1, 3.0])
def test_standard_deviations_are_posterior_and_below_the_prior(weight: float) -> None:
    """Every pulled correction's std, in natural units, is at most the prior's ``σ / w`` with ``σ``
    the noise the evidence profiles: ``(|r|² + w²|δ|²) / (n + p - k)``."""
    cal, data = _socket_fit(weight)
    problem = Problem(cal.model, cal.measurement, data, cal.extension)
    n = cal.model.n_params
    free = cal.identifiability.identifiable
    scale = pincal.identify.identifiability.natural_scale(problem)
    res = problem.residuals(cal.theta)
    delta = (cal.theta[:n] - problem.initial_theta()[:n])[free[:n]] / scale[:n][free[:n]]
    pulled, k = int(free[:n].sum()), int(free.sum())
    sigma = np.sqrt((res @ res + weight**2 * delta @ delta) / (len(res) + pulled - k))
    natural = cal.std[:n][free[:n]] / scale[:n][free[:n]]
    assert pulled > 10 and np.all(natural <= sigma / weight * (1 + 1e-6)), (natural.max(), sigma / weight)
    assert "posterior" in pincal.report_dict(cal)["std_means"]


def test_a_fit_stopped_at_its_evaluation_limit_is_flagged(monkeypatch: pytest.MonkeyPatch) -> None:
    robot = pincal.load_robot("ur5")
    _, fit, _ = pincal.simulate(robot, 40, 1, seed=4)
    done = pincal.calibrate(robot, fit, "placements")
    assert done.converged and not any("evaluation limit" in w for w in report_warnings(done))
    monkeypatch.setattr(solver, "MAX_EVALUATIONS", 2)
    stopped = pincal.calibrate(robot, fit, "placements")
    assert not stopped.converged
    assert any("evaluation limit" in w for w in report_warnings(stopped))
    assert pincal.report_dict(stopped)["solver"]["converged"] is False


@pytest.mark.parametrize(("at", "edge"), [(0, True), (len(WEIGHTS) - 1, True), (8, False)])
def test_an_evidence_optimum_at_the_grid_edge_is_flagged(at: int, edge: bool) -> None:
    curve = tuple((w, -abs(k - at) * 1.0) for k, w in enumerate(WEIGHTS))
    choice = PriorChoice(WEIGHTS[at], "evidence", curve)
    assert choice.at_edge is edge and choice.to_dict()["at_grid_edge"] is edge
    assert ("edge of the weights" in choice.text()) is edge
    robot = pincal.load_robot("ur5")
    _, fit, _ = pincal.simulate(robot, 30, 1, seed=4)
    cal = replace(pincal.calibrate(robot, fit, "placements"), prior=choice)
    assert any("edge of the weights the evidence scanned" in w for w in report_warnings(cal)) is edge
    given = PriorChoice(WEIGHTS[-1], "given")
    assert not given.at_edge
