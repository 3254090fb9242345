"""End-to-end tests of the ``pincal`` command (see ``contracts.md``).

The command runs in-process through :func:`pincal.cli.main` (which returns the exit code), with
the output captured by ``capsys``; one test runs it as a separate process. The data are simulated
UR5 laser-tracker measurements (:func:`pincal.simulate`, seeded) written as measurement CSVs.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import pincal
import pincal.robot.robots
from pincal.cli import main

N_FIT = 70
N_TEST = 30
ERR_KEYS = ("rms_mm", "mean_mm", "max_mm", "std_mm")
TOP_KEYS = {
    "robot": str,
    "tip": str,
    "model": str,
    "measure": str,
    "n_poses": int,
    "n_params": int,
    "n_identifiable": int,
    "condition_number": float,
}


@dataclass(frozen=True)
class Files:
    """CSV files of one simulated experiment.

    Attributes:
        all: every pose (fit and held out), x,y,z in mm.
        fit: the fitted poses, x,y,z in mm.
        test: the held-out poses, x,y,z in mm.
    """

    all: Path
    fit: Path
    test: Path


@dataclass(frozen=True)
class Run:
    """Outcome of one in-process run of the command."""

    code: int
    out: str
    err: str


def _concat(a: pincal.Dataset, b: pincal.Dataset) -> pincal.Dataset:
    return pincal.Dataset(a.joint_names, np.vstack([a.q, b.q]), np.vstack([a.points, b.points]))


def _write_experiment(folder: Path, truth: pincal.simulation.truth.TrueRobot | None = None) -> Files:
    """Simulate the UR5 (seed 0) and write all, fitted and held-out poses as CSV in mm."""
    robot = pincal.load_robot("ur5")
    _, fit, test = pincal.simulate(robot, N_FIT, N_TEST, seed=0, truth=truth)
    folder.mkdir(parents=True, exist_ok=True)
    files = Files(folder / "data.csv", folder / "fit.csv", folder / "test.csv")
    pincal.write_csv(files.all, _concat(fit, test), units="mm")
    pincal.write_csv(files.fit, fit, units="mm")
    pincal.write_csv(files.test, test, units="mm")
    return files


@pytest.fixture(scope="module")
def ur5() -> pincal.Robot:
    """The bundled UR5."""
    return pincal.load_robot("ur5")


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> Files:
    """The default experiment: unknown instrument pose and tool point."""
    return _write_experiment(tmp_path_factory.mktemp("ur5"))


def _run(capsys: pytest.CaptureFixture[str], *args: str | Path) -> Run:
    """Run ``pincal ARGS`` in-process and capture its exit code and output."""
    capsys.readouterr()  # drop anything printed before
    code = main([str(a) for a in args])
    captured = capsys.readouterr()
    return Run(code, captured.out, captured.err)


def _calibrate(capsys: pytest.CaptureFixture[str], report: Path, *args: str | Path) -> dict:
    """Run ``pincal calibrate ARGS --report REPORT``; expect success; return the report."""
    run = _run(capsys, "calibrate", *args, "--report", report)
    assert run.code == 0, run.err
    assert run.err == ""
    assert f"report written to {report}" in run.out
    return json.loads(report.read_text(encoding="utf-8"))


def _check_err(err: dict) -> None:
    for key in ERR_KEYS:
        assert isinstance(err[key], float), key
        assert np.isfinite(err[key]) and err[key] >= 0.0, key
    assert err["max_mm"] >= err["rms_mm"] >= err["mean_mm"]


def _check_contract(report: dict) -> None:
    """Every key and type ``contracts.md`` fixes for the calibrate report."""
    for key, kind in TOP_KEYS.items():
        assert isinstance(report[key], kind), key
    assert report["n_identifiable"] <= report["n_params"]
    assert report["condition_number"] >= 1.0
    for part in ("train", "test"):
        assert set(report[part]) >= {"before", "after"}
        _check_err(report[part]["before"])
        _check_err(report[part]["after"])
    assert len(report["parameters"]) == report["n_params"]
    for row in report["parameters"]:
        assert isinstance(row["name"], str)
        assert isinstance(row["value"], float) and isinstance(row["std"], float)
        assert isinstance(row["unit"], str)


def _assert_calibrated(report: dict) -> None:
    """Held-out error after calibration is a small fraction of the error before."""
    test = report["test"]
    assert test["before"]["rms_mm"] > 0.5
    assert test["after"]["rms_mm"] < test["before"]["rms_mm"] / 10


def listed_names(report: dict) -> list[str]:
    return [row["name"] for row in report["parameters"]]


def _single_error_line(run: Run) -> str:
    """The one ``pincal: error:`` line of a failed run (exit code 2, no traceback)."""
    assert run.code == 2, (run.out, run.err)
    assert "Traceback" not in run.err and "Traceback" not in run.out
    lines = run.err.splitlines()
    assert len(lines) == 1, run.err
    assert lines[0].startswith("pincal: error:")
    return lines[0]


# -- calibrate: success ---------------------------------------------------------------------


def test_calibrate_holdout_writes_contract_report(
    capsys: pytest.CaptureFixture[str], files: Files, tmp_path: Path
) -> None:
    """``calibrate ur5 data.csv --units mm --holdout 0.3 --report r.json``: the full report."""
    before = files.all.read_bytes()
    report = _calibrate(capsys, tmp_path / "r.json", "ur5", files.all, "--units", "mm", "--holdout", "0.3")
    _check_contract(report)
    assert report["robot"] == "ur5" and report["tip"] == "tool0"
    assert report["model"] == "placements" and report["measure"] == "position"
    assert report["n_poses"] == round(0.7 * (N_FIT + N_TEST))
    assert report["test"]["after"]["n"] == round(0.3 * (N_FIT + N_TEST))
    _assert_calibrated(report)
    assert files.all.read_bytes() == before  # the input is never touched
    assert not list(tmp_path.glob("*.tmp"))  # the atomic write left no temporary file


@pytest.mark.parametrize(
    ("options", "model", "measure"),
    [
        ((), "placements", "position"),
        (("--model", "poe"), "poe", "position"),
        (("--model", "mdh"), "mdh", "position"),
        (("--measure", "distance"), "placements", "distance"),
    ],
    ids=["test-file", "poe", "mdh", "distance"],
)
def test_calibrate_with_test_file(
    capsys: pytest.CaptureFixture[str],
    files: Files,
    tmp_path: Path,
    options: tuple[str, ...],
    model: str,
    measure: str,
) -> None:
    """``--test other.csv`` with each model and with distance data."""
    report = _calibrate(
        capsys,
        tmp_path / "r.json",
        "ur5",
        files.fit,
        "--test",
        files.test,
        "--units",
        "mm",
        *options,
    )
    _check_contract(report)
    assert report["model"] == model and report["measure"] == measure
    assert report["n_poses"] == N_FIT
    n_test = N_TEST * (N_TEST - 1) // 2 if measure == "distance" else N_TEST
    assert report["test"]["after"]["n"] == n_test
    if measure == "distance":  # distances need no instrument registration
        assert not any(name.startswith("instrument.") for name in listed_names(report))
    _assert_calibrated(report)


def test_calibrate_degrees(capsys: pytest.CaptureFixture[str], ur5: pincal.Robot, tmp_path: Path) -> None:
    """A CSV in degrees read with ``--degrees`` calibrates as the same data in radians."""
    _, fit, test = pincal.simulate(ur5, N_FIT, N_TEST, seed=0)
    data = _concat(fit, test)
    radians = tmp_path / "radians.csv"
    degrees = tmp_path / "degrees.csv"
    pincal.write_csv(radians, data)
    lines = [
        "# joint angles in degrees, x,y,z in metres",
        ",".join([*ur5.joint_names, "x", "y", "z"]),
    ]
    for q, p in zip(np.rad2deg(data.q), data.points):
        lines.append(",".join(repr(float(v)) for v in (*q, *p)))
    degrees.write_text("\n".join(lines) + "\n", encoding="utf-8")

    in_degrees = _calibrate(capsys, tmp_path / "deg.json", "ur5", degrees, "--degrees", "--holdout", "0.3")
    in_radians = _calibrate(capsys, tmp_path / "rad.json", "ur5", radians, "--holdout", "0.3")
    _check_contract(in_degrees)
    _assert_calibrated(in_degrees)
    for part in ("train", "test"):
        for when in ("before", "after"):
            assert in_degrees[part][when]["rms_mm"] == pytest.approx(
                in_radians[part][when]["rms_mm"], abs=1e-6
            )


def test_calibrate_instrument_frame_base(
    capsys: pytest.CaptureFixture[str], ur5: pincal.Robot, tmp_path: Path
) -> None:
    """``--instrument-frame base``: data in the base frame, no registration unknowns."""
    truth = pincal.random_truth(ur5, 0, instrument=False)
    data = _write_experiment(tmp_path / "data", truth)
    report = _calibrate(
        capsys,
        tmp_path / "r.json",
        "ur5",
        data.all,
        "--units",
        "mm",
        "--holdout",
        "0.3",
        "--instrument-frame",
        "base",
    )
    _check_contract(report)
    assert not any(name.startswith("instrument.") for name in listed_names(report))
    assert any(name.startswith("tool.") for name in listed_names(report))
    _assert_calibrated(report)


@pytest.mark.parametrize("sign", [1.0, -1.0], ids=["as-simulated", "negative-x"])
def test_calibrate_tool_point(
    capsys: pytest.CaptureFixture[str], ur5: pincal.Robot, tmp_path: Path, sign: float
) -> None:
    """``--tool-point X,Y,Z`` (data units): the measured point is known, not estimated.

    The second case flips the simulated point so that X is negative, as ``-32.8,64.4,-19.8``:
    the contract's ``--tool-point X,Y,Z`` must take a negative first coordinate too.
    """
    truth = pincal.random_truth(ur5, 0)
    truth = replace(truth, tool=pin.SE3(truth.tool.rotation, sign * truth.tool.translation))
    assert np.sign(truth.tool.translation[0]) == sign
    data = _write_experiment(tmp_path / "data", truth)
    point = ",".join(repr(float(v)) for v in truth.tool.translation * 1e3)
    report = _calibrate(
        capsys,
        tmp_path / "r.json",
        "ur5",
        data.all,
        "--units",
        "mm",
        "--holdout",
        "0.3",
        "--tool-point",
        point,
    )
    _check_contract(report)
    assert not any(name.startswith("tool.") for name in listed_names(report))
    assert any(name.startswith("instrument.") for name in listed_names(report))
    _assert_calibrated(report)


def test_calibrate_locks_joint_without_column(
    capsys: pytest.CaptureFixture[str], ur5: pincal.Robot, tmp_path: Path
) -> None:
    """A chain joint with no column is an error (issue 6) unless ``--lock`` holds it at neutral.

    The data is measured with ``wrist_3_joint`` at 0 and its column left out.
    """
    truth = pincal.random_truth(ur5, 0)
    q = ur5.random_configurations(N_FIT + N_TEST, np.random.default_rng(1), 0.05)
    q[:, -1] = 0.0
    data = truth.measure(q, seed=2)
    path = tmp_path / "five.csv"
    header = ",".join([*ur5.joint_names[:-1], "x", "y", "z"])
    rows = [",".join(repr(float(v)) for v in (*qi[:-1], *p)) for qi, p in zip(q, data.points)]
    path.write_text("\n".join([header, *rows]) + "\n", encoding="utf-8")

    refused = _single_error_line(
        _run(capsys, "calibrate", "ur5", path, "--holdout", "0.3", "--report", tmp_path / "r.json")
    )
    assert "wrist_3_joint" in refused and "--lock wrist_3_joint" in refused
    assert not (tmp_path / "r.json").exists()

    run = _run(
        capsys,
        "calibrate",
        "ur5",
        path,
        "--holdout",
        "0.3",
        "--report",
        tmp_path / "r.json",
        "--lock",
        "wrist_3_joint",
    )
    assert run.code == 0, run.err
    assert "wrist_3_joint" in run.out  # says which joint it locked
    report = json.loads((tmp_path / "r.json").read_text(encoding="utf-8"))
    _check_contract(report)
    assert not any(name.startswith("wrist_3_joint.") for name in listed_names(report))
    _assert_calibrated(report)


# -- calibrate: unusable input ---------------------------------------------------------------


def _edited_csv(source: Path, target: Path, edit) -> Path:
    """Copy a CSV with ``edit(lines) -> lines`` applied."""
    lines = source.read_text(encoding="utf-8").splitlines()
    target.write_text("\n".join(edit(lines)) + "\n", encoding="utf-8")
    return target


def _drop_column(name: str):
    def edit(lines: list[str]) -> list[str]:
        k = lines[0].split(",").index(name)
        return [",".join(c for i, c in enumerate(line.split(",")) if i != k) for line in lines]

    return edit


def _rename_joints(lines: list[str]) -> list[str]:
    header = [c if c in ("x", "y", "z") else f"j{i}" for i, c in enumerate(lines[0].split(","))]
    return [",".join(header), *lines[1:]]


def _set_cell(row: int, col: int, text: str):
    def edit(lines: list[str]) -> list[str]:
        cells = lines[row].split(",")
        cells[col] = text
        return [*lines[:row], ",".join(cells), *lines[row + 1 :]]

    return edit


ERROR_CASES = {
    # id: (arguments after "calibrate", CSV edit or None, fragment the message must hold)
    "unknown-robot": (("no_such_robot", "{data}"), None, "no_such_robot"),
    "missing-data-file": (("ur5", "{tmp}/missing.csv"), None, "missing.csv"),
    "no-joint-column": (("ur5", "{data}"), _rename_joints, "no column"),
    "missing-z-column": (("ur5", "{data}"), _drop_column("z"), "missing column"),
    "non-numeric-cell": (("ur5", "{data}"), _set_cell(3, 2, "abc"), "abc"),
    "nan-cell": (("ur5", "{data}"), _set_cell(5, 7, "nan"), "nan"),
    "output-is-input-urdf": (("ur5", "{data}", "-o", "{urdf}"), None, "input URDF"),
    "output-folder-missing": (("ur5", "{data}", "-o", "{tmp}/no_such_dir/out.urdf"), None, "no_such_dir"),
    "add-frame-without-output": (("ur5", "{data}", "--add-frame", "smr"), None, "--add-frame"),
    "unknown-option": (("ur5", "{data}", "--frobnicate"), None, "--frobnicate"),
    "bad-units": (("ur5", "{data}", "--units", "inch"), None, "inch"),
    "test-and-holdout": (
        ("ur5", "{data}", "--test", "{data}", "--holdout", "0.3"),
        None,
        "--holdout",
    ),
    "bad-tool-point": (("ur5", "{data}", "--tool-point", "1,2"), None, "1,2"),
}


@pytest.mark.parametrize("case", list(ERROR_CASES))
def test_calibrate_unusable_input(
    capsys: pytest.CaptureFixture[str], files: Files, tmp_path: Path, case: str
) -> None:
    """Exit code 2, one ``pincal: error:`` line naming the problem, no traceback, no output."""
    args, edit, fragment = ERROR_CASES[case]
    data = files.all if edit is None else _edited_csv(files.all, tmp_path / "data.csv", edit)
    before = data.read_bytes()
    urdf = pincal.robot.robots.bundled_urdf("ur5")
    urdf_before = urdf.read_bytes()
    argv = [a.format(data=data, tmp=tmp_path, urdf=urdf) for a in args]
    report = tmp_path / "r.json"

    line = _single_error_line(_run(capsys, "calibrate", *argv, "--report", report))
    assert fragment in line
    assert not report.exists()
    assert not (tmp_path / "out.urdf").exists()
    assert data.read_bytes() == before
    assert urdf.read_bytes() == urdf_before
    assert not list(tmp_path.glob("*.tmp"))


def test_usage_error_hint_names_a_real_command(capsys: pytest.CaptureFixture[str], files: Files) -> None:
    """The ``--help`` hint of a usage error points at a command that exists."""
    line = _single_error_line(_run(capsys, "calibrate", "ur5", files.all, "--frobnicate"))
    hint = re.search(r"see '([^']*)'", line)
    assert hint is not None
    assert hint.group(1) in ("pincal --help", "pincal calibrate --help")


def test_unknown_robot_in_a_subprocess(files: Files, tmp_path: Path) -> None:
    """As a separate process: exit code 2 and exactly one stderr line, no traceback."""
    report = tmp_path / "r.json"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "pincal.cli",
            "calibrate",
            "no_such_robot",
            str(files.all),
            "--report",
            str(report),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("pincal: error:")
    assert "no_such_robot" in lines[0]
    assert not report.exists()


# -- demo and twists --------------------------------------------------------------------------


def test_demo(capsys: pytest.CaptureFixture[str]) -> None:
    """``pincal demo`` prints the UR5 table (every model) and the Gao 2013 gain."""
    run = _run(capsys, "demo")
    assert run.code == 0, run.err
    assert "1. Simulated UR5" in run.out
    assert "2. Gao et al. 2013" in run.out
    for model in pincal.MODELS:
        assert re.search(rf"^\s+{model}\s+\d+ of", run.out, re.MULTILINE), model
    gain = re.search(r"gain ([0-9.]+)x on the URDF as is .*the geometry alone ([0-9.]+)x", run.out)
    assert gain is not None
    # the command's default names a cause on this arm: its URDF alone is no worse than the geometry
    # alone with every parameter, and with its sidecar it beats both
    assert re.search(r"the URDF with its sidecar \(\+ \d causes?\)", run.out)
    assert "joint_compliance:joint3" in run.out
    assert float(gain.group(1)) > max(3.0, float(gain.group(2)))
    # with every parameter the guard may export the nominal geometry in a fold (the fit exported in
    # all of them is test_papers' 3.4x): the demo then says in how many it kept the fit
    if float(gain.group(2)) < 3.0:
        assert re.search(r"the guard kept the fit in \d of 7 folds", run.out)
    means = {
        label.strip(): float(mean)
        for label, mean in re.findall(r"^ {3}(.{54}) +([0-9.]+) +[0-9.]+$", run.out, re.MULTILINE)
    }
    geometry = means["calibrated, geometry only (every parameter)"]
    alone = means["pincal calibrate's default: the URDF alone"]
    full = next(v for k, v in means.items() if k.startswith("the URDF with its sidecar"))
    assert full < alone <= geometry


def test_twists_mrres5(capsys: pytest.CaptureFixture[str]) -> None:
    """``pincal twists mrres5`` prints one twist per joint and the check against Pinocchio."""
    run = _run(capsys, "twists", "mrres5")
    assert run.code == 0, run.err
    for k in range(1, 6):
        assert f"joint{k}" in run.out
    match = re.search(r"max error ([0-9.eE+-]+)", run.out)
    assert match is not None
    assert float(match.group(1)) < 1e-9


def test_the_verdict_warns_when_the_nested_estimate_loses_to_the_urdf() -> None:
    """A nested cross-validation worse than the URDF as is, or than the URDF's geometry with the
    registration and tool fitted (the tool unknown: the URDF as is far off), is a warning on the
    verdict line; one better than both is not."""
    from types import SimpleNamespace

    from pincal.cli.calibrate import NOMINAL_FITTED, verdict_warnings

    def with_nested(urdf: float, before: float, after: float) -> SimpleNamespace:
        stats = {
            k: SimpleNamespace(rms_mm=v) for k, v in (("urdf", urdf), ("before", before), ("after", after))
        }
        return SimpleNamespace(choice=SimpleNamespace(nested=SimpleNamespace(**stats)))

    result = None
    (warning,) = verdict_warnings(with_nested(65.0, 3.85, 3.98), result)  # type: ignore[arg-type]
    assert NOMINAL_FITTED in warning and "3.98 against 3.85 mm" in warning
    (warning,) = verdict_warnings(with_nested(2.0, 3.85, 3.0), result)  # type: ignore[arg-type]
    assert "the URDF as is (3 against 2 mm)" in warning
    assert verdict_warnings(with_nested(65.0, 3.85, 1.25), result) == ()  # type: ignore[arg-type]
    assert verdict_warnings(SimpleNamespace(choice=None), result) == ()  # type: ignore[arg-type]
