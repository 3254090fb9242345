"""Standard input and named pipes as inputs (issue 17): read once, never a hang.

Before, ``-`` and ``/dev/stdin`` were refused as empty (the header was read first, then the
table from a stream already consumed) and a named pipe as DATA hung (opened a second time with
no writer left). Each run here has a timeout; a pipe's writer is a daemon thread, so a regression
fails the test instead of hanging it.
"""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pincal
import pincal.data.dataset
from pincal.cli import main

TIMEOUT = 120  # [s] a child process still running then has hung
FIT = ["--model", "offsets", "--params", "all", "--nested", "no"]


@pytest.fixture(scope="module")
def csv_text(ur5_csv: Path) -> str:
    """30 simulated UR5 poses as CSV text (radians, metres)."""
    return ur5_csv.read_text(encoding="utf-8")


@pytest.fixture(scope="module")
def reference(csv_text: str, tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    """The report of the same calibration read from a regular file."""
    folder = tmp_path_factory.mktemp("ref")
    (folder / "data.csv").write_text(csv_text, encoding="utf-8")
    assert main(["calibrate", "ur5", str(folder / "data.csv"), *FIT, "--report", str(folder / "r.json")]) == 0
    return _numbers(folder / "r.json")


def _numbers(report: Path) -> dict[str, object]:
    """What a report says about the fit (not which file it read)."""
    rep = json.loads(report.read_text(encoding="utf-8"))
    return {"n_poses": rep["n_poses"], "train": rep["train"], "parameters": rep["parameters"]}


def _child(args: list[str], **kwargs: Any) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pincal.cli", *args], capture_output=True, text=True, timeout=TIMEOUT, **kwargs
    )


def _one_line(err: str, *words: str) -> None:
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("pincal: error: "), err
    for word in words:
        assert word in lines[0], (word, lines[0])


@pytest.mark.parametrize("name", ["-", "/dev/stdin"])
def test_data_on_standard_input_through_a_pipe(
    name: str, csv_text: str, reference: dict[str, object], tmp_path: Path
) -> None:
    """``cat data.csv | pincal calibrate ur5 -`` gives the report the file gives."""
    result = _child(["calibrate", "ur5", name, *FIT, "--report", str(tmp_path / "r.json")], input=csv_text)
    assert result.returncode == 0, result.stderr
    assert _numbers(tmp_path / "r.json") == reference


def test_dev_stdin_redirected_from_a_file(
    csv_text: str, reference: dict[str, object], tmp_path: Path
) -> None:
    """``pincal calibrate ur5 /dev/stdin < data.csv``."""
    (tmp_path / "data.csv").write_text(csv_text, encoding="utf-8")
    with open(tmp_path / "data.csv", encoding="utf-8") as stdin:
        result = _child(
            ["calibrate", "ur5", "/dev/stdin", *FIT, "--report", str(tmp_path / "r.json")], stdin=stdin
        )
    assert result.returncode == 0, result.stderr
    assert _numbers(tmp_path / "r.json") == reference


def _feed(fifo: Path, text: str) -> threading.Thread:
    """A daemon thread writing ``text`` into the named pipe once (it blocks until a reader opens)."""

    def write() -> None:
        with open(fifo, "w", encoding="utf-8") as fh:
            fh.write(text)

    thread = threading.Thread(target=write, daemon=True)
    thread.start()
    return thread


def test_data_from_a_named_pipe_is_read_once(
    csv_text: str, reference: dict[str, object], tmp_path: Path
) -> None:
    """The pipe is opened once: the run ends (a second open would wait for a writer forever)."""
    fifo = tmp_path / "data.csv"
    os.mkfifo(fifo)
    writer = _feed(fifo, csv_text)
    result = _child(["calibrate", "ur5", str(fifo), *FIT, "--report", str(tmp_path / "r.json")])
    writer.join(timeout=TIMEOUT)
    assert result.returncode == 0, result.stderr
    assert _numbers(tmp_path / "r.json") == reference


def test_every_command_reads_standard_input_in_process(
    csv_text: str, capfd: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """calibrate, diagnose, tcp (joints with --robot) and compensate take ``-``; each result is
    the one the same text gives from a file."""
    (tmp_path / "data.csv").write_text(csv_text, encoding="utf-8")
    assert main(["calibrate", "ur5", str(tmp_path / "data.csv"), *FIT, "-o", str(tmp_path / "cal.urdf")]) == 0
    runs = {
        "tcp": ["tcp", "--robot", "ur5", "{}", "--accept-implausible", "--json", str(tmp_path / "t{}.json")],
        "compensate": [
            "compensate",
            "ur5",
            str(tmp_path / "cal.urdf"),
            "{}",
            "-o",
            str(tmp_path / "c{}.csv"),
        ],
        "diagnose": [
            "diagnose",
            "ur5",
            "{}",
            "--model",
            "offsets",
            "--folds",
            "3",
            "--json",
            str(tmp_path / "d{}.json"),
        ],
    }
    for command, template in runs.items():
        outs = []
        for source, tag in ((str(tmp_path / "data.csv"), "file"), ("-", "stdin")):
            monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(csv_text.encode("utf-8"))))
            args = [a.replace("{}", source if a == "{}" else tag) for a in template]
            capfd.readouterr()
            code = main(args)
            captured = capfd.readouterr()
            assert code == 0, (command, captured.err)
            outs.append(Path(args[-1]).read_text(encoding="utf-8"))
        if command == "compensate":
            assert outs[0] == outs[1]
        else:
            a, b = (json.loads(t) for t in outs)
            pick = (lambda r: r["tcp"]) if command == "tcp" else (lambda r: r["baseline"]["cv_rms_mm"])
            assert np.allclose(pick(a), pick(b)), command


def test_empty_standard_input_is_one_line(
    capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """An empty pipe, /dev/null as standard input, or none at all."""
    with open(os.devnull, encoding="utf-8") as null:
        for stdin in (io.TextIOWrapper(io.BytesIO(b"")), null, None):
            monkeypatch.setattr(sys, "stdin", stdin)
            capfd.readouterr()
            assert main(["calibrate", "ur5", "-"]) == 2
            _one_line(capfd.readouterr().err, "standard input")


def test_a_terminal_as_standard_input_is_refused_not_waited_on() -> None:
    """``pincal calibrate ur5 -`` typed at a terminal says to pipe the file in."""
    import pty

    leader, follower = pty.openpty()
    try:
        result = _child(["calibrate", "ur5", "-"], stdin=follower)
    finally:
        os.close(leader)
        os.close(follower)
    assert result.returncode == 2
    _one_line(result.stderr, "terminal")


def test_data_and_test_cannot_both_be_standard_input(capfd: pytest.CaptureFixture[str]) -> None:
    code = main(["calibrate", "ur5", "-", "--test", "-"])
    assert code == 2
    _one_line(capfd.readouterr().err, "--test", "'-'")


def test_a_device_that_never_ends_is_refused(
    capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """/dev/zero as DATA: read up to the size bound, then one line (not a hang, not all memory)."""
    monkeypatch.setattr(pincal.files, "MAX_INPUT_BYTES", 1_000_000)
    code = main(["calibrate", "ur5", "/dev/zero"])
    assert code == 2
    _one_line(capfd.readouterr().err, "/dev/zero", "larger")


def test_a_regular_file_is_read_whole_once(
    monkeypatch: pytest.MonkeyPatch, csv_text: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`calibrate` reads a data file whole once: its header (asked for by the chain, the reader
    and the past-tip check) is read only up to the header line, and gives the same columns."""
    data = tmp_path / "data.csv"
    data.write_text("# measured 2026-11-23\n\n" + csv_text, encoding="utf-8")
    whole: list[str] = []
    real = pincal.files.read_input_text

    def counted(path: str | Path, what: str = "data file") -> str:
        whole.append(str(path))
        return real(path, what)

    monkeypatch.setattr(pincal.files, "read_input_text", counted)
    assert main(["calibrate", "ur5", str(data), *FIT]) == 0, capsys.readouterr().err
    assert whole.count(str(data)) == 1
    assert pincal.data.dataset.csv_columns(data) == csv_text.splitlines()[0].split(",")
    assert whole.count(str(data)) == 1
    for text in ("", "# only a comment\n\n"):  # no header line: the empty file's one message
        data.write_text(text, encoding="utf-8")
        with pytest.raises(pincal.DataError, match="is empty"):
            pincal.data.dataset.csv_columns(data)
