"""The guard sees extrapolation: a fit on poses in a small part of each joint's range that passes
the guard on its own poses, but is worse than the nominal model across the joint limits, is
refused (the nominal geometry exported) unless forced; a fit of a real error over the whole
range is still exported; the report and the summary say which joint ranges the data cover.
Distance data are checked on the distances between configurations across the limits, pose data
with their orientation rows."""

from __future__ import annotations

from dataclasses import replace
from functools import cache

import numpy as np
import pytest

import pincal
from pincal.data.dataset import Dataset
from pincal.identify import extrapolation, uncertainty
from pincal.identify.chunked import normal_terms
from pincal.identify.extrapolation import Posterior, expected_gain
from pincal.identify.measurements import Problem
from pincal.identify.prior import WEIGHTS
from pincal.identify.solver import set_up
from pincal.identify.uncertainty import carried_to_points, whitened_pair_terms
from pincal.identify.validity import Z_SPREAD, Z_SPREAD_PAIRS

NOISE = 5e-5  # per axis [m]
NARROW = 0.47  # margin of each range left out at both ends: poses in the central 6 %
#: Seeds whose narrow-range fit on an exact URDF passes the guard on its own poses (the guard's
#: own false exports, a few per hundred sessions): the cases the extrapolation check is for.
PASSING_SEEDS = (44, 68, 143)
#: Seeds whose fit of the distances between 30 poses over the whole range of an exact URDF passes
#: the guard and predicts new poses' distances worse than the nominal model.
DISTANCE_SEEDS = (10, 13)
#: A seed whose distance fit of an exact URDF (7.8 % worse on new poses) passed the guard and the
#: check while the check's posterior stopped at the top of the pull's grid.
BEYOND_GRID_SEED = 25
#: A seed whose fit of every parameter to the distances between 15 poses of an exact URDF passes
#: the guard's null (z 4.38 against 3.85) and is 16 % worse on new poses: a posterior that counted
#: the pairs as independent rows expected it to gain (2.9 standard deviations).
PAIRED_NOISE_SEED = 84
WORSE = 1.05


@cache
def _robot() -> pincal.Robot:
    return pincal.load_robot("ur5")


def _session(seed: int, exact: bool, margin: float, poses: int = 30) -> tuple[Dataset, Dataset]:
    """``poses`` fitted poses within ``margin`` of each range and 200 new poses over the whole range."""
    robot = _robot()
    true = pincal.random_truth(robot, seed, tool_distance=(0.05, 0.05))
    if exact:
        true = replace(true, x=np.zeros_like(true.x))
    rng = np.random.default_rng([seed, poses, 1])
    q_fit = robot.random_configurations(poses, rng, margin)
    q_new = robot.random_configurations(200, rng, 0.0)
    return true.measure(q_fit, NOISE, seed=seed + 7), true.measure(q_new, NOISE, seed=seed + 8)


@cache
def _calibrations(
    seed: int, exact: bool, margin: float, measure: str = "position"
) -> tuple[pincal.Calibration, pincal.Calibration]:
    """The default call and the forced one."""
    fit, new = _session(seed, exact, margin)
    options = dict(measure=measure, params="auto", test=new)
    default = pincal.calibrate(_robot(), fit, **options)
    forced = pincal.calibrate(_robot(), fit, **options, pull=pincal.Pull(force_fit=True))
    return default, forced


@pytest.mark.parametrize("seed", PASSING_SEEDS)
def test_narrow_range_fit_of_an_exact_urdf_is_refused(seed: int) -> None:
    default, forced = _calibrations(seed, True, NARROW)
    assert forced.guard is not None and default.guard is not None
    assert forced.guard.reliable, "the guard alone exports this fit: the case the check is for"
    assert forced.test_after is not None and forced.test_before is not None
    assert forced.test_after.rms_mm > WORSE * forced.test_before.rms_mm, "the fit is worse across the range"
    assert not default.guard.kept_fit
    assert default.guard.extrapolation is not None and not default.guard.extrapolation.holds
    np.testing.assert_array_equal(default.theta, default.nominal_theta)  # the nominal geometry


@pytest.mark.parametrize("seed", DISTANCE_SEEDS)
def test_distance_fit_worse_across_the_limits_is_refused(seed: int) -> None:
    default, forced = _calibrations(seed, True, 0.05, "distance")
    assert forced.guard is not None and default.guard is not None
    assert forced.guard.reliable, "the guard alone exports this fit: the case the check is for"
    assert forced.test_after is not None and forced.test_before is not None
    assert forced.test_after.rms_mm > WORSE * forced.test_before.rms_mm, "the distances are worse"
    assert default.guard.extrapolation is not None and not default.guard.extrapolation.holds
    assert not default.guard.kept_fit
    np.testing.assert_array_equal(default.theta, default.nominal_theta)


def test_a_fit_of_the_pairs_noise_is_refused_across_the_limits() -> None:
    """Every parameter fitted to the distances of 15 poses of an exact URDF: the guard's null
    passes the fit of the noise; the posterior of the whitened pairs does not expect it to gain."""
    fit, new = _session(PAIRED_NOISE_SEED, True, 0.05, poses=15)
    options = dict(measure="distance", params=None, test=new)
    default = pincal.calibrate(_robot(), fit, **options)
    forced = pincal.calibrate(_robot(), fit, **options, pull=pincal.Pull(force_fit=True))
    assert forced.guard is not None and forced.guard.reliable, "the guard alone exports this fit"
    assert forced.test_after is not None and forced.test_before is not None
    assert forced.test_after.rms_mm > WORSE * forced.test_before.rms_mm, "the distances are worse"
    assert default.guard is not None and default.guard.extrapolation is not None
    assert not default.guard.extrapolation.holds and not default.guard.kept_fit
    assert default.guard.extrapolation.z_min == Z_SPREAD_PAIRS < Z_SPREAD
    assert default.guard.extrapolation.text().endswith("outside the data by 1 standard deviation")
    np.testing.assert_array_equal(default.theta, default.nominal_theta)


def test_the_whitened_pairs_are_generalised_least_squares() -> None:
    """The pairs' terms whitened by the pseudo-inverse of their covariance ``A Aᵀ`` (formed here
    from ``A`` itself, one row per pair) equal those formed in the points' coordinates."""
    problem, theta = _problem("distance")
    free = np.ones(problem.n_params, dtype=bool)
    terms = whitened_pair_terms(problem, theta, free)
    assert terms is not None
    jac, res = problem.jacobian(theta, free), problem.residuals(theta)
    carry = carried_to_points(problem, np.eye(len(res))).T  # A (pairs, 3N)
    inverse = np.linalg.pinv(carry @ carry.T, rcond=1e-9, hermitian=True)
    np.testing.assert_allclose(terms[0], jac.T @ inverse @ jac, rtol=1e-6, atol=1e-9 * np.abs(terms[0]).max())
    np.testing.assert_allclose(terms[1], jac.T @ inverse @ res, rtol=1e-6, atol=1e-9 * np.abs(terms[1]).max())
    assert terms[2] == pytest.approx(float(res @ inverse @ res), rel=1e-6)
    assert terms[3] == np.linalg.matrix_rank(carry) == 3 * len(problem.data) - 6


def test_the_posterior_takes_its_weight_beyond_the_pulls_grid() -> None:
    """The data of an exact URDF give the strongest pull of the grid the largest evidence; the
    check's posterior takes the largest evidence beyond it, where its mean is the nominal model,
    and refuses the fit of the noise that a posterior held at the grid's top passed."""
    default, forced = _calibrations(BEYOND_GRID_SEED, True, 0.05, "distance")
    assert forced.guard is not None and forced.guard.reliable
    assert forced.test_after is not None and forced.test_before is not None
    assert forced.test_after.rms_mm > WORSE * forced.test_before.rms_mm
    beyond = default.guard.extrapolation if default.guard is not None else None
    assert beyond is not None and beyond.weight > WEIGHTS[-1] and not beyond.holds
    assert not default.guard.kept_fit


@pytest.mark.parametrize("measure", ["distance", "pose"])
def test_whole_range_fit_of_a_real_error_is_checked_and_exported(measure: str) -> None:
    fit, new = _session(0, False, 0.05)
    if measure == "pose":
        true = pincal.random_truth(_robot(), 0, tool_distance=(0.05, 0.05))
        fit = true.measure(fit.q, NOISE, NOISE, seed=7)
        new = true.measure(new.q, NOISE, NOISE, seed=8)
    cal = pincal.calibrate(_robot(), fit, measure=measure, params="auto", test=new)
    assert cal.guard is not None and cal.guard.kept_fit
    beyond = cal.guard.extrapolation
    assert beyond is not None and beyond.holds and beyond.whole_gain_mm2 > 0
    assert cal.test_after is not None and cal.test_before is not None
    assert cal.test_after.rms_mm < cal.test_before.rms_mm


@pytest.mark.parametrize("seed", PASSING_SEEDS[:1])
def test_force_fit_exports_the_narrow_fit(seed: int) -> None:
    default, forced = _calibrations(seed, True, NARROW)
    assert forced.guard is not None and forced.guard.kept_fit and forced.guard.forced
    assert forced.guard.extrapolation is not None and not forced.guard.extrapolation.holds
    assert not np.array_equal(forced.theta, forced.nominal_theta)
    assert "exported anyway" in forced.guard.text()


@pytest.mark.parametrize("seed", (0, 1))
def test_whole_range_fit_of_a_real_error_is_exported(seed: int) -> None:
    fit, new = _session(seed, False, 0.05)
    cal = pincal.calibrate(_robot(), fit, params="auto", test=new)
    assert cal.guard is not None and cal.guard.kept_fit
    assert cal.guard.extrapolation is not None and cal.guard.extrapolation.holds
    assert cal.test_after is not None and cal.test_before is not None
    assert cal.test_after.rms_mm < cal.test_before.rms_mm
    assert pincal.report_dict(cal, fit, new)["validity_region"]["narrower_than_limits"] == []


def test_the_report_says_what_was_refused_and_where_the_data_are() -> None:
    seed = PASSING_SEEDS[0]
    default, _ = _calibrations(seed, True, NARROW)
    fit, new = _session(seed, True, NARROW)
    report = pincal.report_dict(default, fit, new)
    assert report["guard"]["exported"] == "nominal"
    assert report["guard"]["extrapolation"]["holds"] is False
    assert report["guard"]["extrapolation"]["threshold_sd"] == Z_SPREAD
    region = report["validity_region"]
    q = fit.q
    for j, entry in enumerate(region["joints"]):
        assert entry["min"] == pytest.approx(q[:, j].min()) and entry["max"] == pytest.approx(q[:, j].max())
    assert region["narrower_than_limits"] == list(_robot().joint_names)
    text = pincal.summary(default, fit, new)
    assert "holds for joint ranges" in text and "not across the joint limits" in text


def _problem(measure: str) -> tuple[Problem, np.ndarray]:
    """A problem of 10 simulated poses and a θ near its start."""
    robot = _robot()
    rng = np.random.default_rng(4)
    true = pincal.random_truth(robot, 4, tool_distance=(0.05, 0.05))
    turn = NOISE if measure == "pose" else None
    data = true.measure(robot.random_configurations(10, rng), NOISE, turn, seed=5)
    problem = set_up(robot, data, "placements", measure).problem
    return problem, problem.initial_theta() + rng.normal(0.0, 1e-3, problem.n_params)


@pytest.mark.parametrize(("measure", "rows"), [("position", 3 * 7), ("pose", 6 * 7), ("distance", 21)])
def test_the_rows_drawn_across_the_limits_measure_what_theta_predicts(measure: str, rows: int) -> None:
    problem, theta = _problem(measure)
    q = _robot().random_configurations(7, np.random.default_rng(6))
    sampled = problem.measuring(theta, q)
    assert sampled.residuals(theta).shape == (rows,)
    np.testing.assert_allclose(sampled.residuals(theta), 0.0, atol=1e-12)
    other = theta + np.random.default_rng(7).normal(0.0, 1e-4, len(theta))
    moved = problem.measuring(other, q).residuals(theta)
    np.testing.assert_allclose(moved, -sampled.residuals(other), atol=1e-9)


def test_pose_data_count_the_orientation_across_the_limits() -> None:
    problem, nominal = _problem("pose")
    turned = nominal.copy()
    turned[problem.names.index("tool.rx")] += 1e-3  # the tool's orientation alone [rad]
    every = np.ones(len(nominal), dtype=bool)
    post = Posterior(nominal, turned, 1.0, every, np.zeros((len(nominal), len(nominal))))
    q = _robot().random_configurations(9, np.random.default_rng(8))
    gain, spread = expected_gain(problem, turned, post, q, spread=True)
    weight = problem.measurement.rotation_weight  # [m/rad]
    assert gain == pytest.approx((weight * 1e-3) ** 2, rel=1e-6)  # the rotation rows' whole gain
    assert spread == 0.0


def test_above_the_whitened_size_the_pairs_count_by_their_effective_number(monkeypatch) -> None:
    """Past :data:`WHITENED_POINTS` the posterior's terms are the plain ones with every row scaled
    by ``n_eff / n``: the pairs count for at most ``3N - 6`` rows."""
    problem, theta = _problem("distance")
    free = np.ones(problem.n_params, dtype=bool)
    plain = normal_terms(problem, theta, free)
    monkeypatch.setattr(uncertainty, "WHITENED_POINTS", 0)
    gram, grad, rr, rows = extrapolation._terms(problem, theta, free)
    counted = 3 * len(problem.data) - 6
    assert plain[3] > counted == rows
    scale = counted / plain[3]
    np.testing.assert_allclose(gram, scale * plain[0])
    np.testing.assert_allclose(grad, scale * plain[1])
    assert rr == pytest.approx(scale * plain[2])
