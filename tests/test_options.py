"""Numeric options, plan's candidates, compensate's inputs and small motions in degrees (issue 17).

Before, ``--rotation-weight nan|inf|1e300`` ended in a traceback from the solver, ``--outliers
nan`` or ``-1`` was taken silently, ``plan --candidates 10000000`` ran out of memory, compensate
took zero quaternions and a sidecar matrix that is no rotation (or holds NaN), and ``--degrees``
data that moved every joint less than ±6.3° (a real small-motion experiment) was refused as
"looks like radians". Each case must end in exit code 0 with the right result, or exit code 2
with one ``pincal: error:`` line naming the option or the row.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import pincal
import pincal.export.urdf_writer
import pincal.planning.candidates
from pincal.cli import build_parser, main
from pincal.simulation.truth import random_truth

BAD = ["nan", "inf", "-inf", "1e300", "abc"]
#: (command line before the option, option, values refused)
REFUSED = [
    (["calibrate", "ur5", "d.csv"], "--rotation-weight", [*BAD, "-1", "0", "1e4"]),
    (["calibrate", "ur5", "d.csv"], "--outliers", ["nan", "inf", "-1", "x"]),
    (["calibrate", "ur5", "d.csv"], "--holdout", ["nan", "inf", "0", "1", "1.5", "-0.1"]),
    (["calibrate", "ur5", "d.csv"], "--folds", ["1", "0", "-3", "2.5", "nan", "1e3"]),
    (["calibrate", "ur5", "d.csv"], "--seed", ["-1", "1.5", "nan"]),
    (["calibrate", "ur5", "d.csv"], "--tool-point", ["nan,0,0", "1e300,0,0", "1,2", "inf,0,0"]),
    (["calibrate", "ur5", "d.csv"], "--payload", ["nan,0,0,0", "-1,0,0,0", "1e300,0,0,0", "1,inf,0,0"]),
    (["diagnose", "ur5", "d.csv"], "--rotation-weight", BAD),
    (["diagnose", "ur5", "d.csv"], "--folds", ["1", "nan"]),
    (["plan", "ur5", "-o", "p.csv"], "--poses", ["0", "-1", "1e3", "nan", "2.5"]),
    (["plan", "ur5", "--poses", "10", "-o", "p.csv"], "--candidates", ["0", "-5", "nan", "1e7"]),
    (["plan", "ur5", "--poses", "10", "-o", "p.csv"], "--clearance", [*BAD, "-1e4"]),
    (["plan", "ur5", "--poses", "10", "--instrument", "1,0,0", "-o", "p.csv"], "--reach", [*BAD, "0", "-1"]),
    (["plan", "ur5", "--poses", "10", "-o", "p.csv"], "--instrument", ["nan,0,0", "1e300,0,0"]),
]
CASES = [(before, option, value) for before, option, values in REFUSED for value in values]


def _one_line(capfd: pytest.CaptureFixture[str], code: int, *words: str) -> str:
    captured = capfd.readouterr()
    assert code == 2, (code, captured.out, captured.err)
    assert "Traceback" not in captured.out + captured.err
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("pincal: error: "), captured.err
    for word in words:
        assert word in lines[0], (word, lines[0])
    return lines[0]


@pytest.mark.parametrize(("before", "option", "value"), CASES, ids=[f"{c[1]}={c[2]}" for c in CASES])
def test_a_bad_number_is_one_argparse_line(
    before: list[str], option: str, value: str, capfd: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """Refused while the command line is read (no file is opened): the line names the option."""
    args = [a if a not in ("d.csv", "p.csv") else str(tmp_path / a) for a in before]
    capfd.readouterr()
    _one_line(capfd, main([*args, f"{option}={value}"]), option)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("value", ["-1", "100000", "nan"])
def test_threads_is_bounded(value: str, capfd: pytest.CaptureFixture[str]) -> None:
    _one_line(capfd, main([f"--threads={value}", "demo"]), "--threads")


@pytest.mark.parametrize(
    ("option", "value", "expected"),
    [
        ("--rotation-weight", "1000", 1000.0),
        ("--rotation-weight", "1e-9", 1e-9),
        ("--outliers", "0", 0.0),
        ("--holdout", "0.5", 0.5),
        ("--folds", "2", 2),
        ("--seed", "0", 0),
    ],
)
def test_values_at_the_edge_of_the_range_are_accepted(option: str, value: str, expected: float) -> None:
    args = build_parser().parse_args(["calibrate", "ur5", "d.csv", option, value])
    assert getattr(args, option.lstrip("-").replace("-", "_")) == expected


@pytest.fixture(scope="module")
def ur5() -> pincal.Robot:
    return pincal.load_robot("ur5")


def test_extreme_rotation_weights_fit_pose_data(
    ur5: pincal.Robot, capfd: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """The ends of the accepted range still fit (no overflow), and give a finite report."""
    _, fit, _ = pincal.simulate(ur5, 30, 5, seed=1, rot_noise=1e-4)
    pincal.write_csv(tmp_path / "pose.csv", fit)
    for weight in ("1000", "1e-3"):
        report = tmp_path / f"r{weight}.json"
        args = ["calibrate", "ur5", str(tmp_path / "pose.csv"), "--model", "offsets", "--params", "all"]
        code = main([*args, "--nested", "no", "--rotation-weight", weight, "--report", str(report)])
        assert code == 0, capfd.readouterr().err
        assert np.isfinite(json.loads(report.read_text(encoding="utf-8"))["train"]["after"]["rms_mm"])


def test_plan_candidates_are_bounded_by_memory(
    capfd: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """10,000,000 candidates on a machine with 4 GB free: refused at once with the count that fits;
    a count no machine holds is refused on this one too."""
    out = tmp_path / "p.csv"
    monkeypatch.setattr(pincal.planning.candidates, "available_memory", lambda: 4e9)
    line = _one_line(
        capfd, main(["plan", "ur5", "--poses", "10", "--candidates", "10000000", "-o", str(out)]), "GB"
    )
    most = int(line.split("ask for ")[1].split()[0])
    assert 1000 < most < 10_000_000
    # what fits passes (on the same 4 GB: this machine's free memory varies with its load)
    pincal.planning.candidates.check_memory(pincal.load_robot("ur5"), most, "position", 10)
    monkeypatch.undo()
    _one_line(
        capfd, main(["plan", "ur5", "--poses", "10", "--candidates", str(10**13), "-o", str(out)]), "memory"
    )
    assert not out.exists()


# -- compensate: quaternions and the sidecar ---------------------------------------------------------


@pytest.fixture(scope="module")
def calibration(ur5: pincal.Robot, tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("cal")
    _, fit, _ = pincal.simulate(ur5, 30, 5, seed=0)
    pincal.write_csv(folder / "data.csv", fit)
    args = [
        "calibrate",
        "ur5",
        str(folder / "data.csv"),
        "--model",
        "offsets",
        "--params",
        "all",
        "--nested",
        "no",
    ]
    assert main([*args, "-o", str(folder / "cal.urdf")]) == 0
    return folder / "cal.urdf"


def _program(folder: Path, quat: str) -> Path:
    path = folder / "program.csv"
    path.write_text(f"x,y,z,qw,qx,qy,qz\n0.3,0.1,0.4,1,0,0,0\n0.3,0.2,0.4,{quat}\n", encoding="utf-8")
    return path


def test_compensate_refuses_a_zero_quaternion(
    calibration: Path, capfd: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    args = [
        "compensate",
        "ur5",
        str(calibration),
        str(_program(tmp_path, "0,0,0,0")),
        "-o",
        str(tmp_path / "o.csv"),
    ]
    capfd.readouterr()
    _one_line(capfd, main(args), "row 2", "zero")
    assert not (tmp_path / "o.csv").exists()


SIDECARS = {
    "nan": lambda m: np.where(np.eye(4, dtype=bool) & (np.arange(4) == 0)[:, None], np.nan, m),
    "scaled": lambda m: np.diag([2.0, 2.0, 2.0, 1.0]) @ m,
    "reflection": lambda m: np.diag([-1.0, 1.0, 1.0, 1.0]) @ m,
    "sheared": lambda m: m + np.pad([[0.0, 0.3, 0.0]], ((0, 3), (0, 1))),
    "bottom_row": lambda m: m + np.pad([[0.5]], ((3, 0), (0, 3))),
    "not_4x4": lambda m: m[:3],
}


@pytest.mark.parametrize("case", sorted(SIDECARS))
def test_compensate_refuses_a_sidecar_matrix_that_is_not_a_rigid_transform(
    case: str, calibration: Path, capfd: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    urdf = tmp_path / "cal.urdf"
    urdf.write_bytes(calibration.read_bytes())
    side = json.loads(pincal.export.urdf_writer.sidecar_path(calibration).read_text(encoding="utf-8"))
    matrix = SIDECARS[case](np.array(side["tip_T_tool"]["matrix"]))
    side["tip_T_tool"]["matrix"] = matrix.tolist()
    pincal.export.urdf_writer.sidecar_path(urdf).write_text(json.dumps(side), encoding="utf-8")
    args = ["compensate", "ur5", str(urdf), str(_program(tmp_path, "1,0,0,0")), "-o", str(tmp_path / "o.csv")]
    capfd.readouterr()
    _one_line(capfd, main(args), "tip_T_tool")
    assert not (tmp_path / "o.csv").exists()


def test_compensate_with_a_sound_sidecar_reaches_the_targets(
    calibration: Path, capfd: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    out = tmp_path / "o.csv"
    main(["compensate", "ur5", str(calibration), str(_program(tmp_path, "0,1,0,0")), "-o", str(out)])
    assert "compensated 2 of 2 rows" in capfd.readouterr().out
    assert [line.rsplit(",", 1)[1] for line in out.read_text(encoding="utf-8").splitlines()[1:]] == [
        "ok",
        "ok",
    ]


# -- --degrees and small joint motions -------------------------------------------------------------


@pytest.fixture(scope="module")
def small(ur5: pincal.Robot, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A small-motion experiment (every joint within ±6°) written in radians and in degrees, and
    a full-range one in radians."""
    folder = tmp_path_factory.mktemp("small")
    truth = random_truth(ur5, 0)
    rng = np.random.default_rng(3)
    data = truth.measure(np.deg2rad(rng.uniform(-6.0, 6.0, (40, 6))), 3e-5, None, 5)
    pincal.write_csv(folder / "radians.csv", data)
    pincal.write_csv(folder / "degrees.csv", replace(data, q=np.rad2deg(data.q)))
    _, full, _ = pincal.simulate(ur5, 30, 5, seed=0)
    pincal.write_csv(folder / "full_radians.csv", full)
    return {p.stem: p for p in folder.iterdir()}


def _fitted(capfd: pytest.CaptureFixture[str], data: Path, folder: Path, *more: str) -> np.ndarray:
    """The fitted parameter values and the RMS after, from the report."""
    report = folder / f"{data.stem}.json"
    args = ["calibrate", "ur5", str(data), "--model", "offsets", "--params", "all", "--nested", "no"]
    args += ["--extend", "none", *more]
    code = main([*args, "--report", str(report), "--force"])
    assert code == 0, capfd.readouterr().err
    rep = json.loads(report.read_text(encoding="utf-8"))
    return np.array([*(p["value"] for p in rep["parameters"]), rep["train"]["after"]["rms_mm"]])


def test_small_motions_in_degrees_calibrate_as_the_same_data_in_radians(
    small: dict[str, Path], capfd: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """Accepted (they are within ±6.3°, but the points spread as the tip does read as degrees), and
    the same calibration as from radians, which shows the degrees were read as degrees."""
    in_degrees = _fitted(capfd, small["degrees"], tmp_path, "--degrees")
    in_radians = _fitted(capfd, small["radians"], tmp_path)
    assert np.allclose(in_degrees, in_radians, rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("name", ["radians", "full_radians"])
def test_radians_given_with_degrees_are_still_refused(
    name: str, small: dict[str, Path], capfd: pytest.CaptureFixture[str]
) -> None:
    """Small or full-range motions in radians read as degrees: the points spread like the tip read
    as radians, not as degrees; the line says to drop --degrees."""
    capfd.readouterr()
    _one_line(capfd, main(["calibrate", "ur5", str(small[name]), "--degrees"]), "drop --degrees")
