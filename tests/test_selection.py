"""Tests of :mod:`pincal.auto.selection`: forward selection of model parameters by cross-validation.

- Sparse truth: a simulated UR5 whose URDF is wrong in only three joint-placement parameters
  (1 mm or 2 mrad each), unknown instrument pose and reflector, 0.03 mm noise, 40 fitted poses.
  The selection chooses at most six parameters whose Jacobian columns span the three wrong ones
  (a UR's parallel axes make some parameters exact equivalents of others, so the names
  themselves may differ), its cross-validated RMS falls to the noise floor, and on 60 new poses
  the chosen model predicts no worse than fitting every identifiable parameter.
- The closed-form (linearised) leave-one-out RMS equals the nonlinear one of
  :func:`pincal.auto.crossval.cross_validate` refitting each fold, within 2 %, for position and distance data.
- Only the data given is used: leave-one-out selection does not depend on the order of the
  poses, and in :func:`cross_validate_selection` corrupting one fold's held-out poses leaves
  that fold's chosen set unchanged.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pytest

import pincal
from pincal.auto.selection import cross_validate_selection
from pincal.identify.folds import fold_indices, held_out_rows
from pincal.identify.forward_selection import Selection, select_parameters
from pincal.identify.solver import set_up
from pincal.kinematics.models import PlacementsModel
from pincal.simulation.truth import TrueRobot, points_truth, simulate_points

NOISE = 3e-5  # 1σ of each measured coordinate [m]
NOISE_FLOOR_MM = NOISE * 1e3 * np.sqrt(3.0)  # RMS of a 3-D noise vector [mm]
N_FIT, N_TEST, N_WRONG = 40, 60, 3
SPAN_TOL = 1e-6  # relative residual of a true column projected on the chosen ones


def sparse_experiment(robot: pincal.Robot, seed: int) -> tuple[list[str], pincal.Dataset, pincal.Dataset]:
    """A truth wrong in ``N_WRONG`` identifiable placement parameters; its fit and test data."""
    rng = np.random.default_rng(seed)
    q = robot.random_configurations(N_FIT + N_TEST, rng, margin=0.05)
    base = pincal.random_truth(robot, seed)
    model = PlacementsModel(robot)
    nominal = TrueRobot(model, np.zeros(model.n_params), base.instrument_T_base, base.tool)
    probe = pincal.calibrate(robot, nominal.measure(q[:N_FIT], NOISE, seed=seed), "placements")
    mask = probe.identifiability.identifiable[: model.n_params]
    wrong = sorted(str(n) for n in rng.choice(np.array(model.names)[mask], N_WRONG, replace=False))
    x = np.zeros(model.n_params)
    for name in wrong:
        k = model.names.index(name)
        x[k] = rng.choice([-1.0, 1.0]) * (1e-3 if model.units[k] == "m" else 2e-3)
    truth = TrueRobot(model, x, base.instrument_T_base, base.tool)
    return (
        wrong,
        truth.measure(q[:N_FIT], NOISE, seed=seed + 1),
        truth.measure(q[N_FIT:], NOISE, seed=seed + 2),
    )


def unexplained(
    robot: pincal.Robot, data: pincal.Dataset, chosen: tuple[str, ...], wanted: list[str]
) -> float:
    """Largest relative residual of the ``wanted`` Jacobian columns projected on the span of the
    ``chosen`` ones and the registration and tool columns (0: the chosen set spans them)."""
    start = pincal.calibrate(robot, data, "placements", params=[])
    jac = start.problem(data).jacobian(start.theta)
    names = list(start.names)
    basis = [names.index(n) for n in chosen] + list(range(start.model.n_params, len(names)))
    q, _ = np.linalg.qr(jac[:, basis])
    worst = 0.0
    for name in wanted:
        col = jac[:, names.index(name)]
        worst = max(worst, float(np.linalg.norm(col - q @ (q.T @ col)) / np.linalg.norm(col)))
    return worst


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_sparse_truth_is_found(get_robot: Callable[[str], pincal.Robot], seed: int) -> None:
    robot = get_robot("ur5")
    wrong, fit, test = sparse_experiment(robot, seed)
    sel = select_parameters(robot, fit, "placements")
    assert isinstance(sel, Selection)
    assert len(sel.chosen) <= N_WRONG + 3, sel.chosen
    assert unexplained(robot, fit, sel.chosen, wrong) < SPAN_TOL, (wrong, sel.chosen)
    assert sel.path[0].cv_rms_mm > 3 * NOISE_FLOOR_MM  # the errors are visible at the start
    assert sel.cv_rms_mm < 1.25 * NOISE_FLOOR_MM
    assert [s.added for s in sel.path[1 : len(sel.chosen) + 1]] == list(sel.chosen)
    chosen = pincal.calibrate(robot, fit, "placements", params=list(sel.chosen), test=test)
    full = pincal.calibrate(robot, fit, "placements", test=test)
    assert chosen.test_after is not None and full.test_after is not None
    assert chosen.test_after.rms_mm <= 1.05 * full.test_after.rms_mm
    assert chosen.test_after.rms_mm < 1.25 * NOISE_FLOOR_MM


def test_linearised_leave_one_out_matches_refits(get_robot: Callable[[str], pincal.Robot]) -> None:
    robot = get_robot("ur5")
    _, fit, _ = sparse_experiment(robot, 3)
    sel = select_parameters(robot, fit, "placements", max_params=6)
    cv = pincal.auto.crossval.cross_validate(
        robot, fit, "placements", folds=len(fit), params=list(sel.chosen)
    )
    assert cv.after.rms_mm == pytest.approx(sel.cv_rms_mm, rel=0.02)
    assert len(sel.path) == 7  # max_params ends the path


def test_distance_data_kfold_matches_refits() -> None:
    data, _ = pincal.gao2013_data()
    robot = pincal.load_robot("mrres5")
    sel = select_parameters(robot, data, "poe", "distance", folds=7, seed=0)
    assert 0 < len(sel.chosen) < len(sel.path) - 1
    assert sel.cv_rms_mm < sel.path[0].cv_rms_mm
    cv = pincal.auto.crossval.cross_validate(
        robot, data, "poe", "distance", folds=7, seed=0, params=list(sel.chosen)
    )
    assert cv.after.rms_mm == pytest.approx(sel.cv_rms_mm, rel=0.02)
    assert sel.to_dict()["chosen"] == list(sel.chosen)


def test_pose_data(get_robot: Callable[[str], pincal.Robot]) -> None:
    robot = get_robot("ur5")
    _, fit, _ = pincal.simulate(robot, n_fit=30, n_test=0, seed=4, rot_noise=1e-4)
    sel = select_parameters(robot, fit, "placements", folds=5)
    assert sel.folds == 5 and sel.chosen
    assert sel.cv_rms_mm < 0.2 * sel.path[0].cv_rms_mm


def test_order_of_poses_does_not_matter(get_robot: Callable[[str], pincal.Robot]) -> None:
    robot = get_robot("ur5")
    _, fit, _ = sparse_experiment(robot, 4)
    order = np.random.default_rng(0).permutation(len(fit))
    a = select_parameters(robot, fit, "placements")
    b = select_parameters(robot, fit.subset(order), "placements")
    assert a.chosen == b.chosen
    assert [s.cv_rms_mm for s in a.path] == pytest.approx([s.cv_rms_mm for s in b.path], rel=1e-6)


def test_held_out_fold_is_never_seen(get_robot: Callable[[str], pincal.Robot]) -> None:
    robot = get_robot("ur5")
    _, fit, _ = sparse_experiment(robot, 5)
    folds = 4
    clean = cross_validate_selection(robot, fit, "placements", folds=folds, seed=1)
    held = fold_indices(len(fit), folds, 1)[0]
    points = fit.points.copy()
    points[held] += np.random.default_rng(2).normal(0.0, 5e-3, (len(held), 3))  # 5 mm of garbage
    dirty = cross_validate_selection(robot, replace(fit, points=points), "placements", folds=folds, seed=1)
    assert dirty.chosen[0] == clean.chosen[0]  # fold 0 fits only the untouched poses
    assert dirty.after.rms_mm > clean.after.rms_mm  # ... and is judged on the corrupted ones
    assert len(clean.chosen) == folds and clean.after.n == len(fit)


@pytest.mark.parametrize("folds", [None, 5])
def test_held_out_rows_are_each_poses_rows_and_no_others(folds: int | None) -> None:
    """Every residual row of a pose is in that pose's group (its fold's), no row is in two
    groups, and a known distance's row (fixed points) is in none: it is never held out."""
    robot = pincal.load_robot("ur5")
    truth = points_truth(robot, 3)
    sockets = np.array([[0.45, 0.0, 0.25], [0.45, 0.05, 0.25]])  # [m]
    data = simulate_points(truth, sockets, 30, 5e-5, np.random.default_rng(0))
    problem = set_up(robot, data, "placements", point_distances=(("0", "1", 0.05),)).problem
    poses = problem.row_poses()
    groups = held_out_rows(problem, folds, 0)
    held = [np.array([i]) for i in range(len(data))] if folds is None else fold_indices(len(data), folds, 0)
    assert len(groups) == len(held)
    for rows, h in zip(groups, held):
        np.testing.assert_array_equal(rows, np.flatnonzero(np.isin(poses, h)))
    assert np.all(poses[np.concatenate(groups)] >= 0)
    assert len(np.concatenate(groups)) == np.count_nonzero(poses >= 0) < len(poses)
