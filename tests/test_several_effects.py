"""Several effects at once and lost motion: the direction each joint moved, the identification
Jacobian of any set of effects against finite differences, and the files that carry them."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import pincal
import pincal.auto.choice as choice_module
import pincal.report.outcome
import pincal.simulation.truth
from pincal.auto.residual import residual_verdict
from pincal.data.directions import move_directions
from pincal.identify.measurement import Measurement
from pincal.identify.measurements import Problem
from pincal.kinematics.effects import Effects, Extension, combined
from pincal.kinematics.mdh import make_model

FD_STEP = 1e-7
SHARED = Path(__file__).resolve().parents[2] / "shared"


def _directions_by_the_contract(q: np.ndarray) -> np.ndarray:
    """contracts.md's rule, row by row: +1 rose, -1 fell, the previous row's when still, 0 first."""
    out = np.zeros_like(q)
    for i in range(1, len(q)):
        for j in range(q.shape[1]):
            step = q[i, j] - q[i - 1, j]
            out[i, j] = np.sign(step) if abs(step) > 1e-9 else out[i - 1, j]
    return out


def test_directions_follow_the_contract_row_by_row() -> None:
    rng = np.random.default_rng(3)
    q = np.cumsum(rng.normal(size=(40, 4)) * (rng.random((40, 4)) < 0.6), axis=0)  # joints that rest
    assert np.array_equal(move_directions(q), _directions_by_the_contract(q))
    assert not np.any(move_directions(q)[0])


def test_a_subset_keeps_the_directions_of_the_whole_file(get_robot) -> None:
    robot = get_robot("ur5")
    q = robot.random_configurations(12, np.random.default_rng(1))
    data = pincal.Dataset(robot.joint_names, q, np.zeros((12, 3)))
    rows = np.array([3, 7, 8, 11])
    assert np.array_equal(data.subset(rows).moves(), move_directions(q)[rows])
    assert np.array_equal(data.subset(rows).subset([1, 2]).moves(), move_directions(q)[[7, 8]])


def _effects(robot: pincal.Robot) -> Effects:
    labels = (
        "joint_compliance:shoulder_lift_joint",
        "gear_harmonic2:elbow_joint",
        "lost_motion:shoulder_lift_joint",
    )
    more = ("lost_motion:wrist_1_joint", "encoder_scale:elbow_joint", "backlash:elbow_joint")
    return Effects(tuple(Extension.parse(robot, t) for t in labels + more))


@pytest.mark.parametrize("measure", ["position", "pose"])
def test_the_jacobian_of_several_effects_matches_finite_differences(get_robot, measure: str) -> None:
    robot, rng = get_robot("ur5"), np.random.default_rng(5)
    effects = _effects(robot)
    q = robot.random_configurations(10, rng)
    quats = np.tile([1.0, 0.0, 0.0, 0.0], (10, 1)) if measure == "pose" else None
    data = pincal.Dataset(robot.joint_names, q, rng.normal(size=(10, 3)), quats)
    problem = Problem(make_model("placements", robot), Measurement(measure), data, effects)
    theta = problem.initial_theta() + rng.normal(0.0, 1e-3, problem.n_params)
    jac = problem.jacobian(theta)
    fd = np.empty_like(jac)
    for c in range(problem.n_params):
        step = np.zeros(problem.n_params)
        step[c] = FD_STEP
        fd[:, c] = (problem.residuals(theta + step) - problem.residuals(theta - step)) / (2 * FD_STEP)
    assert np.abs(jac - fd).max() <= 1e-6 * max(1.0, np.abs(fd).max())
    assert problem.names[make_model("placements", robot).n_params :][:4] == effects.names[:4]


def test_several_effects_reach_the_sum_of_their_joint_errors(get_robot) -> None:
    robot, rng = get_robot("ur5"), np.random.default_rng(2)
    effects = _effects(robot)
    q = robot.random_configurations(9, rng)
    p = rng.normal(0.0, 1e-3, effects.n_params)
    bounds = np.cumsum([0, *(e.n_params for e in effects.parts)])
    each = sum(e.joint_error(q, p[a:b]) for e, a, b in zip(effects.parts, bounds[:-1], bounds[1:]))
    assert np.allclose(effects.joint_error(q, p), each, atol=0)
    lost = Extension.parse(robot, "lost_motion:wrist_1_joint")
    assert np.array_equal(lost.joint_error(q, np.array([2e-3]))[:, 3], 2e-3 * move_directions(q)[:, 3])
    assert combined([lost]) is lost and combined([]) is None


def _hidden(robot: pincal.Robot, labels: tuple[str, ...], seed: int) -> tuple[pincal.Dataset, pincal.Dataset]:
    """Position data in visiting order from a random truth with the effects ``labels`` hidden: the
    first 70 poses, and the last 20 as a file of their own (its first row's direction unknown)."""
    rng = np.random.default_rng(seed)
    truth = pincal.simulation.truth.random_truth(robot, seed=seed)
    q = robot.random_configurations(90, rng, 0.2)
    parts = [Extension.parse(robot, t) for t in labels]
    truth = pincal.simulation.truth.hide_effects(truth, parts, q, 0.4e-3, seed)
    data = truth.measure(q, noise=3e-5, seed=seed)
    later = pincal.Dataset(robot.joint_names, data.q[70:], data.points[70:])  # a --test file of its own
    return data.subset(np.arange(70)), later


@pytest.mark.parametrize("deliver", ["complete", "joint", "balanced"])
def test_urdf_and_sidecar_of_several_effects_reproduce_the_report(
    get_robot, tmp_path: Path, deliver: str
) -> None:
    """Write the files, read them by contracts.md alone (shared/tools/contract_predict.py, no
    pincal), and get the report's ``after`` and ``exported`` to 1e-6 mm, lost motion included."""
    robot = get_robot("ur5")
    labels = ("lost_motion:shoulder_lift_joint", "gear_harmonic:elbow_joint")
    data, test = _hidden(robot, labels, 4)
    cal = pincal.calibrate(robot, data, test=test, extension="+".join(labels), deliver=deliver)
    outcome = pincal.report.outcome.outcome(cal, data, test)
    urdf = tmp_path / "cal.urdf"
    pincal.write_corrected_urdf(cal, urdf)
    side = json.loads(urdf.with_name("cal.calibration.json").read_text())
    assert [e["effect"] for e in side["extension"]] == ["lost_motion", "gear_harmonic"]
    assert (side["complete"] is not None) == (deliver == "complete")
    for name, rows, after, alone in (
        ("train", data, cal.train_after, outcome.exported.train),
        ("test", test, cal.test_after, outcome.exported.test),
    ):
        csv = tmp_path / f"{name}.csv"
        pincal.write_csv(csv, rows)
        full, urdf_alone = _contract_rms(urdf.with_name("cal.calibration.json"), csv)
        assert after is not None and alone is not None
        assert abs(full - after.rms_mm) <= 1e-6, name
        assert abs(urdf_alone - alone.rms_mm) <= 1e-6, name


def _contract_rms(sidecar: Path, csv: Path) -> tuple[float, float]:
    """The full model's and the URDF alone's RMS [mm] as contract_predict.py prints them."""
    tool = SHARED / "tools" / "contract_predict.py"
    if not tool.exists():
        pytest.skip(f"{tool} is not beside the project")
    out = subprocess.run(
        [sys.executable, str(tool), str(sidecar), str(csv)], capture_output=True, text=True, check=True
    ).stdout.splitlines()
    return tuple(float(line.split("RMS ")[1].split()[0]) for line in out[:2])  # type: ignore[return-value]


def test_a_sidecar_with_several_effects_loads_back(get_robot, tmp_path: Path) -> None:
    robot = get_robot("ur5")
    labels = ("joint_compliance:shoulder_lift_joint", "lost_motion:elbow_joint")
    data, _ = _hidden(robot, labels, 6)
    cal = pincal.calibrate(robot, data, extension="+".join(labels), deliver="joint")
    urdf = tmp_path / "c.urdf"
    pincal.write_corrected_urdf(cal, urdf)
    loaded = pincal.load_calibration(urdf)
    assert loaded.extension is not None and loaded.extension.label == "+".join(labels)
    assert np.allclose(loaded.effect, cal.effect_params, rtol=0, atol=1e-15)
    reached = loaded.reached(data.q)
    assert np.allclose(reached - data.q, cal.extension.joint_error(data.q, cal.effect_params), atol=1e-6)
    poses = loaded.tool_poses(data.q)  # the API gives the fit's predictions, lost motion included
    assert loaded.instrument_T_base is not None
    predicted = np.array([loaded.instrument_T_base.act(p.translation) for p in poses])
    assert np.abs(predicted - cal.problem(data).predict(cal.theta)[0]).max() < 1e-9
    one = loaded.tool_pose(data.q[5], previous=data.q[4])
    assert isinstance(one, pin.SE3) and np.allclose(one.homogeneous, poses[5].homogeneous, atol=1e-12)


def _visited(robot: pincal.Robot, labels: tuple[str, ...], seed: int, n: int = 100) -> pincal.Dataset:
    """``n`` poses in visiting order with the effects ``labels`` hidden, 0.45 mm RMS each."""
    rng = np.random.default_rng(seed)
    truth = pincal.simulation.truth.random_truth(robot, seed=seed)
    q = robot.random_configurations(n, rng, 0.2)
    parts = [Extension.parse(robot, t) for t in labels]
    truth = pincal.simulation.truth.hide_effects(truth, parts, q, 0.45e-3, seed)
    return truth.measure(q, noise=3e-5, seed=seed + 1)


def test_two_hidden_effects_are_both_named_with_their_joints(get_robot) -> None:
    robot = get_robot("ur5")
    labels = ("lost_motion:elbow_joint", "encoder_scale:wrist_1_joint")
    cal = pincal.calibrate(robot, _visited(robot, labels, 11), extension="auto")
    assert cal.extension is not None and cal.choice is not None
    assert sorted(e.label for e in cal.extension.parts) == sorted(labels)
    steps = cal.choice.steps()
    assert [s[0] for s in steps] == [e.label for e in cal.extension.parts]
    assert all(after < before for _, before, after in steps)


def test_an_effect_outside_the_list_is_not_stacked_from_causes_on_its_joint(get_robot) -> None:
    """sin(3q) on the Panda's joint 4 (outside the list): harmonics 1 and 2 of that joint together
    would absorb most of it. A further cause is sought only on other joints, so at most one cause
    is named on the joint and what it leaves stays unexplained, as with one cause."""
    robot = get_robot("panda")
    rng = np.random.default_rng(3)
    truth = pincal.simulation.truth.random_truth(robot, seed=3)
    q = robot.random_configurations(100, rng, 0.2)
    sin3 = Extension(robot, "gear_harmonic", "panda_joint4", 3)
    truth = pincal.simulation.truth.hide_effects(truth, [sin3], q, 0.26e-3, 3)
    data = truth.measure(q, noise=5e-5, seed=4)
    cal = pincal.calibrate(robot, data, extension="auto")
    assert cal.extension is not None and cal.choice is not None
    joints = [e.joint for e in cal.extension.parts]
    assert joints == ["panda_joint4"]
    for step in cal.choice.more:
        assert all(c.extension.joint not in joints for c in step.candidates)
    assert residual_verdict(cal, data, 5e-2).verdict == "unexplained"


def test_rows_in_no_meaningful_order_show_no_lost_motion(get_robot) -> None:
    """The robot has lost motion, but the file's rows were shuffled after the measurement: the
    directions the rows' order gives are not those the robot moved in, and no lost motion pays."""
    robot = get_robot("ur5")
    data = _visited(robot, ("lost_motion:shoulder_lift_joint",), 12)
    shuffled = data.subset(np.random.default_rng(0).permutation(len(data)))
    shuffled = pincal.Dataset(robot.joint_names, shuffled.q, shuffled.points)  # read as a file is
    cal = pincal.calibrate(robot, shuffled, extension="auto")
    named = [] if cal.extension is None else [e.effect for e in cal.extension.parts]
    assert "lost_motion" not in named


def test_no_diagnosis_runs_twice_on_the_same_parameters(get_robot, monkeypatch: pytest.MonkeyPatch) -> None:
    """A round whose re-selected parameters are those of an earlier round repeats its diagnosis
    (the same poses, parameters and options): it is taken, not run again, and reported alike."""
    robot = get_robot("ur5")
    truth, fit, _ = pincal.simulate(robot, n_fit=100, n_test=1, seed=0)
    parts = [
        Extension.parse(robot, t) for t in ("lost_motion:shoulder_lift_joint", "gear_harmonic:elbow_joint")
    ]
    data = pincal.simulation.truth.hide_effects(truth, parts, fit.q, 0.4e-3, 0).measure(
        fit.q, noise=3e-5, seed=1
    )
    runs: list[tuple[object, object]] = []
    original = choice_module._diagnosis

    def counted(*args: object, **further: object) -> object:
        held = further.get("given")
        runs.append((args[4], getattr(held, "label", None)))
        return original(*args, **further)

    monkeypatch.setattr(choice_module, "_diagnosis", counted)
    cal = pincal.calibrate(robot, data, params="auto", extension="auto")
    assert cal.choice is not None and len(cal.choice.rounds) == 2
    assert cal.choice.rounds[0].params == cal.choice.rounds[1].params  # the repeated round
    assert cal.choice.rounds[0] == replace(cal.choice.rounds[1], with_cause=None)
    assert len(runs) == len(set(runs)), runs
