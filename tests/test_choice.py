"""Tests of ``params="auto"`` and ``extension="auto"`` (:mod:`pincal.auto.choice`), in the API and in
``pincal calibrate``, which must be the same code path.

- Few poses, a truth wrong in a few parameters: ``auto`` fits a subset; the parameters left out
  stay exactly nominal in the calibration and in the corrected URDF; the report says what was
  kept and left out, with the leave-one-out path and the scores of the chosen set and of all.
- Many varied poses, every parameter wrong: ``auto`` keeps every parameter and its fit is the
  ``all`` fit.
- ``--params NAME,...`` and ``--params @FILE`` fit exactly the names given.
- ``extension="auto"`` names a hidden joint compliance and includes it; on clean data it names
  nothing and the model is the geometric one.
- The nested cross-validation runs by default on small data, is skipped (with the reason) on
  large data, and judges the procedure: its held-out error is that of refitting without each fold.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pincal
from pincal.auto.choice import NESTED_MAX_POSES
from pincal.auto.crossval import cross_validate
from pincal.auto.screen_null import ALPHA
from pincal.cli import main
from pincal.kinematics.effects import Extension
from pincal.kinematics.models import PlacementsModel
from pincal.report.summary_table import OFFSETS_CAUSE
from pincal.simulation.truth import TrueRobot, hide_effect

NOISE = 3e-5  # 1σ of each measured coordinate [m]


def sparse_truth(robot: pincal.Robot, n_fit: int, seed: int) -> tuple[pincal.Dataset, pincal.Dataset]:
    """A truth wrong by 1 mm / 2 mrad in four placement parameters; fitted and held-out data."""
    rng = np.random.default_rng(seed)
    base = pincal.random_truth(robot, seed)
    model = PlacementsModel(robot)
    x = np.zeros(model.n_params)
    for name in ("shoulder_lift_joint.tz", "elbow_joint.rx", "wrist_1_joint.ty", "wrist_2_joint.rz"):
        k = model.names.index(name)
        x[k] = rng.choice([-1.0, 1.0]) * (1e-3 if model.units[k] == "m" else 2e-3)
    truth = TrueRobot(model, x, base.instrument_T_base, base.tool)
    q = robot.random_configurations(n_fit + 100, rng, margin=0.05)
    return truth.measure(q[:n_fit], NOISE, seed=seed + 1), truth.measure(q[n_fit:], NOISE, seed=seed + 2)


def run(capsys: pytest.CaptureFixture[str], *argv: object) -> tuple[int, str, str]:
    """``pincal.cli.main(argv)``: exit code, stdout and stderr."""
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_auto_fits_a_subset_and_leaves_the_rest_nominal(get_robot: Callable[[str], pincal.Robot]) -> None:
    robot = get_robot("ur5")
    fit, test = sparse_truth(robot, 30, seed=3)
    auto = pincal.calibrate(robot, fit, params="auto", test=test)
    every = pincal.calibrate(robot, fit, params="all", test=test)
    choice = auto.choice
    assert choice is not None and choice.selection is not None and choice.params is not None
    n_model = auto.model.n_params
    chosen = np.isin(auto.names[:n_model], choice.params)
    assert 0 < chosen.sum() < every.identifiability.n_identifiable - 9  # registration and tool: 9
    np.testing.assert_array_equal(auto.x[~chosen], 0.0)  # left out: exactly nominal
    assert set(choice.left_out).isdisjoint(choice.params)
    assert len(choice.params) + len(choice.left_out) == len(choice.selection.path) - 1
    assert auto.test_after is not None and every.test_after is not None
    assert auto.test_after.rms_mm < every.test_after.rms_mm  # 30 poses: the full model overfits
    assert choice.selection.cv_rms_mm < choice.selection.all_cv_rms_mm


def test_corrected_urdf_holds_the_chosen_model(
    tmp_path: Path, get_robot: Callable[[str], pincal.Robot]
) -> None:
    robot = get_robot("ur5")
    fit, _ = sparse_truth(robot, 30, seed=4)
    cal = pincal.calibrate(robot, fit, params="auto")
    urdf, _ = pincal.write_corrected_urdf(cal, tmp_path / "ur5_cal.urdf")
    reloaded = pincal.load_calibration(urdf)
    q = robot.random_configurations(50, np.random.default_rng(0))
    rot, pos = cal.base_T_tip(q)
    tool = cal.split()[2].translation
    reached = np.array([reloaded.tool_pose(qi).translation for qi in q])
    np.testing.assert_allclose(reached, pos + rot @ tool, atol=1e-9)


def test_many_varied_poses_keep_every_parameter(get_robot: Callable[[str], pincal.Robot]) -> None:
    robot = get_robot("ur5")
    _, fit, test = pincal.simulate(robot, n_fit=150, n_test=100, seed=5)
    auto = pincal.calibrate(robot, fit, params="auto", test=test)
    every = pincal.calibrate(robot, fit, params="all", test=test)
    assert auto.choice is not None and auto.choice.params is None
    np.testing.assert_allclose(auto.theta, every.theta, atol=1e-12)
    assert auto.identifiability.n_identifiable == every.identifiability.n_identifiable


def test_cli_params_names_and_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], get_robot: Callable[[str], pincal.Robot]
) -> None:
    robot = get_robot("ur5")
    fit, _ = sparse_truth(robot, 40, seed=6)
    data = tmp_path / "data.csv"
    pincal.write_csv(data, fit)
    names = ["shoulder_lift_joint.tz", "elbow_joint.rx", "wrist_1_joint.ty"]
    listing = tmp_path / "params.txt"
    listing.write_text("# the parameters to fit\n" + "\n".join(names) + "\n")
    for i, spec in enumerate([",".join(names), f"@{listing}"]):
        report = tmp_path / f"r{i}.json"
        code, out, err = run(capsys, "calibrate", "ur5", data, "--params", spec, "--report", report)
        assert code == 0, err
        doc = json.loads(report.read_text())
        fitted = {p["name"] for p in doc["parameters"] if p["identifiable"] and "." in p["name"]}
        fitted = {n for n in fitted if not n.startswith(("instrument.", "tool."))}
        assert fitted == set(names)
        assert doc["choice"]["params"] == "given"
    code, _, err = run(capsys, "calibrate", "ur5", data, "--params", "elbow_joint.nope")
    assert code == 2 and err.startswith("pincal: error: unknown parameters elbow_joint.nope")
    code, _, err = run(capsys, "calibrate", "ur5", data, "--params", f"@{tmp_path / 'missing.txt'}")
    assert code == 2 and "cannot read the parameter list" in err


def test_cli_default_is_auto_and_reports_the_choice(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], get_robot: Callable[[str], pincal.Robot]
) -> None:
    robot = get_robot("ur5")
    fit, test = sparse_truth(robot, 30, seed=7)
    data, held = tmp_path / "data.csv", tmp_path / "test.csv"
    pincal.write_csv(data, fit)
    pincal.write_csv(held, test)
    report = tmp_path / "r.json"
    code, out, err = run(capsys, "calibrate", "ur5", data, "--test", held, "--report", report)
    assert code == 0, err
    doc = json.loads(report.read_text())
    choice = doc["choice"]
    api = pincal.calibrate(robot, fit, params="auto", extension="auto", outliers=6.0, test=test)
    assert api.choice is not None and api.choice.params is not None
    assert choice["params"] == "auto" and choice["kept"] == list(api.choice.params)
    assert choice["cv_rms_mm"]["chosen"] < choice["cv_rms_mm"]["all"]
    assert [s["added"] for s in choice["selection"]["path"]][1:] == [*choice["kept"], *choice["left_out"]]
    # the diagnosis ran (extension "auto" by default) and named nothing in this rigid truth
    assert choice["cause"] == "none" and choice["extension"] == "auto" and choice["diagnosis"] is not None
    assert len(fit) <= NESTED_MAX_POSES and choice["nested"]["folds"] == 5
    assert doc["test"]["after"]["rms_mm"] == pytest.approx(api.test_after.rms_mm, rel=1e-9)
    assert "parameters:" in out and "chosen by leave-one-out" in out and "nested 5-fold" in out


def test_nested_is_skipped_on_large_data_and_says_why(get_robot: Callable[[str], pincal.Robot]) -> None:
    robot = get_robot("ur5")
    _, fit, _ = pincal.simulate(robot, n_fit=NESTED_MAX_POSES + 5, n_test=1, seed=8)
    cal = pincal.calibrate(robot, fit, params="auto", nested=None)
    assert cal.choice is not None and cal.choice.nested is None
    assert "more than" in cal.choice.nested_note


def test_nested_equals_refitting_without_each_fold(get_robot: Callable[[str], pincal.Robot]) -> None:
    robot = get_robot("ur5")
    fit, _ = sparse_truth(robot, 30, seed=9)
    cal = pincal.calibrate(robot, fit, params="auto", nested=True, folds=3)
    assert cal.choice is not None and cal.choice.nested is not None
    by_hand = cross_validate(robot, fit, folds=3, params="auto")
    assert cal.choice.nested.after.rms_mm == pytest.approx(by_hand.after.rms_mm, rel=1e-9)
    first = by_hand.calibrations[0].choice
    assert first is not None and first.selection is not None  # each fold chose on its own poses


def test_extend_auto_names_a_hidden_compliance(get_robot: Callable[[str], pincal.Robot]) -> None:
    robot = get_robot("ur5")
    truth, fit, _ = pincal.simulate(robot, n_fit=80, n_test=1, seed=101)
    ext = Extension.parse(robot, "joint_compliance:shoulder_lift_joint")
    truth = hide_effect(truth, ext, fit.q, 0.5e-3, seed=101)
    data = truth.measure(fit.q, noise=NOISE, rot_noise=None, seed=1101)
    cal = pincal.calibrate(robot, data, params="auto", extension="auto")
    assert cal.choice is not None and cal.extension is not None
    assert cal.extension.label == "joint_compliance:shoulder_lift_joint"
    assert cal.choice.gain > 3.0
    assert cal.choice.rounds[0].cause == "joint_compliance:shoulder_lift_joint"
    true_c = float(truth.effect[0])
    assert cal.effect_params[0] == pytest.approx(true_c, rel=0.1)


def test_each_round_names_its_cause_at_its_own_level(
    get_robot: Callable[[str], pincal.Robot], monkeypatch: pytest.MonkeyPatch
) -> None:
    import pincal.auto.choice as choice_module

    robot = get_robot("ur5")
    truth, fit, _ = pincal.simulate(robot, n_fit=30, n_test=1, seed=1)
    ext = Extension.parse(robot, "joint_compliance:shoulder_lift_joint")
    truth = hide_effect(truth, ext, fit.q, 0.5e-3, seed=1)
    data = truth.measure(fit.q, noise=NOISE, rot_noise=None, seed=1001)
    steps: list[int] = []
    diagnosis = choice_module._diagnosis

    def recorded(*args: Any, **kwargs: Any) -> Any:
        steps.append(kwargs.get("step", 1))
        return diagnosis(*args, **kwargs)

    monkeypatch.setattr(choice_module, "_diagnosis", recorded)
    cal = pincal.calibrate(robot, data, params="auto", extension="auto")
    assert cal.choice is not None
    rounds = cal.choice.rounds
    assert len(rounds) == 2 and rounds[0].params != rounds[1].params  # the cause re-selected them
    assert rounds[0].cause == rounds[1].cause == ext.label
    assert steps[:2] == [1, 2]  # the second round: the second test
    assert [r.level for r in rounds] == pytest.approx([ALPHA, ALPHA / 2])
    assert rounds[1].to_dict()["level"] == pytest.approx(ALPHA / 2)


def test_extend_auto_names_nothing_on_clean_data(get_robot: Callable[[str], pincal.Robot]) -> None:
    robot = get_robot("ur5")
    _, fit, _ = pincal.simulate(robot, n_fit=60, n_test=1, seed=11)
    cal = pincal.calibrate(robot, fit, params="auto", extension="auto")
    assert cal.choice is not None and cal.choice.extension is None and cal.extension is None
    assert len(cal.choice.rounds) == 1 and cal.choice.rounds[0].cause is None
    plain = pincal.calibrate(robot, fit, params="auto")
    np.testing.assert_allclose(cal.theta, plain.theta, atol=1e-12)


@pytest.mark.parametrize("seed", [1, 2])
def test_a_cause_named_with_the_offsets_model_is_said_to_stand_in_for_geometry(
    get_robot: Callable[[str], pincal.Robot], seed: int
) -> None:
    """``--model offsets`` fits no geometry, so the diagnosis may name an effect that soaks up
    the truth's joint placement errors (seed 2 here: a gear harmonic on a rigid truth); the
    summary says so whenever a cause is named with that model, and only then."""
    robot = get_robot("ur5")
    _, fit, _ = pincal.simulate(robot, n_fit=40, n_test=0, seed=seed)
    cal = pincal.calibrate(robot, fit, "offsets", params="auto", extension="auto")
    said = OFFSETS_CAUSE in pincal.summary(cal, fit)
    assert said == (cal.extension is not None)
    assert said == (seed == 2)
    placements = pincal.calibrate(robot, fit, "placements", params="auto", extension="auto")
    assert placements.extension is None and OFFSETS_CAUSE not in pincal.summary(placements, fit)
