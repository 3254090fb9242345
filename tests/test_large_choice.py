"""Many poses: ``calibrate`` and ``diagnose`` make their automatic choice on a random subset, say
so first, and fit the chosen model on every pose (the subset's size lowered here)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from cli_run import run

import pincal
import pincal.auto.large_choice as large_choice


@pytest.fixture()
def rows(tmp_path: Path) -> Path:
    ur5 = pincal.load_robot("ur5")
    q = ur5.random_configurations(90, np.random.default_rng(8), 0.05)
    path = tmp_path / "ur5.csv"
    pincal.write_csv(path, pincal.random_truth(ur5, seed=9).measure(q, 3e-5, seed=10))
    return path


def test_diagnose_makes_its_choice_on_a_subset_and_judges_every_pose(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], rows: Path, tmp_path: Path
) -> None:
    monkeypatch.setattr(large_choice, "CHOICE_POSES", 60)
    code, out, err = run(capsys, "diagnose", "ur5", rows, "--json", tmp_path / "d.json")
    assert code == 0, err
    assert out.splitlines()[0].startswith("90 poses: the automatic choice")
    assert "random subset of 60 of them" in out.splitlines()[0]
    found = json.loads((tmp_path / "d.json").read_text())
    assert found["candidates"]  # the diagnosis ran, on the subset


def test_the_choice_on_a_subset_is_the_subsets_and_the_fit_is_on_every_pose(
    monkeypatch: pytest.MonkeyPatch, rows: Path
) -> None:
    ur5 = pincal.load_robot("ur5")
    data = pincal.read_csv(rows, ur5.joint_names)
    monkeypatch.setattr(large_choice, "CHOICE_POSES", 60)
    said: list[str] = []
    cal = large_choice.calibrate_choosing(
        pincal.calibrate, ur5, data, said.append, params="auto", extension="none"
    )
    keep = np.sort(np.random.default_rng(0).choice(len(data), 60, replace=False))
    on_subset = pincal.calibrate(ur5, data.subset(keep), params="auto", extension="none")
    assert len(said) == 1 and said[0].startswith("90 poses")
    assert cal.choice is not None and on_subset.choice is not None
    assert cal.choice.params == on_subset.choice.params
    assert cal.n_poses == 90
