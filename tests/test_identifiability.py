"""Property tests of the identifiable set and of the reasons given for what is left out.

All on seeded simulated experiments (``pincal.simulate(robot, n_fit=60, n_test=20, seed=0)``).
The expected counts come from the theory, not from running the code: a complete, minimal model
of a chain of ``n`` revolute joints has ``4n + 6`` independent parameters (Everett; the POE
count, base and tool included). A measured point does not see the 3 tool orientations, so
position data identifies ``4n + 6 - 3`` (registration and tool point included); distances do
not see the 6 rigid motions of the whole set either, hence ``4n + 3 - 6``.

- ``distance`` with ``placements``: the first joint's placement (the base frame) has no effect.
- ``position`` with ``placements``: a joint's translation along its own axis commutes with the
  joint's rotation, so it is absorbed by the next joint's placement (for the base joint, by the
  registration; along a run of parallel axes it can slide to any joint of the run).
- ``offsets`` with a joint that never moves, and the ``mdh`` model's held Hayati β.
"""

from __future__ import annotations

import numpy as np
import pytest

import pincal
import pincal.kinematics.mdh
from pincal.kinematics.mdh import PARALLEL_TOL

COMPONENTS = ("tx", "ty", "tz")


@pytest.fixture(scope="module")
def experiment(get_robot):
    """``experiment(name)``: (robot, truth, fit) of the seeded simulation, cached."""
    cache: dict[str, tuple] = {}

    def get(name: str):
        if name not in cache:
            robot = get_robot(name)
            truth, fit, _ = pincal.simulate(robot, n_fit=60, n_test=20, seed=0)
            cache[name] = (robot, truth, fit)
        return cache[name]

    return get


def column(cal: pincal.Calibration, data: pincal.Dataset, names: list[str]) -> np.ndarray:
    """Columns of the identification Jacobian (at the registered nominal model) for ``names``."""
    jac = cal.problem(data).jacobian(cal.nominal_theta)
    return jac[:, [cal.names.index(n) for n in names]]


def in_span(target: np.ndarray, basis: np.ndarray) -> float:
    """Relative residual of the least-squares fit of ``target`` (m,) by the columns of ``basis``."""
    coef, *_ = np.linalg.lstsq(basis, target, rcond=None)
    return float(np.linalg.norm(basis @ coef - target) / np.linalg.norm(target))


def absorbers(reason: str) -> list[str]:
    """Parameter names listed in an ``absorbed by a, b, c`` reason."""
    assert reason.startswith("absorbed by "), reason
    return [s.strip() for s in reason[len("absorbed by ") :].split(",")]


# --- counts --------------------------------------------------------------------------------------


@pytest.mark.parametrize("measure", ["position", "distance"])
@pytest.mark.parametrize("kind", ["placements", "poe", "mdh"])
@pytest.mark.parametrize("name", ["ur5", "panda", "mrres5"])
def test_complete_models_identify_the_theoretical_count(
    experiment, name: str, kind: str, measure: str
) -> None:
    robot, _, fit = experiment(name)
    assert not any(robot.prismatic)
    cal = pincal.calibrate(robot, fit, kind, measure=measure)
    n = robot.n_joints
    expected = 4 * n + 6 - 3 if measure == "position" else 4 * n + 3 - 6
    ident = cal.identifiability
    assert ident.n_identifiable == expected
    assert ident.identifiable.shape == (len(cal.names),)
    # Every unknown left out is explained, and none that is estimated is.
    held = {p for p, keep in zip(cal.names, ident.identifiable) if not keep}
    assert held == set(ident.reasons)
    assert np.isfinite(ident.condition_number) and ident.condition_number >= 1.0


# --- distances: the base frame is invisible ------------------------------------------------------


def test_distance_placements_base_has_no_effect(experiment) -> None:
    robot, _, fit = experiment("ur5")
    cal = pincal.calibrate(robot, fit, "placements", measure="distance")
    ident = cal.identifiability
    first = robot.joint_names[0]
    assert first == "shoulder_pan_joint"
    base = [f"{first}.{c}" for c in ("tx", "ty", "tz", "rx", "ry", "rz")]
    for name in base:
        assert not ident.identifiable[cal.names.index(name)], name
        assert "has no effect on these measurements" in ident.reasons[name]
    # 4R + 6 for the chain, minus the tool orientation (3) a point does not see, minus the
    # rigid motion (6) distances do not see.
    assert ident.n_identifiable == 4 * 6 + 3 - 6 == 21
    # Independently: moving the base frame leaves every distance exactly as it was.
    problem = cal.problem(fit)
    theta = cal.theta.copy()
    moved = theta.copy()
    moved[[cal.names.index(n) for n in base]] = np.random.default_rng(1).normal(0.0, 0.05, 6)
    assert np.max(np.abs(problem.residuals(moved) - problem.residuals(theta))) <= 1e-12


# --- position data: translations along a joint's own axis ----------------------------------------


def axis_component(robot: pincal.Robot, j: int) -> str:
    """``tx``, ``ty`` or ``tz``: the placement translation along joint ``j``'s local axis."""
    w = robot.axes[j][3:]
    k = int(np.argmax(np.abs(w)))
    assert abs(abs(w[k]) - 1.0) < 1e-12, "the test needs joint axes along a local coordinate axis"
    return COMPONENTS[k]


def parallel_run_end(robot: pincal.Robot, j: int) -> int:
    """Last joint ``m >= j`` such that the axes ``j .. m`` are all parallel (base frame, q = 0)."""
    w = pincal.kinematics.twists.nominal_twists(robot).twists[:, 3:]
    m = j
    while m + 1 < robot.n_joints and np.linalg.norm(np.cross(w[j], w[m + 1])) < 1e-9:
        m += 1
    return m


@pytest.mark.parametrize("name, expected", [("ur5", 4 * 6 + 6 - 3), ("panda", 4 * 7 + 6 - 3)])
def test_axial_translation_absorbed_by_next_joint(experiment, name: str, expected: int) -> None:
    robot, _, fit = experiment(name)
    cal = pincal.calibrate(robot, fit, "placements", measure="position")
    ident = cal.identifiability
    assert ident.n_identifiable == expected
    joints = robot.joint_names
    for j in range(robot.n_joints - 1):
        axial = f"{joints[j]}.{axis_component(robot, j)}"
        assert not ident.identifiable[cal.names.index(axial)], axial
        named = absorbers(ident.reasons[axial])
        assert all(n in cal.names and ident.identifiable[cal.names.index(n)] for n in named), named
        # The mathematical fact behind the reason: exp(d a_j) commutes with the joint's rotation
        # about a_j, so the column is a combination of joint j+1's translation columns.
        nxt = [f"{joints[j + 1]}.{c}" for c in COMPONENTS]
        assert in_span(column(cal, fit, [axial])[:, 0], column(cal, fit, nxt)) <= 1e-9
        # The reason is truthful: the parameters it names reproduce the column.
        assert in_span(column(cal, fit, [axial])[:, 0], column(cal, fit, named)) <= 1e-6
        # It names the next joint's placement, or a later joint of a run of axes parallel to
        # this one (the translation slides along the run), or, for the base joint, the registration.
        allowed = {joints[k] for k in range(j + 1, parallel_run_end(robot, j) + 2)}
        if j == 0:
            allowed.add("instrument")
        assert any(n.split(".")[0] in allowed for n in named), (axial, named, allowed)
        assert all(
            n.split(".")[0] in ("instrument", "tool") or joints.index(n.split(".")[0]) > j for n in named
        ), (axial, named)


# --- offsets: a joint that never moves -----------------------------------------------------------


def offsets_calibration(robot, truth, fit, frozen: int | None, partial: bool = True) -> pincal.Calibration:
    """``offsets`` on the fitted poses with joint ``frozen`` held at one value (measured again);
    ``partial``: fit what the data identifies rather than refuse it."""
    q = fit.q.copy()
    if frozen is not None:
        q[:, frozen] = 0.3
    data = truth.measure(q) if frozen is not None else fit
    if frozen is not None:
        assert np.ptp(data.q[:, frozen]) == 0.0
    return pincal.calibrate(robot, data, "offsets", measure="position", partial=partial)


def identifiable(cal: pincal.Calibration, name: str) -> bool:
    return bool(cal.identifiability.identifiable[cal.names.index(name)])


def test_offsets_all_joints_moving(experiment) -> None:
    """Reference: with every joint moving only the first offset (a rotation of the registration)
    and the last one (a rotation of the unknown tool point) are not identifiable."""
    robot, truth, fit = experiment("ur5")
    cal = offsets_calibration(robot, truth, fit, None)
    names = [f"{j}.offset" for j in robot.joint_names]
    assert [identifiable(cal, n) for n in names] == [False, True, True, True, True, False]
    assert any(a.startswith("instrument.") for a in absorbers(cal.identifiability.reasons[names[0]]))
    assert all(a.startswith("tool.") for a in absorbers(cal.identifiability.reasons[names[-1]]))


@pytest.mark.parametrize("frozen", [0, 5])
def test_offset_of_never_moving_end_joint_is_not_identifiable(experiment, frozen: int) -> None:
    """A frozen end joint: its offset is not identifiable, and its neighbour's offset is lost too
    (with the base joint frozen the second axis is fixed in the base, so its offset is a rotation
    of the registration; with the wrist frozen the last-but-one offset moves the tool point)."""
    robot, truth, fit = experiment("ur5")
    cal = offsets_calibration(robot, truth, fit, frozen)
    names = [f"{j}.offset" for j in robot.joint_names]
    assert not identifiable(cal, names[frozen])
    assert names[frozen] in cal.identifiability.reasons
    neighbour = 1 if frozen == 0 else frozen - 1
    assert not identifiable(cal, names[neighbour])
    owner = "instrument." if frozen == 0 else "tool."
    assert any(a.startswith(owner) for a in absorbers(cal.identifiability.reasons[names[neighbour]]))


@pytest.mark.parametrize("frozen", [0, 5])
def test_never_moving_end_joint_is_refused_without_partial(experiment, frozen: int) -> None:
    """Without ``partial``, data that loses what varied poses identify is an error that names the
    lost parameters and the joint that never moves."""
    robot, truth, fit = experiment("ur5")
    with pytest.raises(pincal.IdentifiabilityError) as err:
        offsets_calibration(robot, truth, fit, frozen, partial=False)
    message = str(err.value)
    assert f"joint(s) {robot.joint_names[frozen]} never move" in message
    neighbour = 1 if frozen == 0 else frozen - 1
    assert f"{robot.joint_names[neighbour]}.offset" in message
    assert "partial=True" in message


@pytest.mark.parametrize("frozen", [1, 2, 3, 4])
def test_offset_of_never_moving_middle_joint(experiment, frozen: int) -> None:
    """A frozen middle joint still bends the arm by its (constant) zero error: in the ``offsets``
    model nothing else can absorb it, so it stays identifiable, and freezing it loses nothing else
    than what the reference experiment already lacked."""
    robot, truth, fit = experiment("ur5")
    cal = offsets_calibration(robot, truth, fit, frozen)
    names = [f"{j}.offset" for j in robot.joint_names]
    assert [identifiable(cal, n) for n in names] == [False, True, True, True, True, False]


# --- mdh: Hayati's beta only between parallel axes -----------------------------------------------


def test_mdh_holds_beta_on_ur5_non_parallel_axes(get_robot) -> None:
    model = pincal.kinematics.mdh.make_model("mdh", get_robot("ur5"))
    for joint in ("shoulder_lift_joint", "wrist_2_joint", "wrist_3_joint"):
        assert f"{joint}.beta" in model.held
    for joint in ("shoulder_pan_joint", "elbow_joint", "wrist_1_joint"):
        assert f"{joint}.beta" not in model.held
    assert all(name.endswith(".beta") for name in model.held)


@pytest.mark.parametrize("name", ["ur5", "ur10", "panda", "z1", "mrres5", "zu3"])
def test_mdh_holds_beta_exactly_where_axes_are_not_parallel(get_robot, name: str) -> None:
    robot = get_robot(name)
    model = pincal.kinematics.mdh.make_model("mdh", robot)
    w = pincal.kinematics.twists.nominal_twists(robot).twists[:, 3:]
    for j, joint in enumerate(robot.joint_names):
        angle = 0.0 if j == 0 else float(np.arcsin(min(1.0, np.linalg.norm(np.cross(w[j - 1], w[j])))))
        assert abs(angle - PARALLEL_TOL) > 1e-3, "an axis pair at the threshold makes this test moot"
        assert (f"{joint}.beta" in model.held) == (angle > PARALLEL_TOL), (joint, angle)


def test_mdh_held_betas_are_not_estimated(experiment) -> None:
    robot, _, fit = experiment("ur5")
    cal = pincal.calibrate(robot, fit, "mdh", measure="position")
    for name, reason in cal.model.held.items():
        assert not cal.identifiability.identifiable[cal.names.index(name)]
        assert cal.identifiability.reasons[name] == reason
        assert cal.theta[cal.names.index(name)] == 0.0


# --- the pivoted QR ------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["ur5", "panda", "mrres5"])
@pytest.mark.parametrize("kind", ["placements", "mdh"])
def test_pivots_are_lapacks(get_robot, name: str, kind: str) -> None:
    """The column pivots the identifiable set is chosen by are those of LAPACK's QR with column
    pivoting (``scipy.linalg.qr``), up to the rank, on identification Jacobians (at the nominal
    model, in natural units) whose redundant columns the preference weights tell apart, and on
    their triangle."""
    import scipy.linalg

    from pincal.identify.identifiability import pivots
    from pincal.identify.solver import register, set_up

    robot = get_robot(name)
    _, fit, _ = pincal.simulate(robot, n_fit=40, n_test=1, seed=1)
    setup = set_up(robot, fit, kind)
    jac = setup.problem.jacobian(register(setup)) * setup.scale
    weighted = jac * (1.0 + 0.05 * np.linspace(0.0, 1.0, jac.shape[1]))
    for mat in (weighted, np.linalg.qr(weighted, mode="r")):
        sv = np.linalg.svd(mat, compute_uv=False)
        rank = int(np.sum(sv > 1e-8 * sv[0]))
        lapack = scipy.linalg.qr(mat, mode="r", pivoting=True)[1][:rank]
        assert list(pivots(mat, rank)) == list(lapack)


def test_a_calibration_loads_no_scipy_linalg() -> None:
    """The default calibration's identifiable set needs no SciPy: its pivots are NumPy's."""
    import subprocess
    import sys

    code = (
        "import sys, pincal\n"
        "robot = pincal.load_robot('ur5')\n"
        "_, fit, _ = pincal.simulate(robot, 30, 1, seed=0)\n"
        "pincal.calibrate(robot, fit)\n"
        "print('scipy.linalg' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False", out.stdout


# --- why poses that vary every joint still lose parameters ---------------------------------------
def _alike_poses(robot: pincal.Robot, n: int, spread_rad: float) -> pincal.Dataset:
    """``n`` poses within ``spread_rad`` of one configuration, every joint moving, measured exactly."""
    rng = np.random.default_rng(3)
    centre = robot.random_configurations(1, rng, margin=0.2)[0]
    q = centre + rng.uniform(-spread_rad, spread_rad, (n, robot.n_joints))
    truth, _, _ = pincal.simulate(robot, n_fit=2, n_test=0, seed=0)
    return truth.measure(q, 0.0)


@pytest.mark.parametrize(
    ("poses", "cause"), [(12, "fewer than 2 per unknown"), (80, "do not vary the joints")]
)
def test_the_refusal_says_whether_poses_are_too_few_or_too_alike(get_robot, poses: int, cause: str) -> None:
    """Poses close together lose parameters whatever their count; the message puts it down to
    the count of poses when they give fewer than 2 equations per unknown, else to their spread."""
    robot = get_robot("ur5")
    with pytest.raises(pincal.IdentifiabilityError) as err:
        pincal.calibrate(robot, _alike_poses(robot, poses, 0.005), "placements")
    assert cause in str(err.value)
    assert "pincal plan" in str(err.value) if poses == 12 else "pincal plan" not in str(err.value)
