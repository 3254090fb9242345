"""Fixed-point constraints (``--measure points``, :mod:`pincal.identify.fixed_points`): calibration without
an instrument, as MUKCa does it.

Every experiment is simulated (:func:`pincal.simulation.truth.simulate_points`, seeded): a true robot
with random geometric errors (:func:`pincal.simulation.truth.points_truth`: 0.5 mm / 0.5 mrad 1σ per
joint origin, 1 mrad 1σ zero offsets) carries a ball 30-80 mm from its tip frame, unknown to the
fit; each row is the commands that put the true ball in its socket (two sockets 50 mm apart in
front of the robot), plus a 0.05 mm 1σ isotropic error of the hand that holds it. What is checked:

1. the simulator: noise-free rows hold the true ball in its socket to 1e-9 m from varied
   configurations within the limits; its noise has the σ asked for; with a hidden effect the
   joints reach other values than commanded;
2. the analytic Jacobian of the ``points`` residuals (rows, then known distances) matches central
   finite differences, column by column, for every model, with and without a known distance and
   an extension; a subset of columns equals the full Jacobian's;
3. on a held-out placement of the sockets the calibrated model's RMS (each row's distance from
   its point's mean tip) is within 1.3x the noise floor, the same statistic of the true robot;
4. ``diagnose`` names a hidden joint compliance and its joint, and nothing when nothing is hidden;
5. without a known distance the scale is a gauge: it is named, and the fit keeps the URDF's
   scale instead of shrinking the set-up; with one, the scale is identified;
6. I/O: the ``point`` column, the CSV round trip, MUKCa's folder of ``hole_<name>.csv``, and
   the errors of malformed input;
7. the command line end to end: report, corrected URDF, a folder as DATA, bad ``--point-distance``.
"""

from __future__ import annotations

import json
from dataclasses import replace
from functools import cache
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import pincal
import pincal.identify.measurement
import pincal.kinematics.mdh
import pincal.simulation.truth
from pincal.auto.diagnose import diagnose
from pincal.cli import main
from pincal.data.point_files import read_socket_folder
from pincal.errors import DataError, PincalError
from pincal.identify.fixed_points import DISTANCE_WEIGHT, parse_point_distances, point_errors
from pincal.kinematics.chain import Chain, forward
from pincal.kinematics.effects import Extension
from pincal.report.report import report_dict, report_warnings
from pincal.simulation.truth import TrueRobot, ball_positions, hide_effect, points_truth, simulate_points

#: 1σ of each coordinate of where the hand holds the ball [m].
NOISE = 5e-5
#: The known distance between the two sockets of a placement [m].
DISTANCE = 0.05
DISTANCES = (("0", "1", DISTANCE),)
#: The fixture's sockets [m] in the base frame: where the fit's rows are, and a held-out placement.
TRAIN_SOCKETS = np.array([[0.45, 0.0, 0.25], [0.45, DISTANCE, 0.25]])
TEST_SOCKETS = np.array([[0.30, -0.35, 0.10], [0.33, -0.31, 0.10]])  # (30, 40, 0) mm apart
N_ROWS = 60  # 30 per socket
#: How far above the noise floor the held-out RMS may sit.
FLOOR_FACTOR = 1.3
#: Largest relative scale of the calibrated tips against a reference that "keeps the scale": a
#: third of the 1 % a silently shrunk set-up would show. The truth's own scale differs from the
#: URDF's by up to 3 per mille (seeds 0-5), through its 0.5 mm errors.
SCALE_TOL = 3e-3
FD_STEP = 1e-6
FD_RTOL = 1e-6
#: (bundled robot, tip or None for the default, a joint gravity loads)
ROBOTS = {
    "ur5": ("ur5", None, "shoulder_lift_joint"),
    "panda": ("panda", None, "panda_joint4"),
    "panda_link8": ("panda", "panda_link8", "panda_joint2"),
}


@cache
def _robot(key: str) -> pincal.Robot:
    name, tip, _ = ROBOTS[key]
    return pincal.load_robot(name, tip=tip)


@cache
def _experiment(key: str, seed: int = 0) -> tuple[TrueRobot, pincal.Dataset, pincal.Dataset]:
    """The seeded truth, its rows at the training sockets, and at the held-out placement."""
    truth = points_truth(_robot(key), seed)
    fit = simulate_points(truth, TRAIN_SOCKETS, N_ROWS, NOISE, np.random.default_rng(seed + 1))
    test = simulate_points(truth, TEST_SOCKETS, N_ROWS, NOISE, np.random.default_rng(seed + 2))
    return truth, fit, test


def _hidden_compliance(key: str, rms: float, seed: int = 0) -> tuple[TrueRobot, pincal.Dataset]:
    """A truth whose loaded joint sags under gravity, the ball moving ``rms`` [m] RMS over the
    rows, and its rows at the training sockets (the same starts and hand errors as without)."""
    truth, fit, _ = _experiment(key, seed)
    ext = Extension.parse(_robot(key), f"joint_compliance:{ROBOTS[key][2]}")
    hidden = hide_effect(truth, ext, fit.q, rms, seed=seed)
    hidden = replace(hidden, effect=-np.abs(hidden.effect))  # c < 0: the joint sags
    return hidden, simulate_points(hidden, TRAIN_SOCKETS, N_ROWS, NOISE, np.random.default_rng(seed + 1))


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def _similarity_scale(points: np.ndarray, reference: np.ndarray) -> float:
    """The scale ``s`` of the best similarity ``s R p + t`` from ``points`` to ``reference``
    (both (N, 3)), Umeyama's closed form."""
    a, b = points - points.mean(axis=0), reference - reference.mean(axis=0)
    u, sv, vt = np.linalg.svd(a.T @ b)
    sign = np.sign(np.linalg.det(u @ vt))
    return float((sv[0] + sv[1] + sign * sv[2]) / np.sum(a**2))


# --- 1. the simulator -----------------------------------------------------------------------------


@pytest.mark.parametrize("key", ["ur5", "panda"])
def test_simulated_rows_hold_the_true_ball_in_its_socket(key: str) -> None:
    """Noise-free rows put the true ball in its socket to 1e-9 m, within the joint limits, in
    blocks of 30 per socket, from configurations whose tip orientations differ (MUKCa's point)."""
    robot = _robot(key)
    truth = points_truth(robot, 3)
    data = simulate_points(truth, TRAIN_SOCKETS, N_ROWS, 0.0, np.random.default_rng(4), names=("a", "b"))
    assert data.point_names == ("a", "b") and data.joint_names == robot.joint_names
    assert data.labels is not None
    assert np.array_equal(data.labels, np.repeat([0, 1], N_ROWS // 2))
    balls, rotations, _ = ball_positions(truth, data.q)
    assert np.abs(balls - TRAIN_SOCKETS[data.labels]).max() <= 1e-9
    assert np.all(data.q >= robot.lower) and np.all(data.q <= robot.upper)
    assert 0.03 <= np.linalg.norm(truth.tool.translation) <= 0.08
    z = rotations[:, :, 2]  # the tip's z axes: pairwise angles
    angles = np.degrees(np.arccos(np.clip(z @ z.T, -1.0, 1.0)))[np.triu_indices(N_ROWS, 1)]
    assert np.median(angles) > 30.0
    # The nominal robot's tip misses the sockets: the truth is not the URDF.
    nominal = forward(Chain.nominal(robot), data.q)
    balls_nominal = nominal.tip_translation + nominal.tip_rotation @ truth.tool.translation
    assert _rms(np.linalg.norm(balls_nominal - balls, axis=1)) > 0.5e-3


def test_simulated_noise_has_the_sigma_asked_for() -> None:
    """The true ball's distance from its socket over 600 rows: RMS σ√3 within 10 % (the RMS of
    1,800 squared Gaussians has a relative 1σ of 1/√3600 ≈ 1.7 %)."""
    truth = points_truth(_robot("ur5"), 5)
    data = simulate_points(truth, TRAIN_SOCKETS, 600, NOISE, np.random.default_rng(6))
    assert data.labels is not None
    miss = ball_positions(truth, data.q)[0] - TRAIN_SOCKETS[data.labels]
    assert abs(_rms(np.linalg.norm(miss, axis=1)) / (NOISE * np.sqrt(3.0)) - 1.0) <= 0.1
    assert np.abs(miss.mean(axis=0)).max() <= 4 * NOISE / np.sqrt(600)


def test_hidden_effect_changes_what_the_joints_reach() -> None:
    """With a hidden compliance, the commands put the ball in its socket only through the joint
    error: the same commands without it miss by the effect's size."""
    hidden, data = _hidden_compliance("ur5", 0.3e-3)
    assert data.labels is not None and hidden.extension is not None
    assert hidden.effect is not None and hidden.effect[0] < 0
    balls = ball_positions(hidden, data.q)[0]
    assert np.abs(balls - TRAIN_SOCKETS[data.labels]).max() <= 5 * NOISE
    rigid = ball_positions(replace(hidden, extension=None, effect=None), data.q)[0]
    assert 0.2e-3 <= _rms(np.linalg.norm(rigid - balls, axis=1)) <= 0.45e-3


def test_simulate_points_accepts_a_nominal_robot() -> None:
    """A :class:`~pincal.Robot` is its own truth: the tip frame's origin in the socket."""
    robot = _robot("panda")
    data = simulate_points(robot, TEST_SOCKETS[:1], 5, 0.0, 11)
    assert data.point_names == ("0",)
    tips = forward(Chain.nominal(robot), data.q).tip_translation
    assert np.abs(tips - TEST_SOCKETS[0]).max() <= 1e-9
    with pytest.raises(DataError, match=r"rows \[0, 1\]: their socket is out of the true robot's reach"):
        simulate_points(robot, [[3.0, 0.0, 0.5]], 2, 0.0, 11)


# --- 2. the Jacobian --------------------------------------------------------------------------------


def _points_problem(
    key: str, kind: str, known: bool, extended: bool, seed: int
) -> tuple[pincal.identify.measurements.Problem, np.ndarray]:
    """A fixed-point problem on 12 simulated rows and a random θ near its fit: model parameters
    ~1e-3, the extension's moving its joint ~1e-3 rad, points and tool within ~1 mm of theirs."""
    robot = _robot(key)
    rng = np.random.default_rng(seed)
    truth = points_truth(robot, seed)
    data = simulate_points(truth, TRAIN_SOCKETS, 12, NOISE, rng)
    ext = Extension.parse(robot, f"joint_compliance:{ROBOTS[key][2]}") if extended else None
    measurement = pincal.identify.measurement.Measurement(
        "points",
        tool=pin.SE3(np.eye(3), truth.tool.translation),
        points=data.point_names,
        point_distances=DISTANCES if known else (),
    )
    problem = pincal.identify.measurements.Problem(
        pincal.kinematics.mdh.make_model(kind, robot), measurement, data, ext
    )
    theta = problem.initial_theta()  # the points at their rows' mean, the tool at the truth's
    n_geo, n_model = problem.model.n_params, problem.n_model
    theta[:n_geo] += rng.normal(0.0, 1e-3, n_geo)
    rms = np.sqrt(np.mean(problem.regressors**2, axis=0))
    theta[n_geo:n_model] += rng.normal(0.0, 1e-3, n_model - n_geo) / rms
    theta[n_model:] += rng.normal(0.0, 1e-3, problem.n_params - n_model)
    return problem, theta


@pytest.mark.parametrize("extended", [False, True], ids=["rigid", "compliance"])
@pytest.mark.parametrize("known", [False, True], ids=["no_distance", "distance"])
@pytest.mark.parametrize("kind", ["placements", "poe", "mdh"])
@pytest.mark.parametrize("key", ["ur5", "panda"])
def test_points_jacobian_matches_finite_differences(key: str, kind: str, known: bool, extended: bool) -> None:
    """Every column (model, extension, points, tool) and every row (the rows' 3 coordinates, then
    the known distance): ``|J - J_fd| <= 1e-6 max |J_column|`` per column, plus the differences'
    round-off."""
    problem, theta = _points_problem(key, kind, known, extended, seed=7)
    jac = problem.jacobian(theta)
    n_rows = 3 * len(problem.data) + int(known)
    assert jac.shape == (n_rows, problem.n_params)
    assert problem.n_params == problem.n_model + 3 * 2 + 3
    assert len(problem.residuals(theta)) == n_rows == len(problem.row_poses()) == problem.n_rows()
    jac_fd = np.empty_like(jac)
    steps = np.full(problem.n_params, FD_STEP)
    steps[problem.model.n_params : problem.n_model] *= 1e-3  # an extension's unit is small: rad/(N·m)
    for c, h in enumerate(steps):
        step = np.zeros(problem.n_params)
        step[c] = h
        jac_fd[:, c] = (problem.residuals(theta + step) - problem.residuals(theta - step)) / (2 * h)
    size = np.abs(jac).max(axis=0)
    assert np.all(size[problem.model.n_params :] > 0)  # the extension, points and tool all act
    # Round-off of the differences: 10 ε |r| / h with residuals computed from positions of ~1 m.
    bad = np.abs(jac - jac_fd).max(axis=0) > FD_RTOL * size + 10 * np.finfo(float).eps / steps
    assert not bad.any(), [problem.names[c] for c in np.flatnonzero(bad)]
    if known:  # the distance row sees the points only, weighted by DISTANCE_WEIGHT √N
        first = problem.n_model
        assert np.all(jac[-1, :first] == 0) and np.all(jac[-1, first + 6 :] == 0)
        expected = DISTANCE_WEIGHT * np.sqrt(2 * len(problem.data))
        assert np.isclose(np.linalg.norm(jac[-1]), expected, rtol=1e-12)


@pytest.mark.parametrize("known", [False, True], ids=["no_distance", "distance"])
@pytest.mark.parametrize("kind", ["placements", "mdh"])
def test_jacobian_of_some_columns_is_the_full_jacobians(kind: str, known: bool) -> None:
    """``jacobian(θ, free)``, free as a mask or as indices, is the full Jacobian's columns."""
    problem, theta = _points_problem("panda", kind, known, True, seed=8)
    full = problem.jacobian(theta)
    rng = np.random.default_rng(9)
    for _ in range(3):
        free = rng.random(problem.n_params) < 0.5
        free[problem.n_model] = free[-1] = True  # a point's column and the tool's among them
        scale = np.abs(full).max()
        np.testing.assert_allclose(problem.jacobian(theta, free), full[:, free], rtol=0, atol=1e-13 * scale)
        index = np.flatnonzero(free)
        np.testing.assert_allclose(problem.jacobian(theta, index), full[:, index], rtol=0, atol=1e-13 * scale)


# --- 3. recovery of simulated truth ---------------------------------------------------------------


def _noise_floor_mm(truth: TrueRobot, data: pincal.Dataset) -> float:
    """The held-out statistic of the true robot: RMS of each row's true ball from its point's mean."""
    return _rms(point_errors(ball_positions(truth, data.q)[0], data, DISTANCES)[0]) * 1e3


@pytest.mark.parametrize("params", [None, "auto"], ids=["all", "auto"])
@pytest.mark.parametrize("key", list(ROBOTS))
def test_held_out_placement_reaches_noise_floor(key: str, params: str | None) -> None:
    """Calibrated on one placement of the sockets, judged on another: the held-out RMS is within
    1.3x what the true robot itself scores (the hand's noise), from over 5x before."""
    truth, fit, test = _experiment(key)
    cal = pincal.calibrate(
        _robot(key), fit, "placements", params=params, point_distances=DISTANCES, test=test
    )
    floor = _noise_floor_mm(truth, test)
    assert cal.measurement.kind == "points"
    assert cal.test_before is not None and cal.test_after is not None
    assert cal.test_after.n == N_ROWS
    assert cal.test_before.rms_mm > 5 * floor
    assert cal.test_after.rms_mm <= FLOOR_FACTOR * floor, (cal.test_after.rms_mm, floor)
    # The distance between the two held-out points' means: the means' own noise is σ√(2/30)
    # along the line between them (13 µm); 4x that.
    assert cal.test_after.point_distance_error_mm is not None
    assert cal.test_after.point_distance_error_mm <= 4 * NOISE * 1e3 * np.sqrt(2 / 30)
    assert cal.test_after.point_mae_mm == cal.test_after.mean_mm
    # The ball is found, to 1 mm: the last joint origin's errors (0.5 mm 1σ) trade with it.
    assert np.linalg.norm(cal.split()[2].translation - truth.tool.translation) <= 1e-3


# --- 4. diagnosis ---------------------------------------------------------------------------------


@pytest.mark.parametrize("key", ["ur5", "panda"])
def test_diagnose_names_a_hidden_compliance(key: str) -> None:
    """A compliance moving the ball 0.3 mm RMS: named with its joint, a sag, its coefficient
    within 4σ of the hidden one."""
    hidden, data = _hidden_compliance(key, 0.3e-3)
    found = diagnose(_robot(key), data, "placements", point_distances=DISTANCES)
    assert found.cause is not None, found.summary()
    ext = found.cause.extension
    assert (ext.effect, ext.joint) == ("joint_compliance", ROBOTS[key][2]), found.summary()
    cal = found.cause.calibration
    assert cal is not None and hidden.effect is not None
    at = cal.model.n_params
    assert abs(cal.theta[at] - hidden.effect[0]) <= 4 * cal.std[at], (
        cal.theta[at],
        cal.std[at],
        hidden.effect,
    )
    assert "sags under gravity" in found.summary()


def test_diagnose_names_nothing_without_a_hidden_effect() -> None:
    """Geometric errors and noise only, 8 datasets: ``none`` in at least 7."""
    answers = []
    for key in ("ur5", "panda"):
        for seed in range(10, 14):
            _, fit, _ = _experiment(key, seed)
            found = diagnose(_robot(key), fit, "placements", point_distances=DISTANCES)
            answers.append(found.cause is None)
    assert sum(answers) >= 7, answers


# --- 5. the scale gauge ---------------------------------------------------------------------------


@pytest.mark.parametrize("sockets", [1, 2], ids=["one_point", "two_points"])
@pytest.mark.parametrize("key", ["ur5", "panda"])
def test_without_known_distance_the_scale_is_named_and_kept(key: str, sockets: int) -> None:
    """No known distance: the scale of the whole set-up is a gauge. The calibration names it
    (gauges, ``not_identifiable``, the held parameter's reason) and keeps the URDF's scale: over
    the workspace the calibrated tips are the URDF's up to a similarity of scale within 3 per
    mille, and the two points' fitted distance is the true 50 mm within that scale."""
    robot = _robot(key)
    truth, fit, _ = _experiment(key)
    data = fit.subset(np.arange(N_ROWS // 2)) if sockets == 1 else fit
    try:
        cal = pincal.calibrate(robot, data, "placements")
    except PincalError as exc:  # refusing is an answer too, if it says what is missing
        assert "distance" in str(exc) or "scale" in str(exc)
        return
    scale = [g for g in cal.identifiability.gauges if "scale" in g]
    assert len(scale) == 1
    report = report_dict(cal)
    assert scale[0] in report["not_identifiable"]
    held = [name for name, why in report["held"].items() if "scale" in why]
    assert len(held) == 1 and held[0] in cal.model.names
    assert not cal.identifiability.identifiable[cal.names.index(held[0])]
    q = robot.random_configurations(300, np.random.default_rng(12), 0.05)
    tips = cal.base_T_tip(q)[1]
    nominal = forward(Chain.nominal(robot), q).tip_translation
    assert abs(_similarity_scale(tips, nominal) - 1.0) <= SCALE_TOL
    if sockets == 2:
        means = cal.problem(data).point_positions(cal.theta)
        assert abs(np.linalg.norm(means[0] - means[1]) - DISTANCE) <= SCALE_TOL * DISTANCE
    assert cal.train_after.rms_mm <= 1.3 * _noise_floor_mm(truth, data)


@pytest.mark.parametrize("key", ["ur5", "panda"])
def test_a_known_distance_identifies_the_scale(key: str) -> None:
    """With the 50 mm given: no scale gauge, the fitted points 50 mm apart to 1 µm, and the
    calibrated tips the TRUE robot's up to a similarity of scale within 1 per mille."""
    robot = _robot(key)
    truth, fit, _ = _experiment(key)
    cal = pincal.calibrate(robot, fit, "placements", point_distances=DISTANCES)
    assert len(cal.identifiability.gauges) == 6
    assert not any("scale" in g for g in cal.identifiability.gauges)
    assert not any("scale" in why for why in report_dict(cal)["held"].values())
    means = cal.problem(fit).point_positions(cal.theta)
    assert abs(np.linalg.norm(means[0] - means[1]) - DISTANCE) <= 1e-6
    q = robot.random_configurations(300, np.random.default_rng(12), 0.05)
    true_tips = forward(truth.model.chain(truth.x), q).tip_translation
    assert abs(_similarity_scale(cal.base_T_tip(q)[1], true_tips) - 1.0) <= SCALE_TOL / 3


# --- 6. I/O ---------------------------------------------------------------------------------------


def _write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def test_read_csv_reads_the_point_column(tmp_path: Path) -> None:
    """Names in order of first appearance, each row's index into them; no x,y,z needed; degrees."""
    robot = _robot("ur5")
    header = ",".join([*robot.joint_names, "point"])
    rows = ["1,2,3,4,5,6,b", "# a comment", "6,5,4,3,2,1, a ", "0,0,0,0,0,0,b"]
    data = pincal.read_csv(
        _write(tmp_path / "p.csv", "\n".join([header, *rows])), robot.joint_names, degrees=True
    )
    assert data.point_names == ("b", "a")
    assert data.labels is not None and data.labels.tolist() == [0, 1, 0]
    np.testing.assert_allclose(data.q[1], np.deg2rad([6, 5, 4, 3, 2, 1]), rtol=0, atol=1e-15)
    assert not data.points.any()
    sub = data.subset([2, 1])
    assert sub.labels is not None and sub.labels.tolist() == [0, 1] and sub.point_names == ("b", "a")


def test_write_csv_read_csv_round_trip(tmp_path: Path) -> None:
    _, fit, _ = _experiment("panda")
    path = tmp_path / "rows.csv"
    pincal.write_csv(path, fit, units="mm")
    back = pincal.read_csv(path, fit.joint_names, units="mm")
    assert np.array_equal(back.q, fit.q)
    assert back.labels is not None and fit.labels is not None
    assert np.array_equal(back.labels, fit.labels) and back.point_names == fit.point_names
    assert back.has_orientation is False


def test_read_socket_folder(tmp_path: Path) -> None:
    """MUKCa's layout: hole_<name>.csv without a header, radians in chain order."""
    _, fit, _ = _experiment("ur5")
    assert fit.labels is not None
    for k, name in enumerate(fit.point_names):
        np.savetxt(tmp_path / f"hole_{name}.csv", fit.q[fit.labels == k], delimiter=",")
    (tmp_path / "notes.txt").write_text("not a socket")
    data = read_socket_folder(tmp_path, fit.joint_names)
    assert data.point_names == ("0", "1") and data.joint_names == fit.joint_names
    assert np.array_equal(data.q, fit.q)
    assert data.labels is not None and np.array_equal(data.labels, fit.labels)


def test_read_socket_folder_refuses_bad_folders(tmp_path: Path) -> None:
    names = _robot("ur5").joint_names
    with pytest.raises(DataError, match="without hole_<name>.csv"):
        read_socket_folder(tmp_path, names)
    _write(tmp_path / "poses.csv", "a,b\n1,2\n")
    with pytest.raises(DataError, match=r"give the measurement CSV file \(it holds poses.csv\)"):
        read_socket_folder(tmp_path, names)
    (tmp_path / "poses.csv").unlink()
    _write(tmp_path / "hole_0.csv", "0.1,0.2,0.3,0.4,0.5\n")
    with pytest.raises(DataError, match="6 finite joint values"):
        read_socket_folder(tmp_path, names)
    _write(tmp_path / "hole_0.csv", "0.1,0.2,0.3,0.4,0.5,nan\n")
    with pytest.raises(DataError, match="finite"):
        read_socket_folder(tmp_path, names)
    _write(tmp_path / "hole_0.csv", "0.1,0.2,0.3,0.4,0.5,x\n")
    with pytest.raises(DataError, match="not a table of numbers"):
        read_socket_folder(tmp_path, names)


def test_missing_point_name_is_refused(tmp_path: Path) -> None:
    names = _robot("ur5").joint_names
    text = "\n".join([",".join([*names, "point"]), "1,2,3,4,5,6,a", "1,2,3,4,5,6,  "])
    with pytest.raises(DataError, match="data row 2 has no point name"):
        pincal.read_csv(_write(tmp_path / "p.csv", text), names)


def test_parse_point_distances() -> None:
    assert parse_point_distances("0,1=50", "mm") == (("0", "1", 0.05),)
    assert parse_point_distances(" a, b = 0.1 ; b,c=0.2") == (("a", "b", 0.1), ("b", "c", 0.2))
    assert parse_point_distances(None) == parse_point_distances("  ") == ()


@pytest.mark.parametrize(
    "text", ["0,1", "0,0=5", "0,1=-3", "0,1=0", "0,1=abc", "0=5", "0,1,2=5", ",1=5", "0,1=inf"]
)
def test_parse_point_distances_refuses_malformed_items(text: str) -> None:
    with pytest.raises(DataError, match="point_distances="):
        parse_point_distances(text, "mm")


@pytest.mark.parametrize("text", ["0,1=40;0,1=50", "0,1=50;1,0=50", "a,b=1;b,c=2;c,b=2"])
def test_parse_point_distances_refuses_a_pair_given_twice(text: str) -> None:
    """In either order, the same value or another: the fit would keep one silently, or split the
    difference."""
    with pytest.raises(DataError, match="twice"):
        parse_point_distances(text, "mm")


def test_held_out_points_named_otherwise_are_said_unjudged() -> None:
    """A held-out placement whose points have other names than the fitted ones: its distance
    error cannot be judged, and a warning says why (named alike: no warning, a figure)."""
    _, fit, test = _experiment("ur5")
    for held, named in ((test, True), (replace(test, point_names=("a", "b")), False)):
        cal = pincal.calibrate(_robot("ur5"), fit, point_distances=DISTANCES, test=held)
        assert cal.test_after is not None
        assert (cal.test_after.point_distance_error_mm is not None) == named
        said = [w for w in report_warnings(cal, fit, held) if "not judged" in w]
        assert len(said) == int(not named) and all("(a, b)" in w and "0-1" in w for w in said)


def test_a_distance_naming_an_unknown_point_is_refused() -> None:
    _, fit, _ = _experiment("ur5")
    with pytest.raises(DataError, match="'7'.*0, 1"):
        pincal.calibrate(_robot("ur5"), fit, point_distances=(("0", "7", DISTANCE),))
    with pytest.raises(DataError, match="point_distances= is for measure=points"):
        pincal.calibrate(_robot("ur5"), fit, "placements", "position", point_distances=DISTANCES)


# --- 7. the command line --------------------------------------------------------------------------


def _run(capsys: pytest.CaptureFixture[str], *args: str | Path) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def ur5_files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    """The UR5 experiment as files: fitted rows (CSV), held-out rows (CSV), fitted rows as a folder."""
    folder = tmp_path_factory.mktemp("points")
    _, fit, test = _experiment("ur5")
    pincal.write_csv(folder / "data.csv", fit, units="mm")
    pincal.write_csv(folder / "test.csv", test, units="mm")
    holes = folder / "holes"
    holes.mkdir()
    assert fit.labels is not None
    for k, name in enumerate(fit.point_names):
        np.savetxt(holes / f"hole_{name}.csv", fit.q[fit.labels == k], delimiter=",")
    return folder / "data.csv", folder / "test.csv", holes


def _reported_model(
    report: dict, robot: pincal.Robot, q: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The reported model's tip rotations and positions [m] at ``q`` and its tool [m], rebuilt
    from the report's parameters (mm, mrad)."""
    values = {row["name"]: row["value"] * 1e-3 for row in report["parameters"]}
    model = pincal.kinematics.mdh.make_model(report["model"], robot)
    frames = forward(model.chain(np.array([values[n] for n in model.names])), q)
    return frames.tip_rotation, frames.tip_translation, np.array([values[f"tool.{c}"] for c in "xyz"])


def test_cli_calibrate_points_end_to_end(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, ur5_files: tuple[Path, Path, Path]
) -> None:
    """Report keys, and a corrected URDF whose tip link is the calibrated ball: URDF and report
    agree to 1e-9, and the URDF alone scores the report's held-out figures."""
    data, test, _ = ur5_files
    report_path, urdf = tmp_path / "r.json", tmp_path / "out.urdf"
    args: list[str | Path] = ["--point-distance", "0,1=50", "--units", "mm", "--test", test]
    args += ["--report", report_path, "-o", urdf]
    code, out, err = _run(capsys, "calibrate", "ur5", data, *args)
    assert code == 0, err
    assert f"report written to {report_path}" in out and "corrected URDF written" in out
    report = json.loads(report_path.read_text())
    assert report["measure"] == "points" and report["n_poses"] == N_ROWS
    for part in ("train", "test"):
        for when in ("before", "after", "urdf"):
            stats = report[part][when]
            for key in ("rms_mm", "point_mae_mm", "point_distance_error_mm"):
                assert isinstance(stats[key], float) and stats[key] >= 0.0, (part, when, key)
    assert report["test"]["after"]["rms_mm"] < report["test"]["before"]["rms_mm"] / 5
    assert not any("scale" in g for g in report["not_identifiable"])
    # --extend defaults to none here: one fixture's rows cannot tell an effect on another placement
    assert report["choice"]["extension"] == "none" and report["choice"]["diagnosis"] is None

    robot = _robot("ur5")
    held = pincal.read_csv(test, robot.joint_names, units="mm")
    rot, tips, tool = _reported_model(report, robot, held.q)
    balls = tips + rot @ tool
    # The reconstruction from the report is the calibrated model: it scores the report's figures.
    errors, off = point_errors(balls, held, DISTANCES)
    assert np.isclose(_rms(errors) * 1e3, report["test"]["after"]["rms_mm"], rtol=1e-9)
    assert np.isclose(off[0] * 1e3, report["test"]["after"]["point_distance_error_mm"], rtol=1e-6)
    exported = pincal.load_robot(str(urdf), tip=robot.tip)
    assert exported.joint_names == robot.joint_names
    sidecar = json.loads(urdf.with_name("out.calibration.json").read_text())
    assert sidecar["measure"] == "points" and sidecar["instrument_T_base"] is None
    assert np.allclose(sidecar["tip_T_tool"]["matrix"], np.eye(4), rtol=0, atol=0)
    parent = pincal.load_robot(str(urdf), tip="wrist_3_link")
    nominal_last = robot.placements[-1]  # wrist_3_link -> tool0 as the input URDF has it
    for i, q in enumerate(held.q):
        tip = exported.frame_placement(q)
        assert np.linalg.norm(tip.translation - balls[i]) <= 1e-9
        assert np.linalg.norm(pin.log3(tip.rotation.T @ rot[i])) <= 1e-9
        # Without the ball: the link that carries it is the calibrated chain's last joint frame.
        link = parent.frame_placement(q) * nominal_last
        assert np.linalg.norm(link.translation - tips[i]) <= 1e-9
        assert np.linalg.norm(pin.log3(link.rotation.T @ rot[i])) <= 1e-9


@pytest.mark.parametrize("distance", ["5", "0.05", "500"])
def test_cli_refuses_a_known_distance_the_robot_cannot_have(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, ur5_files: tuple[Path, Path, Path], distance: str
) -> None:
    """A wrong ``--point-distance`` (5 mm, metres typed for millimetres) would shrink the arm until
    its sockets are that far apart, with perfect-looking figures: the nominal robot puts them
    about 50 mm apart, so it is refused, naming the option; nothing is written. The true value
    passes the same check."""
    data, _, _ = ur5_files
    urdf = tmp_path / "out.urdf"
    code, out, err = _run(
        capsys, "calibrate", "ur5", data, "--point-distance", f"0,1={distance}", "--units", "mm", "-o", urdf
    )
    assert code == 2 and "corrected URDF written" not in out
    assert err.count("\n") == 1 and err.startswith("pincal: error:")
    assert "known distance" in err and "--point-distance" in err
    assert not urdf.exists()
    code, _, err = _run(capsys, "calibrate", "ur5", data, "--point-distance", "0,1=50", "--units", "mm")
    assert code == 0, err


def test_cli_reads_a_folder_of_holes(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, ur5_files: tuple[Path, Path, Path]
) -> None:
    """DATA as MUKCa's folder: the same rows, the same fit as from the CSV."""
    data, test, holes = ur5_files
    reports = []
    for source in (data, holes):
        path = tmp_path / f"{source.stem}.json"
        code, _, err = _run(
            capsys, "calibrate", "ur5", source, "--point-distance", "0,1=50", "--units", "mm",
            "--test", test, "--report", path,
        )  # fmt: skip
        assert code == 0, err
        reports.append(json.loads(path.read_text()))
    csv_report, folder_report = reports
    assert folder_report["measure"] == "points" and folder_report["n_poses"] == N_ROWS
    values = [[row["value"] for row in r["parameters"]] for r in reports]
    np.testing.assert_allclose(values[1], values[0], rtol=1e-9, atol=1e-9)
    assert np.isclose(folder_report["test"]["after"]["rms_mm"], csv_report["test"]["after"]["rms_mm"])


@pytest.mark.parametrize("text", ["0,1=abc", "0,1", "0,0=50", "0,7=50"])
def test_cli_bad_point_distance_exits_2(
    capsys: pytest.CaptureFixture[str], ur5_files: tuple[Path, Path, Path], text: str
) -> None:
    code, out, err = _run(
        capsys, "calibrate", "ur5", ur5_files[0], f"--point-distance={text}", "--units", "mm"
    )
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pincal: error:") and "--point-distance" in lines[0], err
    assert "Traceback" not in out + err
