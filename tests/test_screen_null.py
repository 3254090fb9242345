"""Tests of the diagnosis' chance control (:mod:`pincal.auto.screen_null`).

- The null's screen is the diagnosis' screen: fed the geometric fit's own residuals, its
  cross-validated RMS of every candidate is :meth:`Linearised.screen`'s (position, pose and
  distance data).
- The test holds its level: noise drawn apart from the null, taken as the data, gets a family-wise
  p-value under 0.05 about 5 % of the time (the draws are exchangeable with the data's best gain).
- A hidden effect gets the smallest p-value the draws allow, and the diagnosis names it.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

import pincal
from pincal.auto.bordered import least_squares_steps
from pincal.auto.screen_null import ALPHA, _noise, draws_for, held_out_rms, screen_null
from pincal.auto.screening import Linearised
from pincal.kinematics.effects import EFFECTS, Extension


def _linearised(robot: pincal.Robot, measure: str, seed: int = 3) -> tuple[Linearised, list[Extension]]:
    """The geometric fit of 30 simulated poses (nothing hidden) linearised with every effect of
    ``EFFECTS`` on the elbow and the shoulder."""
    truth, fit, _ = pincal.simulate(robot, n_fit=30, n_test=0, seed=seed)
    rot = 3e-4 if measure == "pose" else None
    data = truth.measure(fit.q, 3e-5, rot, seed=seed + 1)
    base = pincal.calibrate(robot, data, measure=measure, extension="none")
    pool = [
        Extension.parse(robot, f"{effect}:{joint}")
        for effect in EFFECTS
        for joint in ("shoulder_lift_joint", "elbow_joint")
    ]
    return Linearised(base, data, 5, 0, pool), pool


@pytest.mark.parametrize("measure", ["position", "pose", "distance"])
def test_the_null_screens_as_the_diagnosis_screens(
    get_robot: Callable[[str], pincal.Robot], measure: str
) -> None:
    lin, pool = _linearised(get_robot("ur5"), measure)
    design = lin.design
    assert design is not None
    base = np.arange(len(lin.free))
    takes = [base] + [np.concatenate([base, lin.columns[ext.label]]) for ext in pool]
    rms = held_out_rms(design, takes, lin.residuals[:, None], lin.kind.width)[:, 0] * 1e3
    expected = [lin.screen().cv_rms_mm] + [lin.screen(ext).cv_rms_mm for ext in pool]
    np.testing.assert_allclose(rms, expected, rtol=1e-8)


def test_the_screen_null_holds_its_level(get_robot: Callable[[str], pincal.Robot]) -> None:
    lin, pool = _linearised(get_robot("ur5"), "position")
    null = screen_null(lin, pool, 199, seed=0)
    assert null is not None and null.draws == 199 == draws_for(1) and null.candidates == len(pool)
    design = lin.design
    assert design is not None
    base = np.arange(len(lin.free))
    takes = [base] + [np.concatenate([base, lin.columns[ext.label]]) for ext in pool]
    fresh = _noise(lin, design, 400, np.random.default_rng(99))  # noise the null never drew
    rms = held_out_rms(design, takes, fresh, lin.kind.width)
    best = np.max(rms[0] / rms[1:], axis=0)
    rate = np.mean([null.p_value(g) < 0.05 for g in best])
    assert 0.01 <= rate <= 0.10, rate  # 5 %: 20 of 400, binomial spread ±2.2 %


def test_a_hidden_effect_gets_the_smallest_p_value(get_robot: Callable[[str], pincal.Robot]) -> None:
    from test_diagnose import hidden_effect_data

    from pincal.auto.diagnose import diagnose

    robot = get_robot("ur5")
    label = "gear_harmonic:shoulder_lift_joint"
    _, data = hidden_effect_data(robot, label, 3e-4, seed=1, n_poses=60)
    d = diagnose(robot, data)
    assert d.cause is not None and d.cause.extension.label == label
    assert d.cause.p_value == pytest.approx(1 / 200) and d.cause.p_value < ALPHA
    assert d.null_draws == 199 and "under the null of the screen" in d.to_dict()["selection"]


def test_a_large_problem_draws_its_null_on_a_subset(
    get_robot: Callable[[str], pincal.Robot], monkeypatch: pytest.MonkeyPatch
) -> None:
    import pincal.auto.screen_null as screen_null_module
    from pincal.identify import chunked

    lin, pool = _linearised(get_robot("ur5"), "position")
    monkeypatch.setattr(chunked, "LARGE_POSES", 20)  # the 30 poses are a large problem
    monkeypatch.setattr(chunked, "BLOCK_POSES", 10)
    monkeypatch.setattr(screen_null_module, "NULL_MAX_POSES", 20)
    large = Linearised(lin.base, lin.data, 5, 0, pool)
    assert large.large and large.design is None
    null = screen_null(large, pool, 99, seed=0)
    assert null is not None and null.draws == 99 and np.all(null.gains > 0)
    whole = screen_null(lin, pool, 99, seed=0)
    assert whole is not None and not np.array_equal(whole.gains, null.gains)


def test_the_bordered_steps_are_the_least_squares_steps() -> None:
    """Each candidate solved on the baseline's factor gives NumPy's least-squares step; a
    candidate that repeats a baseline column (a singular take) gets the least-squares step too."""
    rng = np.random.default_rng(3)
    jac = rng.standard_normal((80, 14))
    jac[:, 13] = jac[:, 2]  # the last candidate repeats a baseline column
    gram, moment = jac.T @ jac, jac.T @ rng.standard_normal((80, 5))
    base = np.arange(8)
    takes = [base, np.r_[base, 8], np.r_[base, 9, 10], np.r_[base, 11, 12], np.r_[base, 13]]
    steps = least_squares_steps(gram, moment, takes)
    for take, step in zip(takes, steps, strict=True):
        expected = np.linalg.lstsq(gram[np.ix_(take, take)], moment[take], rcond=1e-12)[0]
        np.testing.assert_allclose(step, expected, rtol=1e-9, atol=1e-12)
