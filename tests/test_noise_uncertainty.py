"""The residual verdict with an estimated noise counts the estimate's uncertainty (issue 40, point 3).

- A correct rigid model, no noise figure, three poses measured three times each: the noise from
  those repeats has 18 degrees of freedom; the verdict draws each null draw's noise from its
  posterior. Seed 6 (25 poses) estimates the noise low, and the verdict that took it as exact
  said ``unexplained``: now ``explained``; over 20 sessions at most one ``unexplained``.
- Fewer than 9 degrees of freedom give no noise figure.
- Pose data: the null's orientation rows are noisy too.
- ``unexplained_mm`` says what it is.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

import pincal
from pincal.auto.residual import HeldOut, noise_estimate, residual_verdict

NOISE = 5e-5  # [m] per axis


@cache
def _ur5() -> pincal.Robot:
    return pincal.load_robot("ur5")


def _repeated(seed: int, n: int, extra: tuple[int, ...] = (0, 0, 1, 1, 2, 2)) -> pincal.Dataset:
    """``n`` poses of a rigid truth, poses 0, 1, 2 measured twice more each (noise 0.05 mm)."""
    _, data, _ = pincal.simulate(_ur5(), n_fit=n, n_test=2, seed=seed, noise=0.0)
    idx = np.r_[np.arange(n), list(extra)]
    points = data.points[idx] + np.random.default_rng(seed + 100).normal(0, NOISE, (len(idx), 3))
    return pincal.Dataset(data.joint_names, data.q[idx], points)


def test_a_low_noise_estimate_does_not_make_a_right_model_unexplained() -> None:
    data = _repeated(6, 25)
    found = noise_estimate(data)
    assert found is not None and found[1] == 18 and found[0] < NOISE
    verdict = residual_verdict(pincal.calibrate(_ur5(), data, params="all"), data)
    assert verdict.noise_source == "estimated" and verdict.verdict == "explained", verdict.how
    assert "18 degrees of freedom" in verdict.how


@pytest.mark.parametrize("n", [25])
def test_a_right_model_is_rarely_unexplained_with_an_estimated_noise(n: int) -> None:
    verdicts = []
    for seed in range(20):
        data = _repeated(seed, n)
        verdicts.append(residual_verdict(pincal.calibrate(_ur5(), data, params="all"), data).verdict)
    assert verdicts.count("unexplained") <= 1, verdicts


def test_too_few_repeats_give_no_noise_figure() -> None:
    """One pose measured twice more (6 degrees of freedom): no noise figure."""
    assert noise_estimate(_repeated(1, 25, (0, 0))) is None
    assert noise_estimate(_repeated(1, 25, (0, 0, 1))) is not None


def test_pose_data_null_has_orientation_noise() -> None:
    """Pose data: the null's rows carry orientation noise of the fit's own size; positions keep
    the noise asked for."""
    robot = _ur5()
    _, data, _ = pincal.simulate(robot, n_fit=40, n_test=2, seed=3, noise=NOISE, rot_noise=2e-4)
    cal = pincal.calibrate(robot, data, params="all")
    held = HeldOut(cal, data, 5, 0)
    rows = held.noise_rows(NOISE, 50, np.random.default_rng(0))
    n = len(data)
    by_pose = rows[: n * 6].reshape(n, 6, 50)
    weight = cal.measurement.rotation_weight
    assert 0.7 < np.std(by_pose[:, 3:, :]) / (2e-4 * weight) < 1.3
    assert 0.9 < np.std(by_pose[:, :3, :]) / NOISE < 1.1


def test_unexplained_mm_says_what_it_is() -> None:
    data = _repeated(2, 25)
    said = residual_verdict(pincal.calibrate(_ur5(), data, params="all"), data).to_dict()
    assert "norm of the 3-D error" in said["unexplained_means"] and "per axis" in said["unexplained_means"]
