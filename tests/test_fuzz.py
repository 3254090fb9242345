"""Property tests (hypothesis) of the CSV reader and the command line on malformed input.

- :func:`pincal.read_csv` on random text (headers with duplicates, empty and non-ASCII names;
  cells such as ``nan``, ``inf``, ``1e400``, quotes, empty; extra and missing fields; comments,
  a BOM, NUL bytes, binary) either raises a :class:`pincal.PincalError` or returns a dataset of
  finite values whose shape matches the file.
- :func:`pincal.cli.main` on corrupted measurement and flange-pose files, hostile-ish URDFs and
  random argument lists built from the real parser's options ends with exit code 0 or 2, never a
  traceback, and on exit code 2 prints exactly one stderr line starting with ``pincal: error:``
  and no warning. ``--help`` ends argparse's way, in ``SystemExit(0)``, counted as exit code 0.

The bugs these properties found are reproduced one by one in ``test_bad_input.py`` (the tests
under a ``# Regression (was a bug)`` comment). ``PINCAL_FUZZ_SCALE=20`` multiplies the number of
examples for a deeper search than the normal suite has time for. Every example runs in a fresh
folder, which is the working directory during the run.
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import math
import os
import re
import shutil
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import pincal
import pincal.robot.robots
import pincal.tool.tcp
from pincal import cli

#: Fast and quiet: no example database in the working tree, no per-example deadline.
_BASE = settings(
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


#: Multiplies every test's number of examples: ``PINCAL_FUZZ_SCALE=20 pytest tests/test_fuzz.py``
#: fuzzes deeper than the normal suite has time for.
SCALE = float(os.environ.get("PINCAL_FUZZ_SCALE", "1"))


def fuzz(max_examples: int) -> settings:
    """The fuzzing settings with ``max_examples`` examples (times :data:`SCALE`)."""
    return settings(_BASE, max_examples=max(1, round(max_examples * SCALE)))


UR5 = pincal.load_robot("ur5")
JOINTS = UR5.joint_names
N_POSES = 20
FRAMES = ("tool0", "wrist_3_link", "base_link", "world", "no_such_frame", "")

# -- tokens -------------------------------------------------------------------------------------

#: Cell texts that have broken CSV readers: non-finite, overflowing, localised, quoted, odd unicode.
BAD_CELLS = (
    "nan",
    "NaN",
    "-nan",
    "inf",
    "-inf",
    "Infinity",
    "1e400",
    "-1e400",
    "1e-400",
    "",
    " ",
    "1,5",
    '"1.0"',
    '"',
    '""',
    "'",
    "0x10",
    "1_000",
    "١٢",
    "１",
    "1.0.0",
    "--1",
    "+",
    "e5",
    "None",
    "true",
    "#",
    "\x00",
    "\ufeff1",
    "1\u2028",
    "\t",
    "1e308",
    "-1e308",
    "3.14159e+00",
    "0",
    "-0",
    "1e-12",
    "12345678901234567890",
)
#: Column names: the real ones, near misses, duplicates and junk.
NAMES = (
    *JOINTS,
    "x",
    "y",
    "z",
    "qw",
    "qx",
    "qy",
    "qz",
    "",
    " x",
    "X",
    "joint_7",
    "q1",
    "ÿ",
    "#x",
    '"x"',
    "x\x00",
)

cells = st.one_of(
    st.sampled_from(BAD_CELLS),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.text(max_size=6),
)
names = st.one_of(st.sampled_from(NAMES), st.text(max_size=8))


@dataclass(frozen=True)
class Run:
    """Outcome of one in-process run."""

    code: int
    out: str
    err: str
    warnings: tuple[str, ...]


def _run(capfd: pytest.CaptureFixture[str], argv: Sequence[str]) -> Run:
    """``main(argv)``, its exit code (``--help``'s SystemExit(0) counted as 0), output and warnings.

    Anything else escaping ``main`` (SystemExit with another code included) fails the property.
    """
    capfd.readouterr()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            code = cli.main(list(argv))
        except SystemExit as exc:
            assert exc.code in (0, None), f"SystemExit({exc.code!r}) from {argv!r}"
            code = 0
    captured = capfd.readouterr()
    return Run(code, captured.out, captured.err, tuple(str(w.message) for w in caught))


def _check(run: Run, argv: Sequence[str]) -> None:
    """The contract: exit 0 or 2; on 2, one ``pincal: error:`` line on stderr (file descriptor 2,
    so what C++ code writes counts too) and no warning (which would be more stderr lines)."""
    assert run.code in (0, 2), (argv, run.code, run.err)
    assert "Traceback" not in run.err, argv
    if run.code == 2:
        lines = run.err.splitlines()
        assert len(lines) == 1, (argv, run.err)
        assert lines[0].startswith("pincal: error: "), (argv, run.err)
        assert not run.warnings, (argv, run.warnings)


@contextlib.contextmanager
def _fresh_folder(root: Path) -> Iterator[Path]:
    """A new empty folder under ``root``, the working directory while in use, removed after."""
    folder = Path(os.path.realpath(root)) / f"ex{next(_COUNTER)}"
    folder.mkdir()
    old = os.getcwd()
    os.chdir(folder)
    try:
        yield folder
    finally:
        os.chdir(old)
        shutil.rmtree(folder, ignore_errors=True)


_COUNTER = itertools.count()


def _one_in(n: int, draw: st.DrawFn) -> bool:
    """True about once in ``n`` draws (hypothesis favours the first choice, here False)."""
    return draw(st.sampled_from([False] * (n - 1) + [True]))


# -- (a) read_csv on malformed text -------------------------------------------------------------


@st.composite
def csv_texts(draw: st.DrawFn) -> bytes:
    """A measurement-CSV-like file: a random header, random rows, comments, BOM, NULs or binary."""
    if _one_in(10, draw):
        return draw(st.binary(max_size=300))
    header = list(draw(st.permutations([*JOINTS, "x", "y", "z"])))
    for _ in range(draw(st.integers(0, 3))):
        action = draw(st.sampled_from(["drop", "duplicate", "insert", "rename"]))
        k = draw(st.integers(0, max(0, len(header) - 1)))
        if action == "drop" and header:
            header.pop(k)
        elif action == "duplicate" and header:
            header.insert(draw(st.integers(0, len(header))), header[k])
        elif action == "insert":
            header.insert(k, draw(names))
        elif header:
            header[k] = draw(names)
    n_rows = draw(st.integers(0, 6))
    good = st.floats(-3.0, 3.0, allow_nan=False).map(repr)
    lines = [",".join(header)]
    for _ in range(n_rows):
        width = len(header) + draw(st.sampled_from([0, 0, 0, -1, 1, -len(header)]))
        row = [draw(st.one_of(good, good, cells)) for _ in range(max(0, width))]
        lines.append(",".join(row))
        if _one_in(5, draw):
            lines.append(draw(st.sampled_from(["# comment", "#", "  # indented", "", "   ", ",,,", "\x00"])))
    newline = draw(st.sampled_from(["\n", "\r\n", "\r"]))
    text = newline.join(lines) + draw(st.sampled_from(["", newline]))
    if draw(st.booleans()):
        pos = draw(st.integers(0, len(text)))
        text = text[:pos] + draw(st.text(max_size=5)) + text[pos:]
    data = ("\ufeff" if draw(st.booleans()) else "").encode() + text.encode("utf-8", "surrogatepass")
    if _one_in(6, draw):
        pos = draw(st.integers(0, len(data)))
        data = data[:pos] + draw(st.binary(min_size=1, max_size=4)) + data[pos:]
    return data


@fuzz(400)
@given(
    text=csv_texts(),
    joints=st.sampled_from([JOINTS, JOINTS[:3], ("a", "a"), ()]),
    degrees=st.booleans(),
    units=st.sampled_from(["m", "mm"]),
)
def test_read_csv_raises_only_pincal_errors(
    tmp_path: Path, text: bytes, joints: tuple[str, ...], degrees: bool, units: str
) -> None:
    """Malformed text: a PincalError, or a dataset of finite numbers, one pose per data row."""
    path = tmp_path / "data.csv"
    path.write_bytes(text)
    try:
        data = pincal.read_csv(path, joints, degrees=degrees, units=units)
    except pincal.PincalError as exc:
        assert str(exc).strip()
        return
    assert len(data) >= 1
    assert data.q.shape == (len(data), len(joints))
    assert data.points.shape == (len(data), 3)
    assert np.all(np.isfinite(data.q)) and np.all(np.isfinite(data.points))
    if data.quaternions is not None:
        assert data.quaternions.shape == (len(data), 4)
        assert np.all(np.isfinite(data.quaternions))
    assert len(data) <= len(text.decode("utf-8-sig", errors="replace").splitlines()) - 1


# -- (b) the command line -----------------------------------------------------------------------


def _subparser(name: str) -> argparse.ArgumentParser:
    parser = cli._build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[name]


OUTPUT_DESTS = {"output", "report", "json", "plots"}
#: File names an output option may get: new, existing, inputs, folders, missing folders.
OUTPUT_NAMES = (
    "out.urdf",
    "r.json",
    "t.json",
    "data.csv",
    "test.csv",
    "robot.urdf",
    ".",
    "sub",
    "nodir/x.json",
)
FLOATS = st.one_of(
    st.sampled_from(["0", "-1", "0.3", "0.5", "1", "2", "nan", "inf", "-inf", "1e400", "1e-300", "3", "x"]),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
)
#: Argument text as a shell could pass it: no NUL, no path separator (nothing outside the folder).
junk = st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00/"), max_size=10)


def _mostly(valid: st.SearchStrategy[str], wrong: st.SearchStrategy[str] = junk) -> st.SearchStrategy[str]:
    """``valid`` five times in six, ``wrong`` otherwise (roughly: hypothesis picks a branch)."""
    return st.one_of(valid, valid, valid, valid, valid, wrong)


def _value(action: argparse.Action) -> st.SearchStrategy[str]:
    """Values for an option: mostly what the option expects, some junk."""
    dest = action.dest
    if action.choices is not None:
        return _mostly(st.sampled_from([str(c) for c in action.choices]))
    if dest in OUTPUT_DESTS:
        return st.sampled_from(OUTPUT_NAMES)
    if dest == "test":
        return st.sampled_from(["test.csv", "test.csv", "data.csv", "missing.csv", "robot.urdf"])
    if dest == "tip":
        return _mostly(st.sampled_from(FRAMES))
    if dest == "lock":
        return _mostly(st.sampled_from([JOINTS[-1], ",".join(JOINTS[-2:]), ",".join(JOINTS), ","]))
    if dest == "extend":
        effects = st.sampled_from([*pincal.EFFECTS, "no_such", ""])
        joints = st.sampled_from([*JOINTS, "no_such", ""])
        return st.one_of(st.sampled_from(["auto", "none"]), _mostly(st.tuples(effects, joints).map(":".join)))
    if dest in ("tool_point", "payload"):
        n = 3 if dest == "tool_point" else 4
        return _mostly(st.lists(FLOATS, min_size=n - 1, max_size=n + 1).map(",".join))
    if dest == "columns":
        pairs = st.tuples(
            st.sampled_from(["x", "y", "z", "a", "b", "c", "qw", "q"]), st.sampled_from(["x", "a", "X"])
        )
        return _mostly(st.lists(pairs.map("=".join), max_size=3).map(",".join))
    if dest == "robot":
        return st.sampled_from(["ur5", "ur5", "mrres5", "robot.urdf", "no_such_robot", "data.csv"])
    if dest == "add_frame":
        return _mostly(st.sampled_from(["smr", "tcp.1", "1bad", "a b", ""]))
    if action.type is int:
        return _mostly(st.integers(-3, 10**6).map(str))
    if action.type is float:
        return FLOATS
    return junk


def _options(name: str) -> list[st.SearchStrategy[list[str]]]:
    """One strategy per option of the real ``pincal NAME`` parser: ``[option]`` or ``[option, value]``."""
    out = []
    for action in _subparser(name)._actions:
        if not action.option_strings or isinstance(action, argparse._HelpAction):
            continue
        flag = st.sampled_from(action.option_strings)
        if action.nargs == 0:
            out.append(flag.map(lambda f: [f]))
        else:
            out.append(st.tuples(flag, _value(action)).map(list))
    return out


def _arguments(name: str) -> st.SearchStrategy[list[str]]:
    """Random option lists for ``pincal NAME``, sometimes with a junk token or ``--help``."""
    one = st.one_of(*_options(name))
    none: st.SearchStrategy[list[str]] = st.just([])
    extra = st.one_of(*[none] * 8, st.lists(junk, max_size=1), st.sampled_from([["-h"], ["--help"], ["--"]]))
    return st.tuples(st.lists(one, max_size=3), extra).map(lambda t: [a for o in t[0] for a in o] + t[1])


def _run_checked(capfd: pytest.CaptureFixture[str], argv: Sequence[str]) -> Run:
    """:func:`_run` in the working folder, then the contract: :func:`_check`; input files unchanged;
    on exit code 2 no file appeared or changed; no temporary file left."""
    before = _snapshot()
    run = _run(capfd, argv)
    _check(run, argv)
    after = _snapshot()
    for name in _inputs(argv):
        assert after.get(name) == before[name], (argv, f"input {name} changed")
    if run.code == 2:
        assert after == before, (argv, sorted(set(after) ^ set(before)))
    assert not [name for name in after if name.endswith(".tmp")], argv
    command = argv[0] if argv else "(none)"
    event(f"{command}: exit {run.code}" + (f" ({_gist(run.err.splitlines()[-1])})" if run.code else ""))
    return run


OUTPUT_FLAGS = {"-o", "--output", "--report", "--json", "--plots"}


def _inputs(argv: Sequence[str]) -> set[str]:
    """The files of the working folder that ``argv`` names as inputs (not right after an output flag)."""
    files = set(_snapshot())
    return {a for k, a in enumerate(argv) if a in files and (k == 0 or argv[k - 1] not in OUTPUT_FLAGS)}


def _snapshot() -> dict[str, bytes]:
    """Every file under the working folder and its bytes."""
    folder = Path.cwd()
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def _gist(error: str) -> str:
    """The kind of an error message (its words, without paths, numbers or quoted text)."""
    text = re.sub(r"'[^']*'|\S*/\S*|[-+.\d]+(e[-+]?\d+)?", "", error.removeprefix("pincal: error: "))
    return " ".join(text.split()[:6])


@st.composite
def corrupted(draw: st.DrawFn, lines: Sequence[str]) -> bytes:
    """A valid CSV with 0-4 random corruptions: cells, lines, columns, truncation, bytes."""
    rows = [line.split(",") for line in lines]
    for _ in range(draw(st.sampled_from([0, 0, 1, 1, 2, 4]))):
        op = draw(
            st.sampled_from(
                ["cell", "cell", "header", "drop_line", "dup_line", "comment", "drop_col", "add_col"]
            )
        )
        r = draw(st.integers(1, len(rows) - 1)) if len(rows) > 1 else 0  # the header has its own ops
        if op == "cell" and rows and rows[r]:
            rows[r][draw(st.integers(0, len(rows[r]) - 1))] = draw(cells)
        elif op == "header" and rows and rows[0]:
            if _one_in(4, draw):
                rows.pop(0)
            else:
                rows[0][draw(st.integers(0, len(rows[0]) - 1))] = draw(names)
        elif op == "drop_line" and rows:
            rows.pop(r)
        elif op == "dup_line" and rows:
            rows.insert(r, list(rows[r]))
        elif op == "comment":
            rows.insert(r, [draw(st.sampled_from(["# note", "#", ""]))])
        elif op in ("drop_col", "add_col") and rows and rows[0]:
            c = draw(st.integers(0, len(rows[0]) - 1))
            for row in rows:
                if op == "drop_col" and c < len(row):
                    row.pop(c)
                elif op == "add_col":
                    row.insert(c, draw(names) if row is rows[0] else draw(cells))
    data = "\n".join(",".join(row) for row in rows).encode("utf-8", "surrogatepass") + b"\n"
    if _one_in(6, draw):
        data = data[: draw(st.integers(0, len(data)))]
    if _one_in(6, draw):
        pos = draw(st.integers(0, len(data)))
        data = data[:pos] + draw(st.binary(min_size=1, max_size=3)) + data[pos:]
    return data


def _ur5_lines() -> tuple[list[str], list[str]]:
    _, fit, test = pincal.simulate(UR5, N_POSES, 10, seed=4)
    buffer = []
    for data in (fit, test):
        header = [*data.joint_names, "x", "y", "z"]
        rows = [",".join(repr(float(v)) for v in (*q, *p)) for q, p in zip(data.q, data.points)]
        buffer.append([",".join(header), *rows])
    return buffer[0], buffer[1]


DATA_LINES, TEST_LINES = _ur5_lines()
URDF_TEXT = pincal.robot.robots.bundled_urdf("ur5").read_text(encoding="utf-8")


def _setup(folder: Path, data: bytes) -> None:
    """The files every command example may name."""
    (folder / "data.csv").write_bytes(data)
    (folder / "test.csv").write_text("\n".join(TEST_LINES) + "\n", encoding="utf-8")
    (folder / "robot.urdf").write_text(URDF_TEXT, encoding="utf-8")
    (folder / "sub").mkdir()


@fuzz(400)
@given(
    data=corrupted(DATA_LINES),
    robot=st.sampled_from(
        ["ur5", "ur5", "ur5", "robot.urdf", "robot.urdf", "mrres5", "no_such_robot", "data.csv"]
    ),
    options=_arguments("calibrate"),
)
def test_calibrate_on_malformed_input(
    tmp_path: Path, capfd: pytest.CaptureFixture[str], data: bytes, robot: str, options: list[str]
) -> None:
    """``pincal calibrate`` on a corrupted CSV with random options: exit 0 or 2, never a traceback.
    ``--extend none`` unless the options draw an ``--extend`` (the default's diagnosis on every
    example would take minutes; the reading is what is fuzzed)."""
    argv = ["calibrate", robot, "data.csv", "--model", "offsets", "--extend", "none", *options]
    with _fresh_folder(tmp_path) as folder:
        _setup(folder, data)
        _run_checked(capfd, argv)


def _flange_lines(quaternions: bool) -> list[str]:
    rng = np.random.default_rng(2)
    abc = rng.uniform(-40.0, 40.0, (6, 3))
    rot = pincal.tool.tcp.euler_zyx(*np.deg2rad(abc).T)
    pos = np.array([800.0, 100.0, 300.0]) - rot @ np.array([10.0, -20.0, 150.0])
    if not quaternions:
        return ["x,y,z,a,b,c", *(",".join(repr(float(v)) for v in row) for row in np.hstack([pos, abc]))]
    quat = []
    for r in rot:  # (w, x, y, z) of a rotation matrix, Shepperd's method without the branches
        w = math.sqrt(max(0.0, 1.0 + np.trace(r))) / 2.0
        quat.append(
            [w, (r[2, 1] - r[1, 2]) / (4 * w), (r[0, 2] - r[2, 0]) / (4 * w), (r[1, 0] - r[0, 1]) / (4 * w)]
        )
    return ["x,y,z,qw,qx,qy,qz", *(",".join(repr(float(v)) for v in row) for row in np.hstack([pos, quat]))]


@fuzz(250)
@given(
    data=st.one_of(corrupted(_flange_lines(False)), corrupted(_flange_lines(True)), corrupted(DATA_LINES)),
    options=_arguments("tcp"),
)
def test_tcp_on_malformed_input(
    tmp_path: Path, capfd: pytest.CaptureFixture[str], data: bytes, options: list[str]
) -> None:
    """``pincal tcp`` on corrupted flange poses (Euler, quaternions, or joints with ``--robot``)."""
    argv = ["tcp", "data.csv", *options]
    with _fresh_folder(tmp_path) as folder:
        _setup(folder, data)
        _run_checked(capfd, argv)


#: URDF edits: (pattern, replacements) applied to one random match.
URDF_ODD = (
    (r'<axis xyz="[^"]*"/>', ('<axis xyz="0 0 0"/>', '<axis xyz="1 1 1"/>', '<axis xyz="0 0 1e-300"/>', "")),
    (
        r'<origin rpy="[^"]*" xyz="[^"]*"/>',
        ('<origin rpy="0 0 0" xyz="1e300 0 0"/>', '<origin xyz="0 0 0"/>', ""),
    ),
    (r'lower="[^"]*"', ('lower="10"', 'lower="0"', 'lower="-1e300"')),
    (r'upper="[^"]*"', ('upper="-10"', 'upper="0"', 'upper="1e300"')),
    (r'type="revolute"', ('type="prismatic"', 'type="continuous"', 'type="fixed"', 'type="floating"')),
    (r"<limit [^>]*/>", ("",)),
    (r'<mass value="[^"]*"/>', ('<mass value="0"/>', '<mass value="-1"/>')),
    (r'name="[^"]*_joint"', ('name="shoulder_pan_joint"', 'name="x"', 'name="&amp;"', 'name="é"')),
    (r"<robot ", ("<!DOCTYPE robot>\n<robot ",)),
)
"""Edits a URDF parser may accept (pattern, replacements, one random match): degenerate axes,
huge offsets, empty or inverted limits, other joint types, duplicate or odd names."""

URDF_BROKEN = (
    (r'xyz="[^"]*"', ('xyz="nan 0 1"', 'xyz="a b c"', 'xyz="1 2"', 'xyz=""', 'xyz="1e400 0 0"')),
    (r'rpy="[^"]*"', ('rpy="inf 0 0"', 'rpy="x"', 'rpy="1 2 3 4"')),
    (r'lower="[^"]*"', ('lower="nan"', 'lower="-inf"', 'lower=""')),
    (r'type="revolute"', ('type="planar"', 'type="screw"', 'type=""')),
    (r'<parent link="[^"]*"/>', ('<parent link="tool0"/>', '<parent link="nowhere"/>', "")),
    (r'<child link="[^"]*"/>', ('<child link="base_link"/>', '<child link="world"/>', "")),
    (r"<robot ", ("<robot><robot ", "<!-- <robot ")),
)
"""Edits that break the URDF."""


@st.composite
def urdf_texts(draw: st.DrawFn) -> bytes:
    """The UR5's URDF with 1-3 edits (odd ones twice as often as broken ones), sometimes truncated or
    with random bytes."""
    text = URDF_TEXT
    edits = st.one_of(st.sampled_from(URDF_ODD), st.sampled_from(URDF_ODD), st.sampled_from(URDF_BROKEN))
    for _ in range(draw(st.integers(1, 3))):
        pattern, replacements = draw(edits)
        matches = list(re.finditer(pattern, text))
        if matches:
            m = matches[draw(st.integers(0, len(matches) - 1))]
            text = text[: m.start()] + draw(st.sampled_from(replacements)) + text[m.end() :]
    data = text.encode("utf-8")
    if _one_in(8, draw):
        data = data[: draw(st.integers(len(data) // 2, len(data)))]
    if _one_in(8, draw):
        pos = draw(st.integers(0, len(data)))
        data = data[:pos] + draw(st.binary(min_size=1, max_size=3)) + data[pos:]
    return data


@fuzz(150)
@given(urdf=urdf_texts(), options=_arguments("twists"), calibrate=st.integers(0, 2))
def test_twists_and_calibrate_on_malformed_urdf(
    tmp_path: Path, capfd: pytest.CaptureFixture[str], urdf: bytes, options: list[str], calibrate: int
) -> None:
    """``pincal twists`` (and sometimes ``calibrate``) on a damaged URDF: exit 0 or 2."""
    argv = ["twists", "robot.urdf", *options]
    with _fresh_folder(tmp_path) as folder:
        _setup(folder, "\n".join(DATA_LINES).encode())
        (folder / "robot.urdf").write_bytes(urdf)
        _run_checked(capfd, argv)
        if calibrate == 0:
            argv = ["calibrate", "robot.urdf", "data.csv", "--model", "offsets", "--extend", "none"]
            _run_checked(capfd, [*argv, "-o", "out.urdf"])


@fuzz(100)
@given(
    command=st.sampled_from(["calibrate", "tcp", "twists", "diagnose", "nope", ""]),
    tokens=st.lists(junk, max_size=4),
)
def test_random_tokens(
    tmp_path: Path, capfd: pytest.CaptureFixture[str], command: str, tokens: list[str]
) -> None:
    """Junk words after a command name, in an empty folder: exit 2 with one error line (or 0 for
    ``--help``, and for ``twists`` should a word name a bundled robot)."""
    argv = [command, *tokens] if command else tokens
    with _fresh_folder(tmp_path):
        run = _run_checked(capfd, argv)
    helped = run.code == 0 and run.out.startswith("usage:")
    assert run.code == 2 or helped or command == "twists", (argv, run.out)
