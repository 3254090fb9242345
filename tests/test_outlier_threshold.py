"""The outlier screen's threshold on many poses: noise alone flags no pose, a real outlier is found."""

from __future__ import annotations

import numpy as np
import pytest

from pincal.identify.outliers import chi_sf, far_off, noise_threshold, pose_sf
from pincal.options import THRESHOLD


@pytest.mark.parametrize("k", [1, 2, 3, 6])
def test_chi_survival_matches_draws(k: int) -> None:
    norms = np.linalg.norm(np.random.default_rng(k).standard_normal((400_000, k)), axis=1)
    for x in (0.5, 1.5, 2.5, 3.5):
        drawn = float(np.mean(norms > x))
        assert chi_sf(x, k) == pytest.approx(drawn, abs=4 * np.sqrt(drawn * (1 - drawn) / len(norms)) + 1e-5)


def test_the_threshold_holds_its_family_wise_level_on_noise() -> None:
    """200 data sets of 5,000 position poses of pure noise, level 0.1: about 20 flag a pose."""
    rng = np.random.default_rng(7)
    level, n, sets = 0.1, 5000, 200
    threshold = noise_threshold(n, 3, level)
    flagged = sum(
        bool(far_off(np.linalg.norm(rng.standard_normal((n, 3)), axis=1), threshold).any())
        for _ in range(sets)
    )
    spread = np.sqrt(sets * level * (1 - level))
    assert abs(flagged - sets * level) <= 3.5 * spread


def _pose_noise(rng: np.random.Generator, n: int, ratio: float) -> np.ndarray:
    """Scores of ``n`` poses of pure noise: position rows of unit noise, rotation rows ``ratio``."""
    return np.linalg.norm(
        np.hstack([rng.standard_normal((n, 3)), ratio * rng.standard_normal((n, 3))]), axis=1
    )


@pytest.mark.parametrize("ratio", [0.5, 2.0])
def test_pose_survival_matches_draws(ratio: float) -> None:
    scores = _pose_noise(np.random.default_rng(11), 400_000, ratio)
    for x in (1.5, 3.0, 5.0, 6.0):
        drawn = float(np.mean(scores > x))
        assert pose_sf(x, ratio) == pytest.approx(
            drawn, abs=4 * np.sqrt(drawn * (1 - drawn) / len(scores)) + 1e-5
        )
    assert pose_sf(3.0, 1.0) == chi_sf(3.0, 6)


def test_the_pose_threshold_holds_its_level_when_rotation_noise_differs() -> None:
    """200 data sets of 5,000 pose scores whose rotation rows' noise is twice the position rows',
    level 0.1: about 20 flag a pose with the threshold of that ratio; six equal components' flags
    far more."""
    rng = np.random.default_rng(5)
    level, n, sets = 0.1, 5000, 200
    fitting, equal = noise_threshold(n, 6, level, ratio=2.0), noise_threshold(n, 6, level)
    flagged, naive = 0, 0
    for _ in range(sets):
        scores = _pose_noise(rng, n, 2.0)
        flagged += int(far_off(scores, fitting).any())
        naive += int(far_off(scores, equal).any())
    spread = np.sqrt(sets * level * (1 - level))
    assert abs(flagged - sets * level) <= 3.5 * spread
    assert naive > sets * level + 3.5 * spread


def test_many_poses_raise_the_threshold_few_keep_it() -> None:
    assert noise_threshold(1000, 3) < THRESHOLD  # the screen's 6 robust sigma rules
    assert noise_threshold(10**6, 3) > THRESHOLD + 0.8  # noise reaches 6 among a million poses
    assert noise_threshold(10**6, 6) < noise_threshold(10**6, 3) < noise_threshold(10**6, 1)


def test_a_million_noise_poses_flag_none_and_a_gross_error_is_found() -> None:
    """The fixed 6 robust sigma flags noise poses among 10⁶ in about half of the data sets."""
    rng = np.random.default_rng(3)
    fixed = 0
    for _ in range(6):
        scores = np.linalg.norm(rng.standard_normal((10**6, 3)), axis=1)
        fixed += int(far_off(scores, THRESHOLD).any())
        assert not far_off(scores, max(THRESHOLD, noise_threshold(len(scores), 3))).any()
    assert fixed >= 1
    scores[12345] = 20.0  # a lost beam: 20 sigma off
    assert np.flatnonzero(far_off(scores, max(THRESHOLD, noise_threshold(len(scores), 3)))).tolist() == [
        12345
    ]
