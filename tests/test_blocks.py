"""A million rows by blocks: each path that sums over rows block by block gives what the
computation on every row at once gives (within 1e-10 relative), on small problems cut into tiny
blocks (:mod:`pincal.identify.chunked`'s sizes lowered), so that a block's offset, its folds or
its rows' kinds taken wrong would show:

- the linearised screen of candidate effects (:class:`pincal.auto.screening.Linearised`) against
  its definition: each fold's least-squares step on the other folds' rows of ``[J E]``, its
  held-out poses' position errors;
- the standard deviations of a pose fit (:func:`pincal.identify.uncertainty.pose_std`) against
  ``M Jᵀ D J M`` with each row's hat-matrix diagonal;
- ``pincal tcp``'s leave-one-out distances and TCP standard deviation against a refit without
  each pose and the ``(3n, 3n)`` matrix ``D Dᵀ``;
- gravity torques from vectorised configurations against Pinocchio's call per pose, and the
  torques kept by blocks are bounded by rows.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from scipy.spatial.transform import Rotation

import pincal
import pincal.auto.fitting
import pincal.identify.guard
import pincal.identify.uncertainty
from pincal.auto.screening import Linearised
from pincal.identify import chunked
from pincal.identify.folds import pose_folds
from pincal.identify.measurements import Problem
from pincal.identify.solver import identifiable_set, set_up, solve
from pincal.identify.uncertainty import pose_std, row_sums
from pincal.kinematics import gravity
from pincal.kinematics.effects import Extension, combined
from pincal.simulation.truth import hide_effect
from pincal.tool.tcp import _differences, _leave_one_out, _tcp_std

RTOL = 1e-10
EFFECTS = (
    "joint_compliance:shoulder_lift_joint",
    "encoder_scale:wrist_2_joint",
    "gear_harmonic2:elbow_joint",
)


def _tiny_blocks(monkeypatch: pytest.MonkeyPatch) -> None:
    """Problems above 10 poses work in blocks of 7 (poses split unevenly across blocks), and
    none may ask for the Jacobian of all its poses at once."""
    monkeypatch.setattr(chunked, "LARGE_POSES", 10)
    monkeypatch.setattr(chunked, "BLOCK_POSES", 7)
    whole = chunked.evaluate

    def residuals_only(
        problem: Problem, theta: np.ndarray, cols: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        assert cols is None, "the Jacobian of every pose at once"
        return whole(problem, theta, cols)

    monkeypatch.setattr(chunked, "evaluate", residuals_only)


def _poses_per_call(
    monkeypatch: pytest.MonkeyPatch, where: list[tuple[object, str]], poses: Callable[[Any], int]
) -> list[int]:
    """The number of poses (``poses`` of the first argument) of each call of the function named
    in every ``(module, name)`` of ``where`` (one function, imported under each), recorded as
    the calls are made."""
    seen: list[int] = []
    module, name = where[0]
    original = getattr(module, name)

    def counted(first: Any, *args: Any, **kwargs: Any) -> Any:
        seen.append(poses(first))
        return original(first, *args, **kwargs)

    for module, name in where:
        monkeypatch.setattr(module, name, counted)
    return seen


def _fitted(robot: pincal.Robot, rot_noise: float) -> tuple[pincal.Calibration, pincal.Dataset]:
    truth, fit, _ = pincal.simulate(robot, n_fit=45, n_test=0, seed=3, rot_noise=rot_noise)
    hidden = Extension.parse(robot, EFFECTS[0])
    truth = hide_effect(truth, hidden, fit.q, 4e-4, seed=3)
    fit = truth.measure(fit.q, 3e-5, 5e-4 if rot_noise else None, seed=5)
    return pincal.calibrate(robot, fit), fit


def _screen_by_rows(base: pincal.Calibration, data: pincal.Dataset, ext: Extension) -> tuple[float, float]:
    """The linearised cross-validated RMS [mm] and all-row residual sum [m²], row by row."""
    n_model = base.model.n_params
    both = combined([ext])
    theta = np.concatenate([base.theta[:n_model], np.zeros(ext.n_params), base.theta[n_model:]])
    free = np.flatnonzero(base.identifiability.identifiable)
    cols = np.concatenate(
        [np.where(free < n_model, free, free + ext.n_params), n_model + np.arange(ext.n_params)]
    )
    problem = Problem(base.model, base.measurement, data, both)
    res, jac = problem.rows(theta, cols)
    width = base.measurement.measure.width
    pose = np.arange(len(res)) // width

    def step(rows: np.ndarray) -> np.ndarray:
        return -np.linalg.lstsq(jac[rows], res[rows], rcond=None)[0]

    errors = []
    for held in pose_folds(data, 5, 0):
        test = np.isin(pose, held)
        predicted = (res + jac @ step(~test))[test].reshape(-1, width)[:, :3]
        errors.append(np.sum(predicted**2, axis=1))
    rss = float(np.sum((res + jac @ step(np.ones(len(res), bool))) ** 2))
    return float(np.sqrt(np.mean(np.concatenate(errors)))) * 1e3, rss


@pytest.mark.parametrize("rot_noise", [0.0, 5e-4])
def test_linearised_screen_by_blocks_is_the_screen_by_rows(
    get_robot: Callable[[str], pincal.Robot], monkeypatch: pytest.MonkeyPatch, rot_noise: float
) -> None:
    robot = get_robot("ur5")
    base, data = _fitted(robot, rot_noise)
    pool = [Extension.parse(robot, label) for label in EFFECTS]
    whole = Linearised(base, data, 5, 0, pool)
    by_rows = {ext.label: _screen_by_rows(base, data, ext) for ext in pool}
    _tiny_blocks(monkeypatch)
    blocked = Linearised(base, data, 5, 0, pool)
    alone = Linearised(base, data, 5, 0)  # each effect's columns in a pass of its own
    assert blocked.large and not whole.large
    for ext in pool:
        cv, rss = by_rows[ext.label]
        for lin in (whole, blocked, alone):
            screen = lin.screen(ext)
            assert screen.cv_rms_mm == pytest.approx(cv, rel=RTOL)
            assert screen.rss == pytest.approx(rss, rel=RTOL)
        assert np.allclose(blocked.screen(ext).params, whole.screen(ext).params, rtol=RTOL, atol=0)
    assert blocked.screen().cv_rms_mm == pytest.approx(whole.screen().cv_rms_mm, rel=RTOL)
    assert np.array_equal(blocked.residuals, whole.residuals)


def _pose_std_by_rows(
    problem: Problem, scale: np.ndarray, weight: float, theta: np.ndarray, free: np.ndarray
) -> np.ndarray:
    """``M Jᵀ D J M`` with the hat matrix's diagonal row by row."""
    jac, res = problem.jacobian(theta, free) * scale[free], problem.residuals(theta)
    pen = np.arange(int(free.sum())) < int(free[: problem.model.n_params].sum())
    inverse = np.linalg.pinv(jac.T @ jac + weight**2 * np.diag(pen.astype(float)))
    left = 1.0 - np.einsum("ij,jk,ik->i", jac, inverse, jac)
    turned = np.arange(len(res)) % 6 >= 3
    variance = np.where(
        turned,
        res[turned] @ res[turned] / left[turned].sum(),
        res[~turned] @ res[~turned] / left[~turned].sum(),
    )
    cov = inverse @ (jac.T @ (jac * variance[:, None])) @ inverse
    out = np.zeros(problem.n_params)
    out[free] = np.sqrt(np.diag(cov)) * scale[free]
    return out


def test_pose_std_by_blocks_is_the_std_by_rows(
    get_robot: Callable[[str], pincal.Robot], monkeypatch: pytest.MonkeyPatch
) -> None:
    base, data = _fitted(get_robot("ur5"), 5e-4)
    free, theta = base.identifiability.identifiable, base.theta
    scale = np.random.default_rng(0).uniform(0.5, 2.0, len(theta))
    want = _pose_std_by_rows(base.problem(data), scale, 0.3, theta, free)
    _tiny_blocks(monkeypatch)
    problem = base.problem(data)
    assert chunked.is_large(problem) and want[free].min() > 0
    assert np.allclose(
        pose_std(problem, scale, 0.3, free, row_sums(problem, theta, free)), want, rtol=RTOL, atol=0
    )


def _flange_poses(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    rotations = Rotation.from_rotvec(rng.normal(scale=0.5, size=(n, 3))).as_matrix()
    positions = np.array([0.5, 0.1, 0.2]) - rotations @ np.array([0.01, -0.02, 0.15])
    positions += rng.normal(scale=1e-4, size=(n, 3))
    positions[n // 2] += 3e-3  # one pose badly taught
    return rotations, positions


@pytest.mark.parametrize("n", [4, 6, 13])
def test_tcp_leave_one_out_and_std_are_the_refits(n: int) -> None:
    rotations, positions = _flange_poses(n, n)
    tcp = np.linalg.lstsq(*_differences(rotations, positions), rcond=None)[0]
    points = rotations @ tcp + positions
    distances, scatters = np.empty(n), np.empty(n)
    for i in range(n):  # the fit without pose i, as eq. 6-9 reads
        keep = np.arange(n) != i
        t = np.linalg.lstsq(*_differences(rotations[keep], positions[keep]), rcond=None)[0]
        kept = rotations[keep] @ t + positions[keep]
        distances[i] = np.linalg.norm(rotations[i] @ t + positions[i] - kept.mean(axis=0))
        scatters[i] = np.sqrt(np.sum((kept - kept.mean(axis=0)) ** 2) / max(1, 3 * (n - 1) - 6))
    found, suspects = _leave_one_out(rotations, positions, tcp)
    assert np.allclose(found, distances, rtol=RTOL, atol=0)
    assert np.array_equal(suspects, (distances > 6.0 * scatters) if n >= 5 else np.zeros(n, bool))
    diff = np.eye(n - 1, n, 1) - np.eye(n - 1, n)
    pinv = np.linalg.pinv(_differences(rotations, positions)[0])
    scatter = points - points.mean(axis=0)
    sigma2 = np.sum(scatter**2) / max(1, 3 * n - 6)
    want = np.sqrt(np.diag(pinv @ np.kron(diff @ diff.T, np.eye(3)) @ pinv.T) * sigma2)
    assert np.allclose(_tcp_std(rotations, positions, scatter), want, rtol=RTOL, atol=0)


def test_gravity_by_vectorised_configurations(
    get_robot: Callable[[str], pincal.Robot], monkeypatch: pytest.MonkeyPatch
) -> None:
    robot = get_robot("ur5")
    q = robot.random_configurations(30, np.random.default_rng(1))
    data = robot.model.createData()
    want = np.array([pin.computeGeneralizedGravity(robot.model, data, robot.configuration(x)) for x in q])
    assert np.array_equal(robot.configurations(q), np.array([robot.configuration(x) for x in q]))
    assert np.array_equal(gravity.gravity_torques(robot, q), want)
    monkeypatch.setattr(gravity, "_GRAVITY", [])
    monkeypatch.setattr(gravity, "_GRAVITY_ROWS", 25)
    for k in range(3):  # three blocks of 10 rows: the oldest is let go
        assert np.array_equal(
            gravity.gravity_torques(robot, q[10 * k : 10 * k + 10]), want[10 * k : 10 * k + 10]
        )
    assert sum(len(entry[3]) for entry in gravity._GRAVITY) <= 25 and len(gravity._GRAVITY) == 2


def test_problems_on_the_same_poses_share_their_blocks(monkeypatch: pytest.MonkeyPatch) -> None:
    """The registration's, the fit's and the guard's problems on the same poses hold one copy of
    the poses' blocks (each held its own: 100 MB a problem at 10⁶ pose rows), and what each block
    computes is what it computed from its own copy."""
    _tiny_blocks(monkeypatch)
    robot = pincal.load_robot("ur5")
    _, fit, _ = pincal.simulate(robot, n_fit=30, n_test=0, seed=4, rot_noise=5e-4)
    one = set_up(robot, fit, "placements", "pose").problem
    other = Problem(one.model, one.measurement, fit)
    theta = one.initial_theta() + np.random.default_rng(4).normal(0.0, 1e-3, one.n_params)
    for a, b in zip(chunked.blocks(one), chunked.blocks(other), strict=True):
        assert a.data is b.data and a.measured_rotations is b.measured_rotations
    starts = range(0, 30, 7)
    own = [Problem(one.model, one.measurement, fit.subset(np.arange(s, min(s + 7, 30)))) for s in starts]
    for block, alone in zip(chunked.blocks(one), own, strict=True):
        np.testing.assert_array_equal(block.residuals(theta), alone.residuals(theta))
    np.testing.assert_array_equal(fit.rotations(), fit.subset(np.arange(30)).rotations())
    for block, start in zip(chunked.blocks(one), starts, strict=True):  # views of the poses, no copy
        assert np.shares_memory(block.data.q, fit.q) and np.shares_memory(
            block.measured_rotations, fit.rotations()
        )
        np.testing.assert_array_equal(block.data.row_numbers, fit.row_numbers[start : start + 7])
        assert block.data.rows is not None and block.data.rows.base is None  # its own: not a view of all


def test_large_data_is_screened_before_any_fit_of_every_pose(monkeypatch: pytest.MonkeyPatch) -> None:
    """On large data the outlier screen starts from the fit of its random subset of poses: a call
    that finds an outlier fits every pose only once, without it, and gives what a call on the
    poses kept gives (to the solver's tolerance), the outlier recorded by its row."""
    monkeypatch.setattr(chunked, "LARGE_POSES", 100)  # as at full size: the subset is not large itself,
    monkeypatch.setattr(chunked, "SAMPLE_POSES", 80)  # nor the rank check's 90 varied poses
    monkeypatch.setattr(chunked, "BLOCK_POSES", 7)
    ur5 = pincal.load_robot("ur5")
    q = ur5.random_configurations(150, np.random.default_rng(3), 0.05)
    data = pincal.random_truth(ur5, seed=4).measure(q, 2e-5, seed=5)
    data = replace(data, points=data.points + np.where(np.arange(150) == 17, 3e-3, 0.0)[:, None])
    fitted = _poses_per_call(monkeypatch, [(pincal.auto.fitting, "solve")], lambda on: len(on.problem.data))
    screened = pincal.calibrate(ur5, data, params="all", outliers=6.0)
    assert [row for row, _ in screened.excluded] == [18]
    assert 150 not in fitted and 149 in fitted, fitted
    kept = pincal.calibrate(ur5, data.subset(np.setdiff1d(np.arange(150), [17])), params="all")
    np.testing.assert_allclose(screened.theta, kept.theta, rtol=0, atol=1e-9)
    assert screened.train_after.rms_mm == pytest.approx(kept.train_after.rms_mm, rel=1e-9)


def test_robust_refit_by_blocks_is_the_refit_by_rows(monkeypatch: pytest.MonkeyPatch) -> None:
    """The soft-L1 refit (the outlier screen's, on its subset of poses) builds its triangle block
    by block above BLOCK_POSES poses: the minimum of the dense rooted Jacobian's, to the solver's
    tolerance (1 nm and 1 µrad; the plain least squares is micrometres away: the outlier)."""
    robot = pincal.load_robot("ur5")
    _, fit, _ = pincal.simulate(robot, n_fit=30, n_test=0, seed=6, rot_noise=5e-4)
    fit = replace(fit, points=fit.points + np.where(np.arange(30) == 4, 2e-3, 0.0)[:, None])  # an outlier
    setup = set_up(robot, fit, "placements", "pose")
    start = setup.problem.initial_theta()
    free = identifiable_set(setup, start).identifiable
    dense, dense_result = solve(setup, start, free, "soft_l1", 1e-4)
    monkeypatch.setattr(chunked, "BLOCK_POSES", 7)
    seen: list[int] = []
    rows = chunked.triangle
    monkeypatch.setattr(chunked, "triangle", lambda *a, **k: seen.append(1) or rows(*a, **k))
    blocked, blocked_result = solve(set_up(robot, fit, "placements", "pose"), start, free, "soft_l1", 1e-4)
    assert seen, "the refit did not build its triangle by blocks"
    np.testing.assert_allclose(blocked, dense, rtol=0.0, atol=1e-9)
    assert blocked_result.cost == pytest.approx(dense_result.cost, rel=1e-9)
    plain, _ = solve(setup, start, free)
    assert np.max(np.abs(plain - dense)) > 1e-6, "the outlier moves a plain fit: the test can tell"


def test_block_groups_give_the_same_passes_in_one_process_or_two(monkeypatch: pytest.MonkeyPatch) -> None:
    """A large problem's triangle and normal equations are made by runs of blocks side by side:
    bit for bit those of one process, and the triangle is that of every row at once (its Gram
    matrix to rounding)."""
    robot = pincal.load_robot("ur5")
    _, fit, _ = pincal.simulate(robot, n_fit=40, n_test=0, seed=2, rot_noise=5e-4)
    problem = set_up(robot, fit, "placements", "pose").problem
    theta = problem.initial_theta() + np.random.default_rng(2).normal(0.0, 1e-3, problem.n_params)
    free, scale = np.ones(problem.n_params, dtype=bool), np.full(problem.n_params, 1e-3)
    res, jac = problem.rows(theta, np.arange(problem.n_params))  # every row at once, before the blocks
    whole = np.column_stack([jac * scale, res])
    _tiny_blocks(monkeypatch)
    problem = Problem(problem.model, problem.measurement, fit)
    none = (np.zeros((0, problem.n_params)), np.zeros(0))
    answers = []
    for workers in ("1", "2"):
        monkeypatch.setenv("PINCAL_WORKERS", workers)
        terms = chunked.normal_terms(problem, theta, free)
        answers.append((chunked.triangle(problem, theta, free, scale, none), terms))
    (tri_1, terms_1), (tri_2, terms_2) = answers
    np.testing.assert_array_equal(tri_1, tri_2)
    for one, two in zip(terms_1, terms_2, strict=True):
        np.testing.assert_array_equal(one, two)
    big = np.abs(whole).max() ** 2
    np.testing.assert_allclose(tri_1.T @ tri_1, whole.T @ whole, rtol=1e-10, atol=1e-12 * big)
    np.testing.assert_allclose(terms_1[0], jac.T @ jac, rtol=1e-10, atol=1e-12 * np.abs(jac).max() ** 2)


def test_a_given_pull_or_robust_loss_makes_no_subset_fit(monkeypatch: pytest.MonkeyPatch) -> None:
    """The subset's fit serves the screen only when it looks at the default pull's fit: with a given
    pull or a robust loss it is not made (the screen looks at the fit at that pull), and by default
    it is."""
    monkeypatch.setattr(chunked, "LARGE_POSES", 100)
    monkeypatch.setattr(chunked, "SAMPLE_POSES", 80)
    ur5 = pincal.load_robot("ur5")
    q = ur5.random_configurations(150, np.random.default_rng(3), 0.05)
    setup = set_up(ur5, pincal.random_truth(ur5, seed=4).measure(q, 2e-5, seed=5), "placements", "position")
    fitted = _poses_per_call(
        monkeypatch, [(pincal.auto.fitting, "first_fit")], lambda on: len(on.problem.data)
    )
    given = {"pull": pincal.identify.guard.Pull(weight=0.1)}
    assert pincal.auto.fitting.sample_fit(setup, None, given) is None
    assert pincal.auto.fitting.sample_fit(setup, None, {"loss": "huber"}) is None
    assert fitted == []
    assert pincal.auto.fitting.sample_fit(setup, None, {}) is not None
    assert fitted == [80]


def test_a_large_fit_reads_its_standard_deviations_from_the_pull_s_pass(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """On a large problem the rows are summed once, at the default pull's fit, for the pull's
    evidence and the standard deviations: the standard deviations of the sums at the fit (the call
    on the same poses read as a small problem) to 1e-4 (the pull moves 150 poses' fit more than a
    million's: 2e-8 there), in one pass over the rows."""
    ur5 = pincal.load_robot("ur5")
    _, fit, _ = pincal.simulate(ur5, n_fit=150, n_test=0, seed=8, rot_noise=5e-4)
    small = pincal.calibrate(ur5, fit, params="all")
    monkeypatch.setattr(chunked, "LARGE_POSES", 100)
    monkeypatch.setattr(chunked, "SAMPLE_POSES", 80)
    monkeypatch.setattr(chunked, "BLOCK_POSES", 30)
    where = [(pincal.identify.uncertainty, "row_sums"), (pincal.identify.guard, "row_sums")]
    sums = _poses_per_call(monkeypatch, where, lambda problem: len(problem.data))
    large = pincal.calibrate(ur5, fit, params="all")
    assert sums.count(150) == 1, sums
    assert large.prior is not None and large.prior.chosen_by == "evidence"
    np.testing.assert_allclose(large.std, small.std, rtol=1e-4, atol=1e-15)
    assert large.prior.weight == small.prior.weight  # type: ignore[union-attr]


def test_a_large_problem_keeps_its_last_residuals(monkeypatch: pytest.MonkeyPatch) -> None:
    """Residuals asked for again at the same θ (a fit begun where a check just evaluated it) are
    the ones made before, read-only, without a pass over the blocks; at another θ, or after the
    problem's blocks are released, a new pass gives what every row at once gives."""
    _tiny_blocks(monkeypatch)
    robot = pincal.load_robot("ur5")
    _, fit, _ = pincal.simulate(robot, n_fit=30, n_test=0, seed=4, rot_noise=5e-4)
    problem = set_up(robot, fit, "placements", "pose").problem
    alone = Problem(problem.model, problem.measurement, fit)
    monkeypatch.setattr(chunked, "LARGE_POSES", 10**9)
    whole = [alone.residuals(problem.initial_theta() + d) for d in (0.0, 1e-3)]
    monkeypatch.setattr(chunked, "LARGE_POSES", 10)
    passes = _poses_per_call(monkeypatch, [(chunked, "blocks")], lambda p: len(p.data))
    first = problem.residuals(problem.initial_theta())
    again = problem.residuals(problem.initial_theta())
    assert again is first and not first.flags.writeable and len(passes) == 1
    np.testing.assert_allclose(first, whole[0], rtol=RTOL, atol=1e-15)
    np.testing.assert_allclose(
        problem.residuals(problem.initial_theta() + 1e-3), whole[1], rtol=RTOL, atol=1e-15
    )
    chunked.release(problem)
    np.testing.assert_allclose(problem.residuals(problem.initial_theta()), whole[0], rtol=RTOL, atol=1e-15)
    assert len(passes) == 3
