"""The outlier screen's threshold on many poses: noise alone flags no pose, a real outlier is found."""

from __future__ import annotations

import numpy as np
import pytest

from pincal.identify.outliers import chi_sf, far_off, noise_threshold
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
