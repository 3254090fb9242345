"""Issue 33, second reliability pass: one test (or a few) per class of the battery.

Each case ends in a correct result, or exit 2 with one ``pincal: error:`` line; no input file
changes and no temporary file remains. The cases are built here from simulated data; the
held-out battery itself is not in the project.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from cli_run import one_error_line, run

import pincal
import pincal.data.checks
import pincal.data.csv_table
import pincal.data.dataset
import pincal.inputs
from pincal.json_text import json_text
from pincal.robot.robots import bundled_urdf
from pincal.units import joints_from_file, joints_to_file

FAST = ("--params", "all", "--extend", "none", "--nested", "no")
XACRO_DATA = Path(__file__).resolve().parent / "data" / "xacro"


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """UR5 position data (metres), its calibration, and a joint program."""
    folder = tmp_path_factory.mktemp("reliability")
    ur5 = pincal.load_robot("ur5")
    q = ur5.random_configurations(30, np.random.default_rng(5), 0.05)
    data = pincal.random_truth(ur5, seed=1).measure(q, 3e-5, seed=2)
    pincal.write_csv(folder / "pos.csv", data)
    pincal.write_corrected_urdf(pincal.calibrate(ur5, data, params="all"), folder / "cal.urdf")
    (folder / "prog.csv").write_text(
        ",".join(ur5.joint_names) + "\n" + "\n".join(",".join(map(repr, row)) for row in q[:3]) + "\n"
    )
    return {"pos": folder / "pos.csv", "urdf": folder / "cal.urdf", "prog": folder / "prog.csv"}


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()}


# --- Inputs destroyed: one guard over every input of the run -------------------------------


def test_an_output_that_is_the_params_list_is_refused_with_force(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    names = tmp_path / "names.txt"
    names.write_text("shoulder_pan_joint.tx\n")
    before = _snapshot(tmp_path)
    line = one_error_line(
        capsys,
        "calibrate",
        "ur5",
        files["pos"],
        *FAST[2:],
        "--params",
        f"@{names}",
        "--report",
        names,
        "--force",
    )
    assert "parameter list" in line
    assert _snapshot(tmp_path) == before


def test_an_output_that_is_a_file_the_xacro_includes_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The included macro as --report, through a symlink: refused, the macro unchanged."""
    parts = tmp_path / "pincal_test_parts"
    shutil.copytree(XACRO_DATA / "pincal_test_parts", parts)
    macro = parts / "urdf" / "joint.xacro"
    robot = pincal.load_robot(XACRO_DATA / "arm.urdf.xacro", package_paths={"pincal_test_parts": parts})
    q = robot.random_configurations(30, np.random.default_rng(1), 0.05)
    pincal.write_csv(tmp_path / "d.csv", pincal.random_truth(robot, seed=1).measure(q, 1e-5, seed=2))
    (tmp_path / "link.json").symlink_to(macro)
    before = macro.read_bytes()
    line = one_error_line(
        capsys,
        "calibrate",
        XACRO_DATA / "arm.urdf.xacro",
        tmp_path / "d.csv",
        *FAST,
        "--package-path",
        f"pincal_test_parts={parts}",
        "--report",
        tmp_path / "link.json",
        "--force",
    )
    assert "xacro includes" in line
    assert macro.read_bytes() == before


def test_compensate_refuses_writing_over_its_sidecar(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    side = files["urdf"].with_suffix(".calibration.json")
    before = side.read_bytes()
    one_error_line(capsys, "compensate", "ur5", files["urdf"], files["prog"], "-o", side, "--force")
    assert side.read_bytes() == before


# --- Writes: no temporary file, the longest names ---------------------------------------------


def test_the_longest_output_name_is_written_and_no_temporary_file_remains(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    report = tmp_path / ("r" * 250 + ".json")  # 255 characters: the file system's longest
    code, _, err = run(capsys, "calibrate", "ur5", files["pos"], *FAST, "--report", report)
    assert code == 0, err
    assert json.loads(report.read_text())["n_poses"] == 30
    assert [p.name for p in tmp_path.iterdir()] == [report.name]


def test_a_write_that_fails_leaves_no_temporary_file(
    files: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    def full(*_: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", full)
    line = one_error_line(
        capsys,
        "calibrate",
        "ur5",
        files["pos"],
        *FAST,
        "--report",
        tmp_path / "r.json",
        "-o",
        tmp_path / "c.urdf",
    )
    assert "free some space" in line
    assert list(tmp_path.iterdir()) == []


def test_sigterm_during_a_run_leaves_no_file(tmp_path: Path) -> None:
    """Killed while it works (SIGTERM): exit 143, one line, no output and no temporary file."""
    ur5 = pincal.load_robot("ur5")
    q = ur5.random_configurations(15_000, np.random.default_rng(5), 0.05)
    pincal.write_csv(tmp_path / "d.csv", pincal.random_truth(ur5, seed=1).measure(q, 3e-5, seed=2))
    report = tmp_path / "out" / "r.json"
    report.parent.mkdir()
    child = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "pincal",
            "calibrate",
            "ur5",
            str(tmp_path / "d.csv"),
            "--report",
            str(report),
        ],
        stderr=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        text=True,
    )
    time.sleep(2.5)  # imported, fitting (the automatic choice on 15,000 poses takes longer)
    child.terminate()
    _, err = child.communicate(timeout=60)
    if child.returncode == 0:
        pytest.skip("the run ended before the signal")
    assert child.returncode == 143 and err.strip().startswith("pincal: error: terminated"), err
    assert list(report.parent.iterdir()) == []


# --- Output channels --------------------------------------------------------------------------


def _cli(args: list[str], **kwargs: object) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "pincal", *args], text=True, timeout=300, **kwargs)  # type: ignore[call-overload, no-any-return]


def test_closed_or_full_standard_streams(files: dict[str, Path], tmp_path: Path) -> None:
    """A stdout closed before the run: refused in one line, exit 2, nothing written (it used to end
    quietly, the tables lost); a closed stderr: the run succeeds; stdout on a full disk: one line,
    exit 2; never a traceback."""
    args = ["calibrate", "ur5", str(files["pos"]), *FAST, "--report", str(tmp_path / "r.json")]
    closed = _cli(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, preexec_fn=lambda: os.close(1))
    assert closed.returncode == 2, closed.stderr
    assert closed.stderr.count("\n") == 1 and closed.stderr.startswith(
        "pincal: error: standard output is closed"
    )
    assert not (tmp_path / "r.json").exists()
    quiet = _cli(
        [*args, "--force"], capture_output=False, stdout=subprocess.DEVNULL, preexec_fn=lambda: os.close(2)
    )
    assert quiet.returncode == 0
    with open("/dev/full", "w") as full:
        result = _cli([*args, "--force"], stdout=full, stderr=subprocess.PIPE)
    assert result.returncode == 2, result.stderr
    assert result.stderr.count("\n") == 1 and "No space left" in result.stderr


def test_a_bug_is_one_line_that_says_so(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import pincal.cli.calibrate

    def broken(_: object) -> int:
        raise RuntimeError("something internal")

    monkeypatch.setattr(pincal.cli.calibrate, "run", broken)
    code, _, err = run(capsys, "calibrate", "ur5", files["pos"])
    assert code == 1
    assert err.count("\n") == 1 and err.startswith("pincal: bug: RuntimeError: something internal"), err


def test_json_is_never_infinity() -> None:
    """Non-finite numbers become null, NumPy values plain ones: a strict parser reads the text."""
    text = json_text({"a": float("inf"), "b": [np.float64("nan"), np.float32(1.5)], "c": np.arange(2)})

    def refuse(name: str) -> None:
        raise ValueError(name)

    assert json.loads(text, parse_constant=refuse) == {"a": None, "b": [None, 1.5], "c": [0, 1]}


# --- Bounded readers ----------------------------------------------------------------------------


@pytest.mark.parametrize("what", ["sidecar", "kinematics", "socket", "urdf"])
def test_a_link_to_an_endless_device_is_refused_before_reading(
    what: str, files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    zero = tmp_path / "zero"
    zero.symlink_to("/dev/zero")
    if what == "sidecar":
        shutil.copy(files["urdf"], tmp_path / "c.urdf")
        (tmp_path / "c.calibration.json").symlink_to("/dev/zero")
        args: list[str | Path] = [
            "compensate",
            "ur5",
            tmp_path / "c.urdf",
            files["prog"],
            "-o",
            tmp_path / "o.csv",
        ]
    elif what == "kinematics":
        args = ["calibrate", "ur5", files["pos"], "--kinematics", zero, "-o", tmp_path / "c.yaml"]
    elif what == "socket":
        (tmp_path / "sockets").mkdir()
        (tmp_path / "sockets" / "hole_1.csv").symlink_to("/dev/zero")
        args = ["calibrate", "ur5", tmp_path / "sockets"]
    else:
        (tmp_path / "r.urdf").symlink_to("/dev/zero")
        args = ["calibrate", tmp_path / "r.urdf", files["pos"], "--tip", "tool0"]
    started = time.monotonic()
    line = one_error_line(capsys, *args)
    assert "not a regular file" in line and time.monotonic() - started < 30


def test_a_pipe_nobody_writes_to_is_refused_not_waited_on(
    files: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(pincal.inputs, "PIPE_WAIT_SECONDS", 0.5)
    os.mkfifo(tmp_path / "points.csv")
    line = one_error_line(capsys, "calibrate", "ur5", tmp_path / "points.csv", "--measure", "points")
    assert "named pipe nobody wrote to" in line
    os.mkfifo(tmp_path / "holes")
    os.mkdir(tmp_path / "sockets")
    (tmp_path / "sockets" / "hole_1.csv").symlink_to(tmp_path / "holes")
    assert "named pipe" in one_error_line(capsys, "calibrate", "ur5", tmp_path / "sockets")


def test_a_header_of_150000_columns_is_refused_at_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    names = [f"c{k}" for k in range(150_000)]
    (tmp_path / "wide.csv").write_text(",".join(names) + "\n" + ",".join("1" for _ in names) + "\n")
    started = time.monotonic()
    line = one_error_line(capsys, "calibrate", "ur5", tmp_path / "wide.csv")
    assert "150,000 columns" in line and time.monotonic() - started < 10


def test_an_empty_socket_file_is_one_line_and_no_warning(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "s").mkdir()
    (tmp_path / "s" / "hole_1.csv").write_text("")
    with _no_warnings():
        line = one_error_line(capsys, "calibrate", "ur5", tmp_path / "s")
    assert "has no rows" in line


class _no_warnings:  # noqa: N801 (a context manager used as a phrase)
    def __enter__(self) -> None:
        import warnings

        self._catch = warnings.catch_warnings(record=True)
        self._seen = self._catch.__enter__()
        warnings.simplefilter("always")

    def __exit__(self, *exc: object) -> None:
        self._catch.__exit__(*exc)
        assert not self._seen, [str(w.message) for w in self._seen]


def test_the_streamed_reader_reads_what_the_text_says(tmp_path: Path) -> None:
    """Comments, blank lines, CRLF, quoted cells and an unused text column: the values as written
    (checked against Python's own float of each cell); a non-finite cell named as written."""
    rng = np.random.default_rng(0)
    values = rng.normal(size=(200, 3))
    lines = ["# a comment", "a,name,b,c"]
    for k, (a, b, c) in enumerate(values):
        name = f'"pose, {k}"' if k % 7 == 0 else f"p{k}"
        lines += [f"{float(a)!r},{name},{float(b)!r},{float(c)!r}", "" if k % 13 == 0 else "# note"]
    (tmp_path / "t.csv").write_bytes("\r\n".join(lines).encode())
    got = pincal.data.dataset.read_table(tmp_path / "t.csv", ["a", "b", "c"], "a,b,c")
    assert np.array_equal(got, values)
    (tmp_path / "bad.csv").write_text("a,b\n1,2\n3,1e999\n")
    with pytest.raises(pincal.errors.DataError, match="row 2, column b: 1e999 is not a finite"):
        pincal.data.dataset.read_table(tmp_path / "bad.csv", ["a", "b"], "a,b")


@pytest.mark.parametrize("workers", ["1", "2"])
def test_blocks_read_side_by_side_are_the_blocks_read_in_turn(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, workers: str
) -> None:
    """A file of several blocks gives the same numbers read in one process or two, and a bad cell
    in a later block (read by the careful reader) is named by its own row."""
    monkeypatch.setattr(pincal.data.csv_table, "_BLOCK_LINES", 64)
    monkeypatch.setenv("PINCAL_WORKERS", workers)
    values = np.random.default_rng(1).normal(size=(300, 3))
    lines = ["a,b,c", *(",".join(repr(float(v)) for v in row) for row in values)]
    (tmp_path / "t.csv").write_text("\n".join(lines) + "\n")
    got = pincal.data.dataset.read_table(tmp_path / "t.csv", ["a", "b", "c"], "a,b,c")
    assert np.array_equal(got, values)
    lines[250] = "1,nan,2"
    (tmp_path / "bad.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(pincal.errors.DataError, match="row 250, column b: nan is not a finite"):
        pincal.data.dataset.read_table(tmp_path / "bad.csv", ["a", "b", "c"], "a,b,c")


def test_json_writes_a_list_of_numbers_on_one_line() -> None:
    """Each list of numbers is one line (a report's million rows are not a million lines), nested
    lists and objects stay indented, and the text reads back as the object."""
    obj = {
        "rows": list(range(1, 1001)),
        "m": [[1.5, 2.0], [3.0, None]],
        "s": ["a", "b"],
        "e": [],
        "x": {"v": (1, 2)},
    }
    text = json_text(obj)
    assert json.loads(text) == {**obj, "x": {"v": [1, 2]}}
    assert '"rows": [1, 2, 3,' in text and "    [1.5, 2.0]," in text and '"v": [1, 2]' in text
    assert len(text.splitlines()) == 15, text


def test_flags_are_written_as_the_whole_text_would_have_them() -> None:
    """Searching only the lines with an ``=`` gives what one search of the whole text gives."""
    from pincal.cli.flags import _NAMED, _flag, as_flags

    rng = np.random.default_rng(0)
    words = [
        "folds=",
        "degrees=True",
        "measure=points",
        "nested=",
        "x.folds=",
        "a",
        "=",
        " ",
        "\n",
        ",",
        "\r\n",
    ]
    for _ in range(200):
        text = "".join(rng.choice(words, size=12))
        assert as_flags(text) == _NAMED.sub(_flag, text), repr(text)


# --- Units and plausibility -----------------------------------------------------------------------


def test_joint_values_round_trip_through_the_unit_layer() -> None:
    """What a command writes in mm / degrees reads back as the same radians and metres."""
    rng = np.random.default_rng(3)
    q = rng.normal(size=(20, 4))
    prismatic = (False, True, False, True)
    for degrees in (False, True):
        for units in ("m", "mm"):
            written = joints_to_file(q, degrees, units, prismatic)
            assert np.allclose(joints_from_file(written, degrees, units, prismatic), q, rtol=0, atol=1e-12)
    mm = joints_to_file(q, True, "mm", prismatic)
    assert np.allclose(mm[:, 1], q[:, 1] * 1e3) and np.allclose(mm[:, 0], np.rad2deg(q[:, 0]))


def test_compensate_writes_prismatic_joints_in_the_program_units(tmp_path: Path) -> None:
    from pincal.export.compensate import Compensation, write_program

    q = np.array([[0.1, 0.25], [0.2, 0.5]])
    result = Compensation(
        ("j1", "slide"),
        "position",
        q,
        q,
        ("ok", "ok"),
        np.zeros(2),
        np.zeros(2),
        np.zeros(2, dtype=int),
        ("", ""),
    )
    write_program(tmp_path / "p.csv", result, degrees=True, prismatic=(False, True), units="mm")
    rows = np.loadtxt(tmp_path / "p.csv", delimiter=",", skiprows=1, usecols=(0, 1))
    assert np.allclose(rows[:, 1], [250.0, 500.0]) and np.allclose(rows[:, 0], np.rad2deg([0.1, 0.2]))


def test_tcp_in_millimetres_read_as_metres_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import pinocchio as pin

    rng = np.random.default_rng(0)
    point, tcp = np.array([500.0, 100.0, 200.0]), np.array([10.0, 20.0, 150.0])
    rows = []
    for _ in range(12):
        rot = pin.exp3(rng.normal(0, 0.5, 3))
        quat = pin.Quaternion(rot)
        rows.append([*(point - rot @ tcp), quat.w, quat.x, quat.y, quat.z])
    poses = tmp_path / "tcp.csv"
    poses.write_text(
        "x,y,z,qw,qx,qy,qz\n" + "\n".join(",".join(repr(float(v)) for v in r) for r in rows) + "\n"
    )
    assert "--units mm" in one_error_line(capsys, "tcp", poses)
    code, out, err = run(capsys, "tcp", poses, "--units", "mm", "--json", tmp_path / "t.json")
    assert code == 0, err
    assert np.allclose(json.loads((tmp_path / "t.json").read_text())["tcp"], tcp, atol=1e-6)
    assert "--inertias" in one_error_line(capsys, "tcp", poses, "--units", "mm", "--inertias", "ur5")


def test_a_points_test_file_on_position_data_is_refused(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rows = files["pos"].read_text().splitlines()
    header = rows[0].split(",")[:6] + ["point"]
    body = [",".join(r.split(",")[:6] + [str(k % 3)]) for k, r in enumerate(rows[1:])]
    (tmp_path / "pts.csv").write_text("\n".join([",".join(header), *body]) + "\n")
    line = one_error_line(capsys, "calibrate", "ur5", files["pos"], *FAST, "--test", tmp_path / "pts.csv")
    assert "same kind" in line


@pytest.mark.parametrize(
    "extension",
    [
        "joint_compliance",
        [1, 2],
        {"effect": "joint_compliance", "joint": "elbow_joint"},
        {
            "effect": "joint_compliance",
            "joint": "elbow_joint",
            "harmonic": 1,
            "payload": {"mass_kg": 1.0, "com_m": [0.1]},
            "parameters": {},
        },
        {
            "effect": "joint_compliance",
            "joint": "elbow_joint",
            "harmonic": 1,
            "payload": {"mass_kg": -2.0, "com_m": [0, 0, 0.1]},
            "parameters": {"elbow_joint.compliance": {"value": 1e-4, "unit": "rad/(N·m)"}},
        },
    ],
    ids=["a_string", "a_list_of_numbers", "no_parameters", "short_com", "negative_mass"],
)
def test_a_malformed_sidecar_extension_is_one_line(
    extension: object, files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    shutil.copy(files["urdf"], tmp_path / "c.urdf")
    side = json.loads(files["urdf"].with_suffix(".calibration.json").read_text())
    side["extension"] = extension
    (tmp_path / "c.calibration.json").write_text(json.dumps(side))
    one_error_line(capsys, "compensate", "ur5", tmp_path / "c.urdf", files["prog"], "-o", tmp_path / "o.csv")
    assert not (tmp_path / "o.csv").exists()


# --- False refusals -------------------------------------------------------------------------------


def _fixed_link(name: str, parent: str) -> str:
    joint = f'<joint name="{name}_joint" type="fixed"><parent link="{parent}"/><child link="{name}"/></joint>'
    return f'<link name="{name}"/>{joint}'


def _ur5_text() -> str:
    return bundled_urdf("ur5").read_text()


def test_a_default_namespace_urdf_is_calibrated_and_written(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The corrected URDF of a URDF in a default XML namespace is the plain one's."""
    text = _ur5_text()
    (tmp_path / "plain.urdf").write_text(text)
    (tmp_path / "ns.urdf").write_text(text.replace("<robot ", '<robot xmlns="http://www.ros.org" ', 1))
    for name in ("plain", "ns"):
        code, _, err = run(
            capsys,
            "calibrate",
            tmp_path / f"{name}.urdf",
            files["pos"],
            "--tip",
            "tool0",
            *FAST,
            "-o",
            tmp_path / f"{name}_cal.urdf",
        )
        assert code == 0, err
    plain = pincal.load_robot(tmp_path / "plain_cal.urdf", tip="tool0")
    spaced = pincal.load_robot(tmp_path / "ns_cal.urdf", tip="tool0")
    for a, b in zip(plain.placements, spaced.placements):
        assert np.allclose(a.homogeneous, b.homogeneous, atol=1e-12)


def test_doctype_words_elsewhere_are_not_declarations(tmp_path: Path) -> None:
    """A link named PUBLIC-display and SYSTEM in a comment load; a DOCTYPE with an external DTD or
    an internal subset is still refused."""
    text = _ur5_text()
    extra = _fixed_link("PUBLIC-display", "tool0")
    body = text.replace("<robot ", "<!DOCTYPE robot>\n<!-- SYSTEM, PUBLIC -->\n<robot ", 1)
    body = body.replace("</robot>", extra + "</robot>")
    (tmp_path / "ok.urdf").write_text(body)
    assert pincal.load_robot(tmp_path / "ok.urdf", tip="tool0").n_joints == 6
    for doctype in ('<!DOCTYPE robot SYSTEM "x.dtd">', '<!DOCTYPE robot [<!ENTITY a "b">]>'):
        (tmp_path / "bad.urdf").write_text(body.replace("<!DOCTYPE robot>", doctype))
        with pytest.raises(pincal.errors.RobotError, match="DOCTYPE"):
            pincal.load_robot(tmp_path / "bad.urdf", tip="tool0")


def test_a_thousand_fixed_links_do_not_count_as_joints(tmp_path: Path) -> None:
    text = _ur5_text()
    extra = "".join(_fixed_link(f"m{k}", "base_link") for k in range(1000))
    (tmp_path / "many.urdf").write_text(text.replace("</robot>", extra + "</robot>"))
    many, ur5 = pincal.load_robot(tmp_path / "many.urdf", tip="tool0"), pincal.load_robot("ur5")
    assert many.joint_names == ur5.joint_names
    for a, b in zip(many.placements, ur5.placements):
        assert np.allclose(a.homogeneous, b.homogeneous)


# --- Scale: block by block gives the dense answer ----------------------------------------------------


def test_the_block_by_block_fit_is_the_dense_fit(monkeypatch: pytest.MonkeyPatch) -> None:
    """With the thresholds of :mod:`pincal.identify.chunked` lowered to a few hundred poses, the fit, its
    standard deviations and its errors are those of the dense solver (to rounding; the standard
    deviations to 1e-5, as a large problem reads them at the default pull's fit, which 400 poses
    move from the chosen pull's by 4e-6 relative, a million by 2e-8); found on a random subset, the
    identifiable set is the same and the fit's error within 1 %."""
    import pincal.identify.chunked as chunked

    ur5 = pincal.load_robot("ur5")
    q = ur5.random_configurations(400, np.random.default_rng(2), 0.05)
    data = pincal.random_truth(ur5, seed=4).measure(q, 2e-5, seed=5)
    dense = pincal.calibrate(ur5, data, params="all", outliers=6.0)
    monkeypatch.setattr(chunked, "LARGE_POSES", 150)
    monkeypatch.setattr(chunked, "BLOCK_POSES", 70)
    blocks = pincal.calibrate(ur5, data, params="all", outliers=6.0)
    assert np.array_equal(dense.identifiability.identifiable, blocks.identifiability.identifiable)
    assert np.allclose(blocks.theta, dense.theta, rtol=0, atol=1e-9)
    assert np.allclose(blocks.std, dense.std, rtol=1e-5, atol=1e-12)
    assert blocks.train_after.rms_mm == pytest.approx(dense.train_after.rms_mm, rel=1e-9)
    monkeypatch.setattr(chunked, "SAMPLE_POSES", 200)
    sampled = pincal.calibrate(ur5, data, params="all", outliers=6.0)
    assert np.array_equal(dense.identifiability.identifiable, sampled.identifiability.identifiable)
    assert sampled.train_after.rms_mm == pytest.approx(dense.train_after.rms_mm, rel=0.01)


def test_the_degrees_hint_needs_the_points_to_follow_the_tip() -> None:
    """The unit check's hint: points that are the tip seen by an instrument (any rigid motion) and
    a tool offset follow it; points of another robot, spread alike, do not."""
    import pinocchio as pin

    from pincal.data.checks import follows

    ur5, panda = pincal.load_robot("ur5"), pincal.load_robot("panda")
    q = ur5.random_configurations(200, np.random.default_rng(0), 0.05)
    frames = [ur5.frame_placement(row) for row in q]
    tips = np.array([f.translation for f in frames])
    seen = pin.SE3(pin.exp3(np.array([0.3, -1.0, 2.0])), np.array([1.0, 2.0, 0.5]))
    points = np.array([seen.act(f.act(np.array([0.0, 0.03, 0.1]))) for f in frames])
    assert follows(tips, points)
    other = panda.random_configurations(200, np.random.default_rng(1), 0.05)
    other_tips = np.array([panda.frame_placement(row).translation for row in other])
    assert not follows(
        tips, other_tips * (pincal.data.checks.spread(tips) / pincal.data.checks.spread(other_tips))
    )


def test_a_program_using_the_library_may_rewrite_what_it_read(files: dict[str, Path], tmp_path: Path) -> None:
    """The guard is the command line's, for the files of one run: the library reads a CSV and
    writes it back in millimetres (and a command run before leaves nothing behind)."""
    copy = tmp_path / "pos.csv"
    shutil.copy(files["pos"], copy)
    data = pincal.read_csv(copy, pincal.load_robot("ur5").joint_names)
    pincal.write_csv(copy, data, units="mm")
    again = pincal.read_csv(copy, data.joint_names, units="mm")
    assert np.allclose(again.points, data.points, rtol=0, atol=1e-15)
