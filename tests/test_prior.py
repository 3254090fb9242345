"""The pull toward the URDF chosen from the data (:mod:`pincal.identify.prior`) and the guard
(:mod:`pincal.identify.guard`), on seeded simulated truths.

- The evidence formula against an independent computation (the Gaussian marginal likelihood of
  a linear problem, integrated in closed form over the pulled unknowns).
- Noisier data choose a stronger pull.
- Socket data (two points 50 mm apart, 0.05 mm of hand noise): 15 rows from one placement give a
  model better than the nominal on another placement.
- A truth whose geometry IS the URDF: the guard refuses the fit (its validation is not reliably
  better) and exports the nominal geometry; ``force_fit`` exports the fit.
"""

from __future__ import annotations

import json
from dataclasses import replace
from functools import cache
from pathlib import Path

import numpy as np
import pytest

import pincal
from pincal.cli import main
from pincal.data.csv_writer import write_csv
from pincal.errors import DataError
from pincal.identify.prior import (
    WEIGHTS,
    _ridge_step,
    _ridge_steps,
    evidence_curve,
    log_evidence,
    parse_prior,
)
from pincal.identify.solver import PRIOR_WEIGHT, identifiable_set, register, set_up, solve
from pincal.simulation.truth import TrueRobot, points_truth, simulate_points

NOISE = 5e-5  # [m] 1σ per coordinate of where the hand holds the ball
DISTANCES = (("0", "1", 0.05),)
TRAIN_SOCKETS = np.array([[0.45, 0.0, 0.25], [0.45, 0.05, 0.25]])
TEST_SOCKETS = np.array([[0.30, -0.35, 0.10], [0.33, -0.31, 0.10]])


@cache
def _robot(name: str) -> pincal.Robot:
    return pincal.load_robot(name)


def _nominal_truth(name: str, seed: int) -> TrueRobot:
    """A socket truth whose geometry is the URDF's: only the ball on the flange is unknown."""
    truth = points_truth(_robot(name), seed)
    return replace(truth, x=np.zeros_like(truth.x))


def test_parse_prior_refuses_what_is_not_a_weight() -> None:
    assert parse_prior("auto") is None
    assert parse_prior("0.25") == 0.25
    for bad in ("0", "-1", "nan", "strong", "inf"):
        with pytest.raises(DataError):
            parse_prior(bad)


def test_log_evidence_is_the_gaussian_marginal_likelihood() -> None:
    """On position data the residuals are nearly linear in the unknowns: the formula's
    differences between weights match the closed-form Gaussian evidence ``N(r0 | 0, σ²(I +
    J_p J_pᵀ / w²))`` with the flat-prior unknowns projected out and σ² profiled, to 1 %."""
    robot = _robot("ur5")
    _, fit, _ = pincal.simulate(robot, 40, 1, seed=3, noise=1e-4)
    setup = set_up(robot, fit, "placements", instrument_T_base=None)
    start = register(setup)
    free = np.ones(setup.problem.n_params, bool)
    free[: setup.model.n_params] = False
    free[[0, 4, 9]] = True  # three geometric unknowns, pulled
    jac = setup.problem.jacobian(start, free) * setup.scale[free]
    res0 = setup.problem.residuals(start)
    pen = np.arange(free.sum()) < 3
    flat = jac[:, ~pen]
    proj = np.eye(len(res0)) - flat @ np.linalg.pinv(flat)  # the flat unknowns integrated out
    basis = np.linalg.svd(proj)[0][:, : len(res0) - flat.shape[1]]
    y, jp = basis.T @ res0, basis.T @ jac[:, pen]
    ours, direct = [], []
    for weight in (0.01, 0.1, 1.0):
        trial = replace(setup, prior_weight=weight)
        theta, _ = solve(trial, start, free)
        ours.append(log_evidence(trial, theta, free))
        cov = np.eye(len(y)) + jp @ jp.T / weight**2  # in units of σ²
        quad = float(y @ np.linalg.solve(cov, y))
        direct.append(-len(y) / 2 * np.log(quad) - np.linalg.slogdet(cov)[1] / 2)
    assert np.allclose(np.diff(ours), np.diff(direct), rtol=0.01, atol=0.05), (ours, direct)


@pytest.mark.parametrize("seed", range(4))
def test_one_eigendecomposition_gives_every_weights_step_and_determinant(seed: int) -> None:
    """The scan's steps from one eigendecomposition of the pulled block's Schur complement solve
    each weight's normal equations ``(G + w²P) s = -(g + w²Pδ)`` to a backward error of 1e-9, and
    its log determinants are each weight's own to 1e-9 relative, on Gram matrices of scales
    1e-6 to 1e6 with two pulled directions almost alike."""
    rng = np.random.default_rng(seed)
    jac = rng.standard_normal((50, 12)) * np.geomspace(1e-3, 1e3, 12)
    jac[:, 3] = jac[:, 4] + 1e-7 * rng.standard_normal(50)
    gram, grad = jac.T @ jac, rng.standard_normal(12)
    pen = np.arange(12) < 8
    delta = np.where(pen, rng.standard_normal(12), 0.0)
    weights = np.asarray(WEIGHTS)
    for w, (step, logdet) in zip(weights, _ridge_steps(gram, grad, pen, delta, weights)):
        normal, rhs = gram + w**2 * np.diag(pen.astype(float)), grad + w**2 * pen * delta
        size = np.linalg.norm(normal) * np.linalg.norm(step) + np.linalg.norm(rhs)
        assert np.linalg.norm(normal @ step + rhs) <= 1e-9 * size, w
        assert abs(logdet - _ridge_step(gram, grad, pen, delta, float(w))[1]) <= 1e-9 * abs(logdet), w


def test_the_linearised_curve_is_the_evidence_of_each_fit() -> None:
    """The scan's Gauss-Newton steps from the default pull's fit (where
    :func:`~pincal.identify.prior.choose_weight` starts) give each weight's evidence as the fit
    at that weight does, to 0.1 (nats) over the 17 weights, where neighbours differ by 10 or
    more: the choice is the one a fit per weight would make."""
    robot = _robot("panda")
    data = simulate_points(points_truth(robot, 1), TRAIN_SOCKETS, 60, NOISE, np.random.default_rng(2))
    setup = set_up(robot, data, "placements", point_distances=DISTANCES)
    start = register(setup)
    free = identifiable_set(setup, start).identifiable
    default = replace(setup, prior_weight=PRIOR_WEIGHT)
    curve = evidence_curve(default, solve(default, start, free)[0], free, WEIGHTS)
    for weight, linear in zip(WEIGHTS, curve):
        trial = replace(setup, prior_weight=weight)
        assert abs(linear - log_evidence(trial, solve(trial, start, free)[0], free)) <= 0.1, weight


@pytest.mark.parametrize("seed", [0, 2, 4])
def test_distance_data_are_pulled_as_the_points_they_come_from(seed: int) -> None:
    """On an exact URDF the evidence of position data picks the strongest pulls of the grid; the
    distances between the same points carry no more information, so they pick as strong a pull
    (within one step of the grid). Counting the N(N-1)/2 pairs as independent rows chose pulls
    up to 6 times weaker."""
    from pincal.simulation.truth import random_truth

    robot = _robot("ur5")
    true = random_truth(robot, seed, tool_distance=(0.05, 0.05))
    true = replace(true, x=np.zeros_like(true.x))
    q = robot.random_configurations(30, np.random.default_rng(seed), 0.05)
    data = true.measure(q, NOISE, seed=seed + 7)
    weights = {}
    for measure in ("position", "distance"):
        cal = pincal.calibrate(robot, data, measure=measure, params="all", extension="none")
        assert cal.prior is not None and cal.prior.chosen_by == "evidence"
        weights[measure] = cal.prior.weight
    step = WEIGHTS[1] / WEIGHTS[0]
    assert weights["distance"] >= weights["position"] / step * (1 - 1e-9), weights


def test_noisier_data_choose_a_stronger_pull() -> None:
    """The same poses and truth, 20x the noise: the chosen weight (noise / expected correction)
    rises by at least 4x."""
    robot = _robot("panda")
    truth = points_truth(robot, 2)
    chosen = []
    for noise in (2e-5, 4e-4):
        data = simulate_points(truth, TRAIN_SOCKETS, 60, noise, np.random.default_rng(5))
        cal = pincal.calibrate(robot, data, "placements", point_distances=DISTANCES)
        assert cal.prior is not None and cal.prior.chosen_by == "evidence"
        assert cal.prior.weight in WEIGHTS
        chosen.append(cal.prior.weight)
    assert chosen[1] >= 4 * chosen[0], chosen


@pytest.mark.parametrize("name", ["panda", "ur5"])
@pytest.mark.parametrize("seed", [0, 1])
def test_fifteen_rows_of_one_placement_beat_the_nominal_elsewhere(name: str, seed: int) -> None:
    """15 rows at one placement of the two sockets: on another placement (60 rows), the model
    is better than the nominal geometry with the same fitted ball (and than the URDF as is)."""
    robot = _robot(name)
    truth = points_truth(robot, seed)
    fit = simulate_points(truth, TRAIN_SOCKETS, 15, NOISE, np.random.default_rng(seed + 1))
    test = simulate_points(truth, TEST_SOCKETS, 60, NOISE, np.random.default_rng(seed + 2))
    cal = pincal.calibrate(robot, fit, "placements", point_distances=DISTANCES, test=test)
    assert cal.test_after is not None and cal.test_before is not None and cal.test_urdf is not None
    assert cal.test_after.point_mae_mm is not None and cal.test_before.point_mae_mm is not None
    assert cal.test_after.point_mae_mm < cal.test_before.point_mae_mm
    assert cal.test_after.rms_mm < min(cal.test_before.rms_mm, cal.test_urdf.rms_mm)


@pytest.mark.parametrize("name", ["panda", "ur5"])
def test_guard_exports_the_nominal_geometry_when_the_urdf_is_true(name: str) -> None:
    """The truth's geometry is the URDF's: the fit is not reliably better on its own validation,
    so the exported θ is the nominal one (geometry untouched, ball and sockets fitted), and the
    summary says so; ``force_fit`` exports the fit."""
    robot = _robot(name)
    truth = _nominal_truth(name, 0)
    data = simulate_points(truth, TRAIN_SOCKETS, 60, NOISE, np.random.default_rng(1))
    cal = pincal.calibrate(robot, data, "placements", point_distances=DISTANCES)
    assert cal.guard is not None and not cal.guard.reliable and not cal.guard.kept_fit
    assert np.array_equal(cal.theta, cal.nominal_theta)
    assert np.all(cal.x[: cal.model.n_params] == 0.0)
    assert "do not support a calibration better than the nominal" in pincal.summary(cal, data)
    report = pincal.report_dict(cal)
    assert report["guard"]["exported"] == "nominal" and report["prior"]["chosen_by"] == "evidence"
    pull = pincal.Pull(force_fit=True)
    forced = pincal.calibrate(robot, data, "placements", point_distances=DISTANCES, pull=pull)
    assert forced.guard is not None and forced.guard.kept_fit and forced.guard.forced
    assert not np.array_equal(forced.theta, forced.nominal_theta)


def test_guard_keeps_a_fit_of_position_data_with_real_errors() -> None:
    """Position data of a robot with 0.5 mm / 0.5 mrad errors: reliably better, the fit kept,
    and a weight given is used and said so."""
    robot = _robot("ur5")
    _, fit, _ = pincal.simulate(robot, 60, 1, seed=4)
    cal = pincal.calibrate(robot, fit, "placements", pull=pincal.Pull(0.02))
    assert cal.prior is not None and cal.prior.weight == 0.02 and cal.prior.chosen_by == "given"
    assert cal.guard is not None and cal.guard.reliable and cal.guard.kept_fit
    assert cal.guard.fit_cv_rms_mm < cal.guard.nominal_cv_rms_mm


def test_cli_prior_and_force_fit(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--prior W`` reaches the report; a bad ``--prior`` is one error line, exit 2."""
    robot = _robot("ur5")
    _, fit, _ = pincal.simulate(robot, 40, 1, seed=5)
    csv = tmp_path / "fit.csv"
    write_csv(csv, fit)
    report = tmp_path / "r.json"
    args = ["calibrate", "ur5", str(csv), "--prior", "0.05", "--force-fit", "--report", str(report)]
    assert main(args) == 0
    saved = json.loads(report.read_text())
    assert saved["prior"]["weight"] == 0.05 and saved["prior"]["chosen_by"] == "given"
    assert saved["guard"]["forced"] is True
    capsys.readouterr()
    assert main(["calibrate", "ur5", str(csv), "--prior", "strong"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("pincal: error: prior=")
