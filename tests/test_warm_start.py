"""Warm starts (:mod:`pincal.identify.warm`) change where a fit begins, never its answer.

- A diagnosis (its folds and candidates begun at the fits on all poses) names the same cause, with
  the same cross-validated RMS of the baseline and of every candidate within 1e-6 relative, as
  the same diagnosis with every fit begun at the nominal model; and its fold fits take fewer
  solver steps (else there is nothing warm about it).
- A further cause's diagnosis takes its baseline (fit and cross-validation) from the previous
  step's named cause instead of fitting it again: the choice names the same causes with the same
  cross-validated RMS before and after each, within 1e-6 relative, in fewer fits.
- The nominal model's registration-only fit is solved once per content (poses, set-up): a second
  set-up of the same poses gets the first one's answer, bit for bit what it would have solved,
  and a pose moved by a nanometre is solved again.
- A start carries the registration and a pose's target frame over as the transforms they stand
  for: on another set-up of the same unknowns (other first guesses) it gives the same
  ``instrument_T_base`` and ``tip_T_target``; the unknowns not free keep the nominal value.
"""

from __future__ import annotations

import numpy as np
import pytest

import pincal
import pincal.auto.choice
import pincal.auto.pipeline
import pincal.identify.lm
import pincal.identify.solver
import pincal.identify.warm
from pincal.auto.diagnose import diagnose
from pincal.identify.registrations import REGISTRATIONS
from pincal.identify.solver import register, set_up
from pincal.identify.warm import WarmStart, fits_better
from pincal.kinematics.effects import Extension
from pincal.simulation.truth import hide_effect, hide_effects, random_truth

SAME = 1e-6  # relative agreement of a warm-started and a cold-started figure


@pytest.fixture(scope="module")
def ur5() -> pincal.Robot:
    """The bundled UR5."""
    return pincal.load_robot("ur5")


def hidden_compliance(robot: pincal.Robot, seed: int = 3) -> pincal.Dataset:
    """60 seeded poses of a simulated UR5 with a joint compliance hidden at 0.5 mm RMS."""
    truth, fit, _ = pincal.simulate(robot, n_fit=60, n_test=1, seed=seed)
    ext = Extension.parse(robot, "joint_compliance:shoulder_lift_joint")
    truth = hide_effect(truth, ext, fit.q, 5e-4, seed=seed)
    return truth.measure(fit.q, noise=3e-5, rot_noise=None, seed=seed + 1000)


def counted_steps(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The Jacobian evaluations of every solve made from now on, as a growing list."""
    steps: list[int] = []
    solve = pincal.identify.lm.levenberg_marquardt

    def counting(*args: object, **kwargs: object) -> pincal.identify.lm.OptimizeResult:
        result = solve(*args, **kwargs)  # type: ignore[arg-type]
        steps.append(int(result.njev))
        return result

    monkeypatch.setattr(pincal.identify.solver, "levenberg_marquardt", counting)
    return steps


def test_warm_diagnosis_is_the_cold_one(ur5: pincal.Robot, monkeypatch: pytest.MonkeyPatch) -> None:
    data = hidden_compliance(ur5)
    monkeypatch.setenv("PINCAL_WORKERS", "1")  # every solve in this process, where it is counted
    steps = counted_steps(monkeypatch)
    REGISTRATIONS.clear()  # the two diagnoses solve the same registrations
    warm = diagnose(ur5, data, folds=5, seed=0)
    warm_steps = sum(steps)
    steps.clear()
    REGISTRATIONS.clear()
    with monkeypatch.context() as cold_start:
        cold_start.setattr(WarmStart, "fit", lambda self, problem, nominal, free: nominal)
        cold = diagnose(ur5, data, folds=5, seed=0)
    cold_steps = sum(steps)
    REGISTRATIONS.clear()
    assert warm.cause is not None and cold.cause is not None
    assert warm.cause.extension.label == cold.cause.extension.label
    assert warm.baseline_cv_rms_mm == pytest.approx(cold.baseline_cv_rms_mm, rel=SAME)
    by_label = {c.extension.label: c.cv_rms_mm for c in cold.candidates}
    assert [c.extension.label for c in warm.candidates] == list(by_label)
    for c in warm.candidates:
        assert c.cv_rms_mm == pytest.approx(by_label[c.extension.label], rel=SAME), c.extension.label
    assert warm_steps < cold_steps, f"warm {warm_steps} solver steps, cold {cold_steps}"


def two_hidden_effects(robot: pincal.Robot, seed: int = 11) -> pincal.Dataset:
    """100 poses in visiting order with a lost motion and an encoder scale hidden, 0.45 mm RMS each."""
    q = robot.random_configurations(100, np.random.default_rng(seed), 0.2)
    parts = [Extension.parse(robot, t) for t in ("lost_motion:elbow_joint", "encoder_scale:wrist_1_joint")]
    truth = hide_effects(random_truth(robot, seed=seed), parts, q, 0.45e-3, seed)
    return truth.measure(q, noise=3e-5, seed=seed + 1)


def test_a_further_cause_reuses_the_named_one(ur5: pincal.Robot, monkeypatch: pytest.MonkeyPatch) -> None:
    data = two_hidden_effects(ur5)
    monkeypatch.setenv("PINCAL_WORKERS", "1")  # every fit in this process, where it is counted
    fits: list[int] = []
    fit = pincal.auto.pipeline.calibrate_unjudged

    def counting(*args: object, **kwargs: object) -> pincal.Calibration:
        fits.append(1)
        return fit(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(pincal.auto.pipeline, "calibrate_unjudged", counting)
    reused = pincal.calibrate(ur5, data, extension="auto", deliver="joint")
    n_reused = len(fits)
    fits.clear()
    with monkeypatch.context() as again:
        again.setattr(pincal.auto.choice, "known_baseline", lambda previous, given: None)
        refitted = pincal.calibrate(ur5, data, extension="auto", deliver="joint")
    assert reused.choice is not None and refitted.choice is not None
    steps, expected = reused.choice.steps(), refitted.choice.steps()  # type: ignore[attr-defined]
    assert len(steps) >= 2, "two hidden effects: a further cause is sought on a known baseline"
    assert [s[0] for s in steps] == [s[0] for s in expected]
    for (_, before, after), (_, want_before, want_after) in zip(steps, expected):
        assert before == pytest.approx(want_before, rel=SAME) and after == pytest.approx(want_after, rel=SAME)
    assert n_reused < len(fits), f"{n_reused} fits reusing the named cause, {len(fits)} without"


@pytest.mark.parametrize("measure", ["position", "pose"])
def test_start_carries_the_transforms(ur5: pincal.Robot, measure: str) -> None:
    rot_noise = 1e-4 if measure == "pose" else None
    _, fit, _ = pincal.simulate(ur5, n_fit=30, n_test=1, seed=5, rot_noise=rot_noise)
    full = set_up(ur5, fit, "placements", measure)
    rng = np.random.default_rng(0)
    theta = register(full) + 1e-3 * rng.standard_normal(full.problem.n_params)
    start = WarmStart(full.problem.names, full.problem.n_model, full.problem.measurement, theta)
    fold = set_up(ur5, fit.subset(np.arange(0, 30, 2)), "placements", measure)  # other first guesses
    problem = fold.problem
    assert problem.measurement.instrument_T_base != full.problem.measurement.instrument_T_base
    nominal = register(fold)
    free = np.ones(problem.n_params, dtype=bool)
    free[:3] = False
    begun = start.fit(problem, nominal, free)
    _, reg, tool = full.problem.split(theta)
    _, reg_here, tool_here = problem.split(begun)
    assert np.allclose(reg_here.homogeneous, reg.homogeneous, atol=1e-12)
    assert np.allclose(tool_here.homogeneous, tool.homogeneous, atol=1e-12)
    assert np.array_equal(begun[:3], nominal[:3])
    assert np.array_equal(begun[3 : problem.model.n_params], theta[3 : problem.model.n_params])


def test_the_registration_is_solved_once_per_content(
    ur5: pincal.Robot, monkeypatch: pytest.MonkeyPatch
) -> None:
    _, fit, _ = pincal.simulate(ur5, n_fit=30, n_test=1, seed=7)
    REGISTRATIONS.clear()
    steps = counted_steps(monkeypatch)
    first = register(set_up(ur5, fit, "placements"))
    solved = len(steps)
    scale = Extension.parse(ur5, "encoder_scale:elbow_joint")
    again = register(set_up(ur5, fit, "placements", extension=scale))
    assert len(steps) == solved, "the same poses and set-up: no second solve"
    assert np.array_equal(again[-9:], first[-9:]) and not again[:-9].any()
    REGISTRATIONS.clear()
    assert np.array_equal(register(set_up(ur5, fit, "placements")), first)  # what it would have solved
    moved = fit.subset(np.arange(30))
    moved.points[0, 0] += 1e-9
    solved = len(steps)
    register(set_up(ur5, moved, "placements"))
    assert len(steps) > solved, "other poses: solved again"


def test_a_start_worse_than_nominal_is_not_taken(ur5: pincal.Robot) -> None:
    """A fit whose registration turned far (poses that determine it poorly) is no start: the
    fit begins at the nominal model, where a start that fits better is taken."""
    _, fit, _ = pincal.simulate(ur5, n_fit=20, n_test=1, seed=2)
    setup = set_up(ur5, fit, "placements")
    problem, nominal = setup.problem, register(setup)
    turned = nominal.copy()
    turned[problem.n_model + 3 : problem.n_model + 6] += (0.0, 2.3, -0.1)  # the registration's rotation
    assert not fits_better(problem, turned, nominal)
    solved = pincal.calibrate(ur5, fit, "placements")
    assert fits_better(problem, solved.theta, nominal)
