"""The report names the rows each figure scored (``train.rows``, ``test.rows``), so that a held-out
figure can be checked: the poses of those rows, and only they, give the figure."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from cli_run import run

import pincal
from pincal.identify.evaluation import evaluate

FAST = ("--params", "all", "--nested", "no", "--extend", "none")
N = 40
OUTLIER_ROW = 5  # 1-based data row moved by 20 mm


@pytest.fixture(scope="module")
def data_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """UR5 positions (40 poses, 0.03 mm noise) with comment lines, and one gross outlier."""
    ur5 = pincal.load_robot("ur5")
    q = ur5.random_configurations(N, np.random.default_rng(11), 0.05)
    data = pincal.random_truth(ur5, seed=12).measure(q, 3e-5, seed=13)
    points = data.points.copy()
    points[OUTLIER_ROW - 1] += 0.02
    path = tmp_path_factory.mktemp("rows") / "pos.csv"
    pincal.write_csv(path, pincal.Dataset(data.joint_names, data.q, points))
    lines = path.read_text().splitlines()
    path.write_text("\n".join(["# tracker session 1", lines[0], "# first poses", *lines[1:]]) + "\n")
    return path


def _report(capsys: pytest.CaptureFixture[str], tmp_path: Path, *args: str | Path) -> dict:
    out = tmp_path / "r.json"
    code, _, err = run(capsys, "calibrate", "ur5", *args, *FAST, "--report", out)
    assert code == 0, err
    return json.loads(out.read_text())


@pytest.mark.parametrize("seed", [0, 3])
def test_holdout_rows_partition_the_file_and_reproduce_the_figures(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, data_file: Path, seed: int
) -> None:
    report = _report(capsys, tmp_path, data_file, "--holdout", "0.3", "--seed", str(seed))
    train, test = report["train"]["rows"], report["test"]["rows"]
    excluded = [pose["row"] for pose in report["excluded_poses"]]
    assert OUTLIER_ROW in excluded or OUTLIER_ROW in test
    assert not set(excluded) & set(train)
    assert sorted(train + test + excluded) == list(range(1, N + 1))
    assert len(train) == report["train"]["after"]["n"] and len(test) == report["test"]["after"]["n"]
    ur5 = pincal.load_robot("ur5")
    full = pincal.read_csv(data_file, ur5.joint_names)
    cal = pincal.calibrate(
        ur5, full.subset(np.array(train) - 1), params="all", extension="none", outliers=None
    )
    held = full.subset(np.array(test) - 1)
    stats = evaluate(cal.model, cal.measurement, cal.theta, held, cal.extension)
    assert stats.rms_mm == pytest.approx(report["test"]["after"]["rms_mm"], rel=1e-6)


def test_a_test_file_rows_are_its_own(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, data_file: Path
) -> None:
    report = _report(capsys, tmp_path, data_file, "--test", data_file)
    assert report["test"]["rows"] == list(range(1, N + 1))  # the held-out file is not screened
    assert OUTLIER_ROW not in report["train"]["rows"]
    assert len(report["train"]["rows"]) == N - len(report["excluded_poses"])
