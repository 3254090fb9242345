"""Bad input, outliers and hostile files (issue 6): clear errors, nothing lost, nothing leaked.

Every case runs the command in-process through :func:`pincal.cli.main` in a fresh ``tmp_path``
and checks the contract of ``contracts.md``: exit code 2, exactly one stderr line that starts
with ``pincal: error:`` and names the problem (a column, a row number, the option that fixes it),
no traceback, and no file in the folder appeared or changed (inputs and pre-existing outputs are
compared byte for byte). The data are simulated UR5 laser-tracker measurements
(:func:`pincal.simulate`, seeded) written with :func:`pincal.write_csv` and then corrupted as text.

Tests under a ``# Regression (was a bug)`` comment reproduce bugs found while writing these tests
(most by the fuzzing of ``test_fuzz.py``); the comment says what went wrong.
"""

from __future__ import annotations

import json
import os
import re
import threading
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

import pincal
import pincal.robot.robots
import pincal.tool.tcp
from pincal.cli import main
from pincal.robot.ur_frames import JOINTS

N_FIT = 30
N_TEST = 20
#: Text of the secret file a hostile URDF tries to read.
SECRET = "TOP-SECRET-7f3a9c-do-not-leak"


@dataclass(frozen=True)
class Run:
    """Outcome of one in-process run of the command."""

    code: int
    out: str
    err: str


Lines = list[str]
Edit = Callable[[Lines], Lines]


@dataclass(frozen=True)
class Sim:
    """A simulated UR5 experiment and its CSV text (radians, metres)."""

    robot: pincal.Robot
    fit: pincal.Dataset
    test: pincal.Dataset
    lines: tuple[str, ...]
    test_lines: tuple[str, ...]


def _csv_lines(data: pincal.Dataset, folder: Path, name: str) -> tuple[str, ...]:
    path = folder / name
    pincal.write_csv(path, data)
    return tuple(path.read_text(encoding="utf-8").splitlines())


@pytest.fixture(scope="module")
def sim(tmp_path_factory: pytest.TempPathFactory) -> Sim:
    """UR5, 30 fitted and 20 held-out poses (seed 0)."""
    robot = pincal.load_robot("ur5")
    _, fit, test = pincal.simulate(robot, N_FIT, N_TEST, seed=0)
    folder = tmp_path_factory.mktemp("sim")
    return Sim(robot, fit, test, _csv_lines(fit, folder, "fit.csv"), _csv_lines(test, folder, "test.csv"))


def _write(path: Path, lines: Sequence[str]) -> Path:
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _run(capfd: pytest.CaptureFixture[str], *args: str | Path) -> Run:
    """Run ``pincal ARGS`` in-process; capture the exit code and the output."""
    capfd.readouterr()
    code = main([str(a) for a in args])
    captured = capfd.readouterr()
    return Run(code, captured.out, captured.err)


def _error_line(run: Run) -> str:
    """The single ``pincal: error:`` line of a run that must fail with exit code 2."""
    assert run.code == 2, (run.code, run.out, run.err)
    assert "Traceback" not in run.err + run.out
    lines = run.err.splitlines()
    assert len(lines) == 1, run.err
    assert lines[0].startswith("pincal: error: ")
    return lines[0]


def _snapshot(folder: Path) -> dict[str, bytes]:
    """Every regular file under ``folder`` and its bytes."""
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and not p.is_symlink()
    }


def _assert_refused(
    capfd: pytest.CaptureFixture[str], folder: Path, args: Sequence[str | Path], *words: str
) -> str:
    """Exit 2, one error line holding every one of ``words``, and no file appeared or changed."""
    before = _snapshot(folder)
    line = _error_line(_run(capfd, *args))
    for word in words:
        assert word in line, (word, line)
    assert _snapshot(folder) == before
    return line


# -- CSV edits ----------------------------------------------------------------------------------


def _col(lines: Lines, name: str) -> int:
    return lines[0].split(",").index(name)


def drop_column(name: str) -> Edit:
    def edit(lines: Lines) -> Lines:
        k = _col(lines, name)
        return [",".join(c for i, c in enumerate(line.split(",")) if i != k) for line in lines]

    return edit


def rename_column(old: str, new: str) -> Edit:
    def edit(lines: Lines) -> Lines:
        header = [new if c == old else c for c in lines[0].split(",")]
        return [",".join(header), *lines[1:]]

    return edit


def add_column(name: str, value: str) -> Edit:
    def edit(lines: Lines) -> Lines:
        return [f"{lines[0]},{name}", *(f"{line},{value}" for line in lines[1:])]

    return edit


def set_cell(row: int, name: str, text: str) -> Edit:
    """Replace the cell of data row ``row`` (1-based) in column ``name``."""

    def edit(lines: Lines) -> Lines:
        cells = lines[row].split(",")
        cells[_col(lines, name)] = text
        return [*lines[:row], ",".join(cells), *lines[row + 1 :]]

    return edit


def drop_field(row: int) -> Edit:
    def edit(lines: Lines) -> Lines:
        return [*lines[:row], ",".join(lines[row].split(",")[:-1]), *lines[row + 1 :]]

    return edit


def keep_rows(n: int) -> Edit:
    def edit(lines: Lines) -> Lines:
        return lines[: n + 1]

    return edit


def with_comments(edit: Edit) -> Edit:
    """``edit``, then comment lines at the top and between every data row (not counted as rows)."""

    def commented(lines: Lines) -> Lines:
        lines = edit(lines)
        out = ["# measured with a laser tracker", "#", lines[0]]
        for k, line in enumerate(lines[1:], start=1):
            out += [f"# pose {k}", line]
        return out

    return commented


def scale_columns(names: Sequence[str], factor: float) -> Edit:
    def edit(lines: Lines) -> Lines:
        cols = [_col(lines, n) for n in names]
        out = [lines[0]]
        for line in lines[1:]:
            cells = line.split(",")
            for c in cols:
                cells[c] = repr(float(cells[c]) * factor)
            out.append(",".join(cells))
        return out

    return edit


#: id: (CSV edit, extra arguments, words the error line must hold). Row numbers are data rows.
DATA_CASES: dict[str, tuple[Edit | None, tuple[str, ...], tuple[str, ...]]] = {
    "missing-joint-column": (drop_column("elbow_joint"), (), ("elbow_joint", "--lock")),
    "misspelt-joint-column": (
        rename_column("elbow_joint", "elbow_jiont"),
        (),
        ("elbow_joint", "elbow_jiont"),
    ),
    "extra-joint-like-column": (add_column("wrist_4_joint", "0.1"), (), ("wrist_4_joint",)),
    "extra-numbered-joint-column": (add_column("joint7", "0.0"), (), ("joint7",)),
    "missing-x-column": (drop_column("x"), (), ("missing column", "x")),
    "capital-x-column": (rename_column("x", "X"), (), ("missing column", "'X' for x?")),
    "x-column-named-with-its-unit": (
        rename_column("y", "y [mm]"),
        (),
        ("'y [mm]' for y?", "--units mm"),
    ),
    "joint-column-named-with-its-unit": (
        rename_column("elbow_joint", "elbow_joint_deg"),
        (),
        ("'elbow_joint_deg' for elbow_joint?", "--degrees"),
    ),
    "non-numeric-cell": (set_cell(3, "elbow_joint", "abc"), (), ("row 3", "elbow_joint", "abc")),
    "empty-cell": (set_cell(4, "wrist_1_joint", ""), (), ("row 4", "wrist_1_joint")),
    "nan-cell": (set_cell(5, "y", "nan"), (), ("row 5", "y", "nan")),
    "inf-cell": (set_cell(2, "shoulder_pan_joint", "inf"), (), ("row 2", "shoulder_pan_joint", "inf")),
    "minus-inf-cell": (set_cell(6, "z", "-inf"), (), ("row 6", "z", "inf")),
    "overflowing-cell": (set_cell(7, "x", "1e400"), (), ("row 7", "x", "1e400")),
    "nan-after-comments": (with_comments(set_cell(5, "x", "NaN")), (), ("row 5", "NaN")),
    "row-missing-a-field": (drop_field(6), (), ("row 6", "fields")),
    "duplicated-header": (add_column("x", "1.0"), (), ("duplicated", "x")),
    "duplicated-joint-header": (add_column("elbow_joint", "0.0"), (), ("duplicated", "elbow_joint")),
    "header-only": (keep_rows(0), (), ("no data rows",)),
    "comments-only": (lambda lines: ["# nothing measured yet", "#"], (), ("empty",)),
    "too-few-poses": (keep_rows(4), (), ("4 poses", "measure at least")),
    "one-pose": (keep_rows(1), (), ("1 pose",)),
    "degrees-as-radians": (scale_columns(JOINTS, 180 / np.pi), (), ("radians", "--degrees")),
    "millimetres-as-metres": (scale_columns("xyz", 1e3), (), ("--units mm",)),
    "metres-as-millimetres": (None, ("--units", "mm"), ("--units mm",)),
    "joint-beyond-limit": (set_cell(4, "elbow_joint", repr(float(np.pi + np.deg2rad(5)))), (), ("row 4",)),
}


@pytest.mark.parametrize("command", ["calibrate", "diagnose"])
@pytest.mark.parametrize("case", list(DATA_CASES))
def test_bad_data_is_refused(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path, command: str, case: str
) -> None:
    """Each malformed CSV: exit 2, one error line naming the problem, no output, input unchanged."""
    edit, extra, words = DATA_CASES[case]
    data = _write(tmp_path / "data.csv", (edit or list)(list(sim.lines)))
    outputs = (
        ("-o", tmp_path / "out.urdf", "--report", tmp_path / "r.json")
        if command == "calibrate"
        else ("--json", tmp_path / "d.json", "--folds", "3", "--model", "offsets")
    )
    _assert_refused(capfd, tmp_path, [command, "ur5", data, *extra, *outputs], *words)
    assert set(_snapshot(tmp_path)) == {"data.csv"}


def test_joint_beyond_limit_names_joint_and_limits(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path
) -> None:
    """A joint value 5 deg beyond the URDF limit: the row, the column and the limits are named."""
    value = np.pi + np.deg2rad(5.0)
    data = _write(tmp_path / "data.csv", set_cell(4, "elbow_joint", repr(float(value)))(list(sim.lines)))
    line = _assert_refused(capfd, tmp_path, ["calibrate", "ur5", data], "row 4", "elbow_joint")
    assert "limit" in line
    assert f"{value:.4g}" in line or f"{value:.6g}" in line


# Regression (was a bug): check_limits hints 'pass --degrees' when one radian value is slightly out of
# range: deg2rad of a radian column is always inside the limits, so the hint fires for any single bad row
def test_single_joint_beyond_limit_is_not_called_degrees(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path
) -> None:
    """One radian value 5 deg beyond the limit is a bad row, not a file in degrees."""
    data = _write(
        tmp_path / "data.csv",
        set_cell(4, "elbow_joint", repr(float(np.pi + np.deg2rad(5))))(list(sim.lines)),
    )
    line = _assert_refused(capfd, tmp_path, ["calibrate", "ur5", data], "row 4")
    assert "--degrees" not in line


def test_joints_past_tight_limits_are_kept_with_a_warning(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path
) -> None:
    """A value 2 deg past a limit (a soft limit passed), a joint past its limits in two rows by a
    few degrees or in many rows (limits too tight, as MUKCa's Gen3 lite), is kept: exit 0 and one
    warning with the count."""
    k = int(np.argmax(sim.fit.q[:, 2]))
    once = set_cell(k + 1, "elbow_joint", repr(float(np.pi + np.deg2rad(2.0))))(list(sim.lines))
    twice = set_cell(k + 1, "elbow_joint", repr(float(np.pi + np.deg2rad(4.0))))(list(sim.lines))
    twice = set_cell(1 if k else 2, "elbow_joint", repr(float(-np.pi - np.deg2rad(3.5))))(twice)
    many = list(sim.lines)
    rows = range(1, 1 + len(many) // 5)  # a fifth of the rows, 20 deg past
    for row in rows:
        many = set_cell(row, "elbow_joint", repr(float(np.pi + np.deg2rad(20.0))))(many)
    for lines, count in ((once, 1), (twice, 2), (many, len(rows))):
        data = _write(tmp_path / "data.csv", lines)
        run = _run(capfd, "calibrate", "ur5", data, "--model", "offsets", "--accept-implausible")
        assert run.code == 0, run.err
        warning = [ln for ln in run.err.splitlines() if "beyond the URDF limits" in ln]
        assert len(warning) == 1 and f"{count} joint value(s)" in warning[0], run.err


def test_joint_within_limit_tolerance_is_accepted(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path
) -> None:
    """A value a fraction of a degree beyond the limit (rounding, encoder noise) is no error."""
    k = int(np.argmax(sim.fit.q[:, 2]))
    value = repr(float(np.pi + np.deg2rad(0.2)))
    data = _write(tmp_path / "data.csv", set_cell(k + 1, "elbow_joint", value)(list(sim.lines)))
    run = _run(capfd, "calibrate", "ur5", data, "--model", "offsets")
    assert run.code == 0, run.err


# Regression (was a bug): radians read with --degrees shrink the tip's spread and check_scale blames x,y,z
# ('check the unit of x,y,z') instead of saying the joints look like radians (drop --degrees)
def test_radians_read_as_degrees_names_degrees(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path
) -> None:
    data = _write(tmp_path / "data.csv", list(sim.lines))
    _assert_refused(capfd, tmp_path, ["calibrate", "ur5", data, "--degrees"], "--degrees")


# Regression (was a bug): a header with trailing commas (a spreadsheet export) is refused as 'duplicated
# column(s)' followed by nothing: the empty names are not said, nor the fix
def test_trailing_commas_are_accepted_or_explained(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path
) -> None:
    data = _write(tmp_path / "data.csv", [f"{line},," for line in sim.lines])
    run = _run(capfd, "calibrate", "ur5", data, "--model", "offsets")
    if run.code != 0:
        line = _error_line(run)
        assert not re.search(r"duplicated column\(s\)\s*$", line), line
        assert "empty" in line


def test_too_few_poses_says_how_many_and_that_is_enough(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path
) -> None:
    """'measure at least N poses': N poses of the same experiment do calibrate."""
    few = _write(tmp_path / "few.csv", keep_rows(4)(list(sim.lines)))
    line = _assert_refused(capfd, tmp_path, ["calibrate", "ur5", few], "measure at least")
    match = re.search(r"measure at least (\d+) poses", line)
    assert match is not None, line
    n = int(match.group(1))
    assert 4 < n <= N_FIT
    enough = _write(tmp_path / "enough.csv", keep_rows(n)(list(sim.lines)))
    run = _run(capfd, "calibrate", "ur5", enough, "--outliers", "0")
    assert run.code == 0, run.err


def test_too_few_poses_for_the_folds_count_all_the_poses(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path
) -> None:
    """``diagnose`` (5-fold cross-validation) on too few poses: the count it asks for is of all
    the poses, more than given (not the fold's, fewer than given), and that many run."""
    given = 12
    few = _write(tmp_path / "few.csv", keep_rows(given)(list(sim.lines)))
    every = ["--params", "all"]  # the full geometry: with 'auto' (the default) 12 poses can do
    line = _assert_refused(capfd, tmp_path, ["diagnose", "ur5", few, *every], "measure at least", "--folds")
    match = re.search(r"measure at least (\d+) poses", line)
    assert match is not None, line
    n = int(match.group(1))
    assert given < n <= N_FIT
    enough = _write(tmp_path / "enough.csv", keep_rows(n)(list(sim.lines)))
    run = _run(capfd, "diagnose", "ur5", enough, *every)
    assert run.code == 0, run.err


def test_bad_test_file_is_named(capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path) -> None:
    """A NaN in the ``--test`` file: the error names that file and row."""
    data = _write(tmp_path / "fit.csv", sim.lines)
    test = _write(tmp_path / "held_out.csv", set_cell(2, "z", "nan")(list(sim.test_lines)))
    _assert_refused(
        capfd, tmp_path, ["calibrate", "ur5", data, "--test", test, "--report", tmp_path / "r.json"],
        "held_out.csv", "row 2",
    )  # fmt: skip


# -- files that cannot be read, unknown robot, frame or joint ------------------------------------


# Regression (was a bug): finite but huge numbers (a URDF joint origin of 1e300 m, a measured x of 1e154)
# overflow in check_scale: numpy prints 'RuntimeWarning: overflow encountered in square/reduce' on stderr
# next to the error line
@pytest.mark.parametrize("where", ["urdf-origin", "data-cell"])
def test_huge_numbers_warn_nothing(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path, where: str
) -> None:
    """Numbers that overflow when squared: exit 0, or 2 with one error line, and no numpy warning
    (which the command line would print as more stderr lines)."""
    text = pincal.robot.robots.bundled_urdf("ur5").read_text(encoding="utf-8")
    urdf = tmp_path / "robot.urdf"
    if where == "urdf-origin":
        text = re.sub(r'xyz="[^"]*"', 'xyz="1e300 0 0"', text, count=1)
    urdf.write_text(text, encoding="utf-8")
    lines = list(sim.lines) if where == "urdf-origin" else set_cell(1, "x", "1.4e154")(list(sim.lines))
    data = _write(tmp_path / "data.csv", lines)
    before = _snapshot(tmp_path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run = _run(capfd, "calibrate", urdf, data, "--model", "offsets")
    assert [str(w.message) for w in caught] == []
    assert run.code in (0, 2), run.err
    if run.code == 2:
        _error_line(run)
        assert _snapshot(tmp_path) == before


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads a file whatever its permissions")
def test_file_without_read_permission(capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path) -> None:
    data = _write(tmp_path / "data.csv", sim.lines)
    data.chmod(0)
    try:
        _assert_refused(
            capfd, tmp_path, ["calibrate", "ur5", data, "--report", tmp_path / "r.json"], "data.csv"
        )
    finally:
        data.chmod(0o644)


@pytest.mark.parametrize("command", ["calibrate", "diagnose"])
def test_missing_and_unreadable_files(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path, command: str
) -> None:
    """Missing data, a folder or a binary file as data, a missing or binary URDF."""
    data = _write(tmp_path / "data.csv", sim.lines)
    (tmp_path / "folder.csv").mkdir()
    (tmp_path / "binary.csv").write_bytes(bytes(range(256)) * 4)
    (tmp_path / "binary.urdf").write_bytes(b"\xff\xfe\x00<robot" + bytes(range(128, 256)))
    out = ("--report", tmp_path / "r.json") if command == "calibrate" else ("--json", tmp_path / "d.json")
    cases = [
        (("ur5", tmp_path / "nope.csv"), ("nope.csv", "not found")),
        (("ur5", tmp_path / "folder.csv"), ("folder.csv",)),
        (("ur5", tmp_path / "binary.csv"), ("binary.csv",)),
        ((tmp_path / "nope.urdf", data), ("nope.urdf", "not found")),
        ((tmp_path / "binary.urdf", data), ("binary.urdf",)),
    ]
    for args, words in cases:
        _assert_refused(capfd, tmp_path, [command, *args, *out], *words)


#: Malformed URDFs (edit of the UR5's text: pattern, replacement) and a word the error should hold
#: ("{line}": the number of the last line, where the text breaks off).
MALFORMED_URDFS = {
    "truncated-xml": (r"(?s)<link name=\"forearm_link\">.*", '<link name="forearm_link', "{line}"),
    "bad-axis": (r'<axis xyz="[^"]*"/>', '<axis xyz="a b c"/>', "axis"),
    "nan-limit": (r'lower="[^"]*"', 'lower="nan"', "lower"),
    "unknown-joint-type": (r'type="revolute"', 'type="screw"', "screw"),
}


# Regression (was a bug): urdfdom (inside pin.buildModelFromXML) writes its own 'Error: ...' and 'at line
# ... in model.cpp' lines straight to file descriptor 2, so stderr holds 3-5 lines, and the pincal line
# says only 'The XML stream does not contain a valid URDF model' (the cause is in the other lines)
@pytest.mark.parametrize("case", list(MALFORMED_URDFS))
@pytest.mark.parametrize("command", ["twists", "calibrate"])
def test_malformed_urdf_is_one_error_line(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path, command: str, case: str
) -> None:
    """A damaged URDF: one error line (stderr at the file-descriptor level) that names the cause."""
    pattern, replacement, word = MALFORMED_URDFS[case]
    text = pincal.robot.robots.bundled_urdf("ur5").read_text(encoding="utf-8")
    urdf = tmp_path / "robot.urdf"
    text = re.sub(pattern, replacement, text, count=1)
    urdf.write_text(text, encoding="utf-8")
    data = _write(tmp_path / "data.csv", sim.lines)
    args = ["twists", urdf] if command == "twists" else ["calibrate", urdf, data, "-o", tmp_path / "o.urdf"]
    _assert_refused(capfd, tmp_path, args, "robot.urdf", word.format(line=text.count("\n") + 1))


@pytest.mark.parametrize(
    ("args", "word"),
    [
        (("no_such_robot",), "no_such_robot"),
        (("ur5", "--tip", "no_such_frame"), "no_such_frame"),
        (("ur5", "--lock", "no_such_joint"), "no_such_joint"),
        (("ur5", "--extend", "joint_compliance:no_such_joint"), "no_such_joint"),
        (("ur5", "--extend", "no_such_effect:elbow_joint"), "no_such_effect"),
    ],
    ids=["robot", "frame", "lock-joint", "extend-joint", "extend-effect"],
)
def test_unknown_robot_frame_joint(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path, args: tuple[str, ...], word: str
) -> None:
    data = _write(tmp_path / "data.csv", sim.lines)
    robot, *options = args
    _assert_refused(capfd, tmp_path, ["calibrate", robot, data, *options, "-o", tmp_path / "o.urdf"], word)


def test_twists_unknown_robot_and_frame(capfd: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    _assert_refused(capfd, tmp_path, ["twists", "no_such_robot"], "no_such_robot")
    _assert_refused(capfd, tmp_path, ["twists", "ur5", "--tip", "no_such_frame"], "no_such_frame")
    _assert_refused(capfd, tmp_path, ["twists", tmp_path / "nope.urdf"], "nope.urdf")


# Regression (was a bug): a tip frame with no joint before it (--tip base_link) is accepted: calibrate
# fits a 0-joint chain to data that moves 6 joints and exits 0 (check_scale skips a still tip, the rank
# check finds nothing lost)
def test_calibrate_tip_without_joints_is_refused(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path
) -> None:
    data = _write(tmp_path / "data.csv", sim.lines)
    _assert_refused(capfd, tmp_path, ["calibrate", "ur5", data, "--tip", "base_link"], "base_link")


# Regression (was a bug): the same 0-joint chain, with -o: urdf_writer.urdf_chain indexes an empty list
def test_calibrate_output_for_tip_without_joints_is_refused(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path
) -> None:
    data = _write(tmp_path / "data.csv", sim.lines)
    args = ["calibrate", "ur5", data, "--tip", "base_link", "--model", "offsets", "-o", tmp_path / "o.urdf"]
    _assert_refused(capfd, tmp_path, args, "base_link")


# Regression (was a bug): without --tip, a URDF path's tip is the last BODY frame in Pinocchio's order,
# which follows the alphabetical order of joint names: renaming the fixed joint base_link-base_fixed_joint
# to 'x' makes the tip 'base' and the chain empty, and calibrate then exits 0 (see above)
def test_default_tip_of_a_urdf_path_is_the_end_of_the_arm(
    capfd: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    text = pincal.robot.robots.bundled_urdf("ur5").read_text(encoding="utf-8")
    urdf = tmp_path / "robot.urdf"
    urdf.write_text(text.replace('name="base_link-base_fixed_joint"', 'name="x"'), encoding="utf-8")
    run = _run(capfd, "twists", urdf)
    assert run.code == 0, run.err
    assert "6 joints from the base" in run.out, run.out


# Regression (was a bug): tcp --robot ur5 --tip world (no joint before the tip): read_flange_poses indexes
# the joint values with an empty float array (IndexError), or inverts it for --degrees (TypeError)
@pytest.mark.parametrize("options", [(), ("--degrees",)], ids=["radians", "degrees"])
def test_tcp_tip_without_joints_is_refused(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path, options: tuple[str, ...]
) -> None:
    data = _write(tmp_path / "data.csv", sim.lines)
    _assert_refused(capfd, tmp_path, ["tcp", data, "--robot", "ur5", "--tip", "world", *options], "world")


# -- rank ---------------------------------------------------------------------------------------


def _alike(sim: Sim) -> Edit:
    """Every row the first pose, the measured point jittered by 10 µm."""

    def edit(lines: Lines) -> Lines:
        rng = np.random.default_rng(3)
        first = lines[1].split(",")
        out = [lines[0]]
        for _ in range(N_FIT):
            cells = list(first)
            for c in (6, 7, 8):
                cells[c] = repr(float(cells[c]) + float(rng.normal(0.0, 1e-5)))
            out.append(",".join(cells))
        return out

    return edit


def _frozen(name: str, value: float) -> Edit:
    """One joint at the same value in every row (the measured points stay as simulated).

    The points then disagree with the joint values, but that is what the rank check must catch
    first: this data cannot identify the joint's parameters, whatever the points say.
    """

    def edit(lines: Lines) -> Lines:
        k = _col(lines, name)
        out = [lines[0]]
        for line in lines[1:]:
            cells = line.split(",")
            cells[k] = repr(value)
            out.append(",".join(cells))
        return out

    return edit


def _still_data(sim: Sim, folder: Path) -> Path:
    """Simulated measurements with ``elbow_joint`` held at 0.8 rad in every pose."""
    truth = pincal.random_truth(sim.robot, 0)
    q = sim.robot.random_configurations(N_FIT, np.random.default_rng(5), 0.05)
    q[:, 2] = 0.8
    path = folder / "still.csv"
    pincal.write_csv(path, truth.measure(q, seed=6))
    return path


def test_rank_all_poses_alike(capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path) -> None:
    """30 copies of one pose: the parameters it cannot see and the cause are named."""
    data = _write(tmp_path / "alike.csv", _alike(sim)(list(sim.lines)))
    line = _assert_refused(
        capfd, tmp_path, ["calibrate", "ur5", data, "--report", tmp_path / "r.json"], "alike", "--partial"
    )
    assert re.search(r"identify [a-z_0-9]+\.[a-z]+", line), line  # names parameters


def test_rank_joint_never_moves(capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path) -> None:
    """elbow_joint still in every pose: exit 2 naming its parameters and the joint; ``--partial`` fits
    what the data identifies."""
    data = _still_data(sim, tmp_path)
    report = tmp_path / "r.json"
    line = _assert_refused(
        capfd,
        tmp_path,
        ["calibrate", "ur5", data, "--report", report],
        "elbow_joint never move",
        "--partial",
    )
    named = re.search(r"identify (.*?), which", line)
    assert named is not None, line
    assert any(p.strip().startswith("elbow_joint.") for p in named.group(1).split(","))

    run = _run(capfd, "calibrate", "ur5", data, "--report", report, "--partial")
    assert run.code == 0, run.err
    partial = json.loads(report.read_text(encoding="utf-8"))
    varied = tmp_path / "varied.json"
    assert (
        _run(capfd, "calibrate", "ur5", _write(tmp_path / "v.csv", sim.lines), "--report", varied).code == 0
    )
    full = json.loads(varied.read_text(encoding="utf-8"))
    assert partial["n_identifiable"] < full["n_identifiable"]
    assert np.isfinite(partial["train"]["after"]["rms_mm"])


def test_rank_joint_frozen_in_text_is_refused(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path
) -> None:
    """The same, made by editing the CSV: wrist_2_joint set to one value in every row."""
    data = _write(tmp_path / "data.csv", _frozen("wrist_2_joint", 0.3)(list(sim.lines)))
    _assert_refused(capfd, tmp_path, ["calibrate", "ur5", data], "wrist_2_joint never move")


def test_rank_alike_with_partial_fits_what_it_can(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path
) -> None:
    data = _write(tmp_path / "alike.csv", _alike(sim)(list(sim.lines)))
    report = tmp_path / "r.json"
    run = _run(capfd, "calibrate", "ur5", data, "--partial", "--report", report)
    assert run.code == 0, run.err
    rep = json.loads(report.read_text(encoding="utf-8"))
    assert rep["n_identifiable"] < rep["n_params"]


# -- outliers -----------------------------------------------------------------------------------


def _outlier_experiment(folder: Path, seed: int, row: int | None) -> tuple[Path, Path]:
    """UR5, 80 fitted and 100 held-out poses; a 5 mm jump of x,y,z in data row ``row`` (or none)."""
    robot = pincal.load_robot("ur5")
    _, fit, test = pincal.simulate(robot, 80, 100, seed=seed)
    lines = list(_csv_lines(fit, folder, f"clean{seed}.csv"))
    if row is not None:
        direction = np.random.default_rng(seed).normal(size=3)
        jump = 5e-3 * direction / np.linalg.norm(direction)  # [m]
        cells = lines[row].split(",")
        for k, c in enumerate(("x", "y", "z")):
            cells[_col(lines, c)] = repr(float(cells[_col(lines, c)]) + float(jump[k]))
        lines[row] = ",".join(cells)
    data = _write(folder / f"fit{seed}_{row}.csv", lines)
    test_path = folder / f"test{seed}.csv"
    pincal.write_csv(test_path, test)
    return data, test_path


def _held_out(capfd: pytest.CaptureFixture[str], data: Path, test: Path, report: Path, *options: str) -> dict:
    run = _run(capfd, "calibrate", "ur5", data, "--test", test, "--report", report, "--force", *options)
    assert run.code == 0, run.err
    return json.loads(report.read_text(encoding="utf-8")) | {"stdout": run.out}


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_one_5mm_outlier_among_80_poses(capfd: pytest.CaptureFixture[str], tmp_path: Path, seed: int) -> None:
    """A lost tracker beam (5 mm jump in one row) is found by row number, left out, and the
    held-out RMS stays within 10 % of the clean run's; a clean run leaves nothing out."""
    row = 17 + 11 * seed
    clean_data, test = _outlier_experiment(tmp_path, seed, None)
    bad_data, _ = _outlier_experiment(tmp_path, seed, row)
    report = tmp_path / "r.json"

    clean = _held_out(capfd, clean_data, test, report)
    assert clean["excluded_poses"] == []
    assert "outliers left out" not in clean["stdout"]

    screened = _held_out(capfd, bad_data, test, report)
    assert [p["row"] for p in screened["excluded_poses"]] == [row]
    assert screened["excluded_poses"][0]["residual_mm"] == pytest.approx(5.0, rel=0.2)
    assert f"row {row} (" in screened["stdout"]
    assert screened["n_poses"] == 79
    rms_clean = clean["test"]["after"]["rms_mm"]
    assert screened["test"]["after"]["rms_mm"] <= 1.1 * rms_clean

    # The screen is what keeps the error down: without it, the same outlier spoils the fit.
    unscreened = _held_out(capfd, bad_data, test, report, "--outliers", "0")
    assert unscreened["excluded_poses"] == []
    assert unscreened["test"]["after"]["rms_mm"] > 1.1 * rms_clean


@pytest.mark.parametrize("loss", ["soft_l1", "huber", "cauchy"])
def test_robust_loss_without_screen_resists_the_outlier(
    capfd: pytest.CaptureFixture[str], tmp_path: Path, loss: str
) -> None:
    """``--loss`` alone (screen off) keeps the held-out error far below the plain least-squares fit's."""
    clean_data, test = _outlier_experiment(tmp_path, 0, None)
    bad_data, _ = _outlier_experiment(tmp_path, 0, 40)
    report = tmp_path / "r.json"
    clean = _held_out(capfd, clean_data, test, report, "--outliers", "0")["test"]["after"]["rms_mm"]
    plain = _held_out(capfd, bad_data, test, report, "--outliers", "0")["test"]["after"]["rms_mm"]
    robust = _held_out(capfd, bad_data, test, report, "--outliers", "0", "--loss", loss)
    assert robust["excluded_poses"] == []
    assert plain > 1.1 * clean  # the outlier matters to a least-squares fit ...
    assert robust["test"]["after"]["rms_mm"] <= 1.1 * clean  # ... and not to a robust one


@pytest.mark.parametrize("seed", [3, 4, 5, 6, 7])
def test_clean_data_excludes_nothing(capfd: pytest.CaptureFixture[str], tmp_path: Path, seed: int) -> None:
    """The screen's false alarms: simulated data with Gaussian noise only loses no pose."""
    data, test = _outlier_experiment(tmp_path, seed, None)
    report = _held_out(capfd, data, test, tmp_path / "r.json")
    assert report["excluded_poses"] == []
    assert report["n_poses"] == 80


def test_outlier_rows_are_file_rows(capfd: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """With comment lines in the file and ``--holdout``, the excluded row is the data row of the
    file (comments and header not counted), not a position in the fitted subset."""
    n_rows, fraction, seed = 80, 0.25, 3
    dummy = pincal.Dataset(("j",), np.zeros((n_rows, 1)), np.zeros((n_rows, 3)))
    fitted, _ = dummy.split(fraction, seed)
    row = int(fitted.row_numbers[len(fitted) // 2])  # a row that stays in the fit
    assert row != len(fitted) // 2 + 1  # its position in the fitted subset differs
    bad, _ = _outlier_experiment(tmp_path, 0, row)
    commented = _write(
        tmp_path / "commented.csv", with_comments(list)(bad.read_text(encoding="utf-8").splitlines())
    )
    report = tmp_path / "r.json"
    args = ["--holdout", str(fraction), "--seed", str(seed), "--report", report]
    run = _run(capfd, "calibrate", "ur5", commented, *args)
    assert run.code == 0, run.err
    assert [p["row"] for p in json.loads(report.read_text(encoding="utf-8"))["excluded_poses"]] == [row]
    assert f"row {row} (" in run.out


# -- outputs: --force, atomic, never into an input ----------------------------------------------


def test_existing_outputs_need_force(capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path) -> None:
    """Each existing output (report, URDF, its sidecar) is kept without ``--force``, replaced with it."""
    data = _write(tmp_path / "data.csv", sim.lines)
    urdf, side, report = tmp_path / "out.urdf", tmp_path / "out.calibration.json", tmp_path / "r.json"
    args = ["calibrate", "ur5", data, "--model", "offsets", "-o", urdf, "--report", report]
    for existing in (report, urdf, side):
        existing.write_text("keep me\n", encoding="utf-8")
        _assert_refused(capfd, tmp_path, args, existing.name, "--force")
        existing.unlink()

    for path in (urdf, side, report):
        path.write_text("old\n", encoding="utf-8")
    before = data.read_bytes()
    run = _run(capfd, *args, "--force")
    assert run.code == 0, run.err
    assert json.loads(report.read_text(encoding="utf-8"))["n_poses"] == N_FIT
    assert json.loads(side.read_text(encoding="utf-8"))
    assert urdf.read_text(encoding="utf-8").lstrip().startswith("<?xml")
    assert data.read_bytes() == before
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


def test_outputs_naming_inputs_are_refused_even_with_force(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path
) -> None:
    """An output that is an input file (by name, another spelling, or a symlink) is refused."""
    data = _write(tmp_path / "data.csv", sim.lines)
    test = _write(tmp_path / "test.csv", sim.test_lines)
    robot = tmp_path / "robot.urdf"
    robot.write_bytes(pincal.robot.robots.bundled_urdf("ur5").read_bytes())
    (tmp_path / "sub").mkdir()
    (tmp_path / "link.json").symlink_to(data)
    base = ["calibrate", robot, data, "--test", test, "--model", "offsets", "--force"]
    for output in (
        ("--report", data),
        ("--report", test),
        ("--report", tmp_path / "sub" / ".." / "data.csv"),
        ("--report", tmp_path / "link.json"),
        ("-o", robot),
        ("--report", robot),
    ):
        _refused_as_input(_assert_refused(capfd, tmp_path, [*base, *output]), output[1])
    line = _assert_refused(capfd, tmp_path, ["diagnose", robot, data, "--json", data, "--force"])
    _refused_as_input(line, data)
    # A bundled robot's URDF is an input too.
    line = _assert_refused(
        capfd, tmp_path, ["calibrate", "ur5", data, "-o", pincal.robot.robots.bundled_urdf("ur5")]
    )
    _refused_as_input(line, pincal.robot.robots.bundled_urdf("ur5"))


def _refused_as_input(line: str, output: Path) -> None:
    """The error names the output and says it is one of the inputs."""
    assert output.name in line, line
    assert re.search(r"input|is the [\w ]*(file|URDF)", line), line


def test_interrupted_write_keeps_the_old_output(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Interrupted at the rename of an atomic write (Ctrl-C), ``--force`` leaves the old report whole
    and no temporary file behind, and the command ends with one line and exit code 130."""
    data = _write(tmp_path / "data.csv", sim.lines)
    report = tmp_path / "r.json"
    report.write_text('{"old": true}\n', encoding="utf-8")
    replace = os.replace

    def interrupted(src: str | Path, dst: str | Path) -> None:
        if Path(dst).name == report.name:
            raise KeyboardInterrupt
        replace(src, dst)

    monkeypatch.setattr(os, "replace", interrupted)
    run = _run(capfd, "calibrate", "ur5", data, "--model", "offsets", "--report", report, "--force")
    monkeypatch.undo()
    assert run.code == 130 and run.err.splitlines() == [run.err.strip()], run.err
    assert run.err.startswith("pincal: error: interrupted")
    assert report.read_text(encoding="utf-8") == '{"old": true}\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data.csv", "r.json"]


def test_one_file_for_two_outputs_and_missing_folder(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path
) -> None:
    data = _write(tmp_path / "data.csv", sim.lines)
    args = ["calibrate", "ur5", data, "--force"]
    _assert_refused(
        capfd,
        tmp_path,
        [*args, "-o", tmp_path / "o.urdf", "--report", tmp_path / "o.calibration.json"],
        "two",
    )
    _assert_refused(capfd, tmp_path, [*args, "--report", tmp_path / "no_dir" / "r.json"], "no_dir")
    _assert_refused(capfd, tmp_path, [*args, "--report", tmp_path], "folder")


# Regression (was a bug): -o . (or -o /): cli._calibrate computes the sidecar name with Path.with_name
# before _check_outputs says the output is a folder, and Path('.').with_name raises ValueError
def test_output_folder_dot_is_refused(capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path) -> None:
    data = _write(tmp_path / "data.csv", sim.lines)
    _assert_refused(capfd, tmp_path, ["calibrate", "ur5", data, "-o", "."], "folder")


def test_diagnose_json_needs_force(capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path) -> None:
    data = _write(tmp_path / "data.csv", sim.lines)
    out = tmp_path / "d.json"
    out.write_text("keep me\n", encoding="utf-8")
    args = ["diagnose", "ur5", data, "--folds", "3", "--model", "offsets", "--json", out]
    _assert_refused(capfd, tmp_path, args, "d.json", "--force")
    run = _run(capfd, *args, "--force")
    assert run.code == 0, run.err
    assert "baseline" in json.loads(out.read_text(encoding="utf-8"))


# -- tcp ----------------------------------------------------------------------------------------


def _tcp_lines(n: int = 6, header: str = "x,y,z,a,b,c") -> list[str]:
    """Flange poses [mm, deg] touching one point with a 150 mm tool (R = Rz(a) Ry(b) Rx(c))."""
    rng = np.random.default_rng(1)
    abc = rng.uniform(-40.0, 40.0, (n, 3))
    rot = pincal.tool.tcp.euler_zyx(*np.deg2rad(abc).T)
    pos = np.array([800.0, 100.0, 300.0]) - rot @ np.array([10.0, -20.0, 150.0])
    return [header, *(",".join(repr(float(v)) for v in row) for row in np.hstack([pos, abc]))]


@pytest.mark.parametrize(
    ("edit", "words"),
    [
        (drop_column("c"), ("missing column", "c")),
        (set_cell(2, "b", "nan"), ("row 2", "b")),
        (set_cell(3, "x", "12,5"), ("row 3",)),
        (set_cell(1, "a", "ninety"), ("row 1", "ninety")),
        (keep_rows(2), ("3 poses",)),
        (keep_rows(0), ("no data rows",)),
        (add_column("x", "1"), ("duplicated", "x")),
    ],
    ids=["missing-column", "nan", "extra-field", "non-numeric", "two-poses", "header-only", "duplicated"],
)
def test_tcp_bad_poses(
    capfd: pytest.CaptureFixture[str], tmp_path: Path, edit: Edit, words: tuple[str, ...]
) -> None:
    poses = _write(tmp_path / "poses.csv", edit(_tcp_lines()))
    _assert_refused(capfd, tmp_path, ["tcp", poses, "--units", "mm", "--json", tmp_path / "t.json"], *words)


def test_tcp_outputs(capfd: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """``tcp --json``: an existing file needs ``--force``; the input file is never the output."""
    poses = _write(tmp_path / "poses.csv", _tcp_lines())
    out = tmp_path / "t.json"
    out.write_text("keep me\n", encoding="utf-8")
    _assert_refused(capfd, tmp_path, ["tcp", poses, "--units", "mm", "--json", out], "--force")
    line = _assert_refused(capfd, tmp_path, ["tcp", poses, "--units", "mm", "--json", poses, "--force"])
    _refused_as_input(line, poses)
    run = _run(capfd, "tcp", poses, "--units", "mm", "--json", out, "--force")
    assert run.code == 0, run.err
    assert json.loads(out.read_text(encoding="utf-8"))["tcp"] == pytest.approx([10.0, -20.0, 150.0], abs=1e-6)


# Regression (was a bug): a row with qw=qx=qy=qz=0 divides by a zero norm in read_flange_poses and ends in
# numpy.linalg.LinAlgError ('SVD did not converge') instead of exit 2
def test_tcp_zero_quaternion_is_refused(capfd: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    lines = ["x,y,z,qw,qx,qy,qz"] + [f"{100 + k},{k},{3 * k},1,0,0,0" for k in range(5)]
    lines[3] = "102,2,6,0,0,0,0"
    poses = _write(tmp_path / "poses.csv", lines)
    _assert_refused(capfd, tmp_path, ["tcp", poses], "row 3")


# -- option values that ended in tracebacks (found by fuzzing the options) ----------------------


# Regression (was a bug): a negative --seed (ValueError from default_rng), a --holdout that leaves no
# pose to fit (ValueError in identifiability.analyse), a finite but huge --tool-point (OverflowError).
@pytest.mark.parametrize(
    "options",
    [
        pytest.param(
            ("--holdout", "0.3", "--seed", "-1"),
            id="negative-seed",
        ),
        pytest.param(
            ("--holdout", "0.99"),
            id="holdout-leaves-nothing",
        ),
        pytest.param(
            ("--tool-point", "1e300,0,0"),
            id="huge-tool-point",
        ),
    ],
)
def test_calibrate_option_values_end_in_exit_2(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path, options: tuple[str, ...]
) -> None:
    data = _write(tmp_path / "data.csv", sim.lines)
    _assert_refused(capfd, tmp_path, ["calibrate", "ur5", data, "--model", "offsets", *options], options[-2])


# Regression (was a bug): diagnose --folds < 2 or a negative --seed raise ValueError
@pytest.mark.parametrize(
    "options",
    [
        pytest.param(("--folds", "1"), id="one-fold"),
        pytest.param(("--folds", "0"), id="no-fold"),
        pytest.param(("--seed", "-1"), id="negative-seed"),
    ],
)
def test_diagnose_option_values_end_in_exit_2(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path, options: tuple[str, ...]
) -> None:
    data = _write(tmp_path / "data.csv", sim.lines)
    _assert_refused(capfd, tmp_path, ["diagnose", "ur5", data, "--model", "offsets", *options], options[0])


# Regression (was a bug): distance data with one pose measured twice (a repeated row): the pair of
# identical poses has zero model distance, its Jacobian row is 0/0 = NaN, and identifiability.analyse
# raises ValueError('no parameter has any effect on the measurements')
@pytest.mark.parametrize("model", ["offsets", "placements"])
def test_distance_data_with_a_repeated_pose(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path, model: str
) -> None:
    """Measuring one pose twice is common: the command calibrates, or says which rows to fix."""
    lines = list(sim.lines)
    data = _write(tmp_path / "data.csv", [lines[0], lines[1], *lines[1:]])
    run = _run(capfd, "calibrate", "ur5", data, "--measure", "distance", "--model", model)
    if run.code != 0:
        assert "row" in _error_line(run)


# Regression (was a bug): a CSV field over 131072 characters raises _csv.Error (field larger than field
# limit), not caught by data.read_table/csv_columns
def test_huge_field_is_refused(capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path) -> None:
    data = _write(tmp_path / "data.csv", [*sim.lines, "9" * 200_000])
    _assert_refused(capfd, tmp_path, ["calibrate", "ur5", data], "data.csv")


# -- hostile URDFs ------------------------------------------------------------------------------

#: DOCTYPEs that could make an XML parser read a local file or expand entities ({secret}: its URL).
HOSTILE_DOCTYPES = {
    "external-entity": '<!DOCTYPE robot [\n  <!ENTITY s SYSTEM "{secret}">\n]>',
    "parameter-entity": '<!DOCTYPE robot [\n  <!ENTITY % p SYSTEM "{secret}">\n  %p;\n  <!ENTITY s "x">\n]>',
    "external-dtd": '<!DOCTYPE robot SYSTEM "{secret}">',
    "public-dtd": '<!DOCTYPE robot PUBLIC "-//pincal//x" "{secret}">',
    "entity-expansion": '<!DOCTYPE robot [\n  <!ENTITY a "aaaaaaaaaa">\n  <!ENTITY s "&a;&a;&a;&a;&a;">\n]>',
    "comment-hides-entity": '<!DOCTYPE robot [\n  <!-- <robot -->\n  <!ENTITY s SYSTEM "{secret}">\n]>',
}
# "comment-hides-entity" is a regression case: the guard once looked for declarations only up to the
# first "<robot", which a comment inside the DOCTYPE can hold.


def _hostile_urdf(folder: Path, doctype: str) -> tuple[Path, Path]:
    """A copy of the UR5 URDF with ``doctype`` and ``&s;`` in the robot's name, a new link's name and
    the text of an element (where an entity-resolving parser would put the secret file's text)."""
    secret = folder / "secret.txt"
    secret.write_text(SECRET + "\n", encoding="utf-8")
    text = pincal.robot.robots.bundled_urdf("ur5").read_text(encoding="utf-8")
    declaration = text.index("?>") + 2
    body = text[declaration:]
    start = body.index("<robot")
    end = body.index(">", start) + 1
    body = (
        body[:start]
        + '<robot name="ur5_&s;">\n  <link name="leak_&s;"/>\n  <joint name="leak_joint" type="fixed">'
        + '<parent link="tool0"/><child link="leak_&s;"/></joint>\n  <gazebo><leak>&s;</leak></gazebo>'
        + body[end:]
    )
    urdf = folder / "hostile.urdf"
    urdf.write_text(
        text[:declaration] + "\n" + doctype.format(secret=secret.as_uri()) + body, encoding="utf-8"
    )
    return urdf, secret


def test_hostile_urdf_would_leak_through_a_resolving_parser(tmp_path: Path) -> None:
    """The control of the tests below: parsed with entity resolution on, the hostile URDF does hold
    the secret, so a command that resolved it would show it."""
    from lxml import etree

    urdf, _ = _hostile_urdf(tmp_path, HOSTILE_DOCTYPES["external-entity"])
    text = urdf.read_text(encoding="utf-8").replace('"ur5_&s;"', '"ur5"').replace('"leak_&s;"', '"leak"')
    parser = etree.XMLParser(resolve_entities=True, load_dtd=True, no_network=True)
    root = etree.fromstring(text.encode("utf-8"), parser, base_url=str(urdf))
    assert SECRET in root.findtext("gazebo/leak")


@pytest.mark.parametrize("case", list(HOSTILE_DOCTYPES))
def test_hostile_urdf_leaks_nothing(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path, case: str
) -> None:
    """Whatever the commands do with the URDF, the secret file's text appears in no output."""
    urdf, _ = _hostile_urdf(tmp_path, HOSTILE_DOCTYPES[case])
    data = _write(tmp_path / "data.csv", sim.lines)
    out = tmp_path / "out"
    out.mkdir()
    commands = [
        ["calibrate", urdf, data, "--model", "offsets", "-o", out / "c.urdf", "--report", out / "r.json"],
        ["calibrate", urdf, data, "--tip", "no_such_frame"],
        ["calibrate", urdf, data, "--tip", "leak_&s;", "--model", "offsets"],
        ["twists", urdf],
        ["tcp", data, "--robot", urdf, "--json", out / "t.json"],
    ]
    for args in commands:
        run = _run(capfd, *args)
        assert run.code in (0, 2), (args, run.err)
        assert "Traceback" not in run.err
        assert SECRET not in run.out + run.err, args
    for path in out.iterdir():
        assert SECRET not in path.read_text(encoding="utf-8", errors="replace"), path


@pytest.mark.parametrize("case", list(HOSTILE_DOCTYPES))
def test_hostile_urdf_is_refused(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path, case: str
) -> None:
    """A DOCTYPE with entity declarations or an external DTD: exit 2 before anything is written."""
    urdf, _ = _hostile_urdf(tmp_path, HOSTILE_DOCTYPES[case])
    data = _write(tmp_path / "data.csv", sim.lines)
    for args in (
        [
            "calibrate",
            urdf,
            data,
            "--model",
            "offsets",
            "-o",
            tmp_path / "c.urdf",
            "--report",
            tmp_path / "r.json",
        ],
        ["twists", urdf],
        ["tcp", data, "--robot", urdf, "--json", tmp_path / "t.json"],
    ):
        _assert_refused(capfd, tmp_path, args, "DOCTYPE")


def test_plain_doctype_is_accepted(capfd: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """A DOCTYPE that declares nothing cannot read anything: the URDF loads."""
    text = pincal.robot.robots.bundled_urdf("ur5").read_text(encoding="utf-8")
    declaration = text.index("?>") + 2
    urdf = tmp_path / "doctype.urdf"
    urdf.write_text(text[:declaration] + "\n<!DOCTYPE robot>" + text[declaration:], encoding="utf-8")
    run = _run(capfd, "twists", urdf)
    assert run.code == 0, run.err


class _FifoWatch:
    """Named pipes that record whether anything opened them for reading.

    A reader's ``open`` blocks until a writer comes; a thread polls each pipe with a non-blocking
    write-open, which succeeds only while a reader has it open: it records the pipe (once) and
    closes it (the reader sees an empty file instead of hanging).
    """

    def __init__(self, paths: Sequence[Path]) -> None:
        self.paths = list(paths)
        self.opened: list[Path] = []
        self._stop = threading.Event()
        for path in self.paths:
            os.mkfifo(path)
        self._thread = threading.Thread(target=self._watch, daemon=True)

    def _watch(self) -> None:
        while not self._stop.is_set():
            for path in self.paths:
                try:
                    fd = os.open(path, os.O_WRONLY | os.O_NONBLOCK)
                except OSError:
                    continue
                if path not in self.opened:  # a reader still closing is seen again: once is enough
                    self.opened.append(path)
                os.close(fd)
            self._stop.wait(0.001)

    def __enter__(self) -> _FifoWatch:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()


def test_mesh_paths_outside_the_urdf_folder_are_not_opened(
    capfd: pytest.CaptureFixture[str], sim: Sim, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Meshes by ``package://`` and by relative paths leading out of the URDF's folder: calibration
    needs no mesh, opens none of them, and the corrected URDF keeps the references as written."""
    outside = tmp_path / "outside"
    outside.mkdir()
    (tmp_path / "pkgs" / "evil").mkdir(parents=True)
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tmp_path / "pkgs"))
    robot_dir = tmp_path / "robot"
    robot_dir.mkdir()
    references = [
        "package://evil/../../outside/pkg_mesh.stl",
        "../outside/rel_mesh.stl",
        "../../../../../../../../etc/passwd",
    ]
    text = pincal.robot.robots.bundled_urdf("ur5").read_text(encoding="utf-8")
    meshes = re.findall(r'filename="(package://[^"]+)"', text)
    assert meshes
    for k, mesh in enumerate(meshes):
        text = text.replace(f'filename="{mesh}"', f'filename="{references[k % len(references)]}"')
    urdf = robot_dir / "ur5.urdf"
    urdf.write_text(text, encoding="utf-8")
    data = _write(tmp_path / "data.csv", sim.lines)
    out = tmp_path / "out.urdf"

    probe = tmp_path / "probe.fifo"
    with _FifoWatch([outside / "pkg_mesh.stl", outside / "rel_mesh.stl", probe]) as watch:
        run = _run(capfd, "calibrate", urdf, data, "--model", "offsets", "-o", out)
        twists = _run(capfd, "twists", urdf)
        assert watch.opened == []
        assert probe.read_bytes() == b""  # the watch does see a reader (and lets it go) ...
    assert watch.opened == [probe]  # ... and saw none of the meshes opened
    assert run.code == 0, run.err
    assert twists.code == 0, twists.err
    written = out.read_text(encoding="utf-8")
    for reference in references:
        assert f'filename="{reference}"' in written
    assert "root:" not in written


def test_a_column_hint_speaks_of_units_only_for_a_unit_in_the_name() -> None:
    """``x_mm``, ``y [mm]``, ``a(deg)`` carry a unit; a name that merely ends in the letter m
    (``elbow_joint_custom``) is a misspelling, and the hint says nothing of units."""
    from pincal.data.csv_table import misspelt

    assert "units=mm" in misspelt(["x", "y", "a"], ["x_mm", "y [mm]", "a(deg)"])
    hint = misspelt(["elbow_joint"], ["elbow_joint_custom"])
    assert "'elbow_joint_custom' for elbow_joint?" in hint and "unit" not in hint
