"""Outputs (issue 17): regular files only, written whole or not at all, with the usual permissions.

Before, ``--force`` replaced a character device or a named pipe given as an output by a regular
file (as root, ``--report /dev/null --force`` replaced /dev/null), replaced a symlink instead of
writing through it, wrote reports with mode 0600, and a full disk, a read-only folder or Ctrl-C
during a fit ended in a traceback. Each case must end with exit code 0 and the right file, or
exit code 2 (130 for Ctrl-C) with one ``pincal: error:`` line, the old files unchanged and no
temporary file left behind.
"""

from __future__ import annotations

import errno
import json
import os
import signal
import stat
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

import pincal
import pincal.auto.fitting
import pincal.data.dataset
import pincal.export.urdf_writer
import pincal.files
from pincal.cli import main


@pytest.fixture(scope="module")
def data(ur5_csv: Path) -> Path:
    """30 simulated UR5 poses (radians, metres)."""
    return ur5_csv


def _run(capfd: pytest.CaptureFixture[str], *args: object) -> tuple[int, str, str]:
    capfd.readouterr()
    code = main([str(a) for a in args])
    captured = capfd.readouterr()
    assert "Traceback" not in captured.out + captured.err
    return code, captured.out, captured.err


def _one_line(err: str, *words: str) -> str:
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("pincal: error: "), err
    for word in words:
        assert word in lines[0], (word, lines[0])
    return lines[0]


def _calibrate(data: Path, *more: object) -> list[object]:
    return ["calibrate", "ur5", data, "--model", "offsets", "--params", "all", "--nested", "no", *more]


def _leftovers(folder: Path) -> list[str]:
    return [p.name for p in folder.iterdir() if p.name.endswith(".tmp")]


def _special(tmp_path: Path, kind: str) -> Path:
    """A named pipe, a folder, or a character device (a /dev/null twin when root may make one)."""
    path = tmp_path / f"special_{kind}"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "folder":
        path.mkdir()
    elif os.geteuid() == 0:
        os.mknod(path, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    else:
        return Path(os.devnull)  # not root: /dev/null cannot be replaced anyway
    return path


@pytest.mark.parametrize("kind", ["fifo", "folder", "chardev"])
def test_special_files_and_folders_are_refused_even_with_force(
    kind: str, capfd: pytest.CaptureFixture[str], data: Path, tmp_path: Path
) -> None:
    """Every command's output option refuses them, ``--force`` or not, and they stay what they were."""
    target = _special(tmp_path, kind)
    mode = target.stat().st_mode
    commands = [
        _calibrate(data, "--report", target),
        _calibrate(data, "-o", target),
        ["diagnose", "ur5", data, "--json", target],
        ["tcp", data, "--json", target],
        ["plan", "ur5", "--poses", "10", "-o", target],
        ["compensate", "ur5", tmp_path / "cal.urdf", data, "-o", target],
    ]
    for args in commands:
        for force in ([], ["--force"]):
            code, _, err = _run(capfd, *args, *force)
            assert code == 2, (args, err)
            _one_line(err, target.name)
            assert stat.S_IFMT(target.stat().st_mode) == stat.S_IFMT(mode)
    assert not _leftovers(tmp_path)


def test_dash_is_not_an_output(
    capfd: pytest.CaptureFixture[str], data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    code, _, err = _run(capfd, *_calibrate(data, "--report", "-"))
    assert code == 2
    _one_line(err, "'-'")
    assert not (tmp_path / "-").exists()


def test_a_symlink_is_written_through(capfd: pytest.CaptureFixture[str], data: Path, tmp_path: Path) -> None:
    """The link stays a link; its target gets the output (``--force`` when the target exists)."""
    real, link = tmp_path / "real.json", tmp_path / "link.json"
    real.write_text("old\n", encoding="utf-8")
    link.symlink_to(real.name)
    code, _, err = _run(capfd, *_calibrate(data, "--report", link))
    _one_line(err, "--force")
    code, _, err = _run(capfd, *_calibrate(data, "--report", link, "--force"))
    assert code == 0, err
    assert link.is_symlink() and os.readlink(link) == real.name
    assert json.loads(real.read_text(encoding="utf-8"))["n_poses"] == 30
    # A link to a file not yet there creates it; one into a missing folder is refused.
    fresh = tmp_path / "fresh.json"
    (tmp_path / "new.json").symlink_to(fresh.name)
    assert _run(capfd, *_calibrate(data, "--report", tmp_path / "new.json"))[0] == 0
    assert json.loads(fresh.read_text(encoding="utf-8"))["n_poses"] == 30
    (tmp_path / "dangling.json").symlink_to(tmp_path / "missing" / "r.json")
    code, _, err = _run(capfd, *_calibrate(data, "--report", tmp_path / "dangling.json"))
    assert code == 2
    _one_line(err, "missing", "does not exist")


@pytest.mark.parametrize("mask", [0o022, 0o077, 0o002])
def test_new_outputs_follow_the_umask_replaced_ones_keep_their_mode(
    mask: int, capfd: pytest.CaptureFixture[str], data: Path, tmp_path: Path
) -> None:
    old = os.umask(mask)
    try:
        kept = tmp_path / "kept.json"
        kept.write_text("old\n", encoding="utf-8")
        kept.chmod(0o640)
        args = _calibrate(data, "--report", tmp_path / "new.json", "-o", tmp_path / "new.urdf")
        assert _run(capfd, *args)[0] == 0
        assert _run(capfd, *_calibrate(data, "--report", kept, "--force"))[0] == 0
    finally:
        os.umask(old)
    for name in ("new.json", "new.urdf", "new.calibration.json"):
        assert stat.S_IMODE((tmp_path / name).stat().st_mode) == 0o666 & ~mask, name
    assert stat.S_IMODE(kept.stat().st_mode) == 0o640
    assert json.loads(kept.read_text(encoding="utf-8"))["n_poses"] == 30


def _old_outputs(tmp_path: Path) -> tuple[Path, Path, dict[str, bytes]]:
    report, urdf = tmp_path / "r.json", tmp_path / "out.urdf"
    report.write_text('{"old": true}\n', encoding="utf-8")
    return report, urdf, {p.name: p.read_bytes() for p in tmp_path.iterdir()}


def _unchanged(tmp_path: Path, before: dict[str, bytes]) -> None:
    """Every file as it was: no new one (no URDF, no sidecar, no temporary file), none changed."""
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def test_a_full_disk_leaves_no_partial_file(
    capfd: pytest.CaptureFixture[str], data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The disk fills up halfway through the second file: one line, and no output at all (the
    report, the URDF and its sidecar are written all or none)."""
    report, urdf, before = _old_outputs(tmp_path)
    written: list[int] = []
    real_write = pincal.files._write_all

    def filling(fd: int, payload: bytes) -> None:
        if written:
            os.write(fd, payload[: len(payload) // 2])
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        written.append(len(payload))
        real_write(fd, payload)

    monkeypatch.setattr(pincal.files, "_write_all", filling)
    code, _, err = _run(capfd, *_calibrate(data, "-o", urdf, "--report", report, "--force"))
    assert code == 2
    _one_line(err, "No space left", "free some space")
    _unchanged(tmp_path, before)
    # A single output (plan's poses) too.
    code, _, err = _run(capfd, "plan", "ur5", "--poses", "10", "--candidates", "100", "-o", report, "--force")
    assert code == 2
    _one_line(err, "No space left")
    _unchanged(tmp_path, before)


def test_a_read_only_folder(capfd: pytest.CaptureFixture[str], data: Path, tmp_path: Path) -> None:
    """Refused with one line before the fit; root, whom permissions do not stop, writes the file."""
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        code, _, err = _run(capfd, *_calibrate(data, "--report", folder / "r.json"))
    finally:
        folder.chmod(0o755)
    if os.geteuid() == 0:
        assert code == 0, err
        assert json.loads((folder / "r.json").read_text(encoding="utf-8"))["n_poses"] == 30
    else:
        assert code == 2
        _one_line(err, "not writable")
        assert list(folder.iterdir()) == []


def test_a_folder_that_refuses_the_file_at_write_time(
    capfd: pytest.CaptureFixture[str], data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Permission lost between the check and the write (or a read-only file system): one line."""
    report, urdf, before = _old_outputs(tmp_path)

    def refused(*args: object, **kwargs: object) -> tuple[int, str]:
        raise PermissionError(errno.EACCES, os.strerror(errno.EACCES))

    monkeypatch.setattr(tempfile, "mkstemp", refused)
    code, _, err = _run(capfd, *_calibrate(data, "-o", urdf, "--report", report, "--force"))
    assert code == 2
    _one_line(err, "Permission denied", "folder you can write")
    _unchanged(tmp_path, before)


def test_ctrl_c_inside_a_fit(
    capfd: pytest.CaptureFixture[str], data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    report, urdf, before = _old_outputs(tmp_path)

    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(pincal.auto.fitting, "solve", interrupted)
    code, _, err = _run(capfd, *_calibrate(data, "-o", urdf, "--report", report, "--force"))
    assert code == 130
    _one_line(err, "interrupted")
    _unchanged(tmp_path, before)


def test_ctrl_c_while_writing(
    capfd: pytest.CaptureFixture[str], data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Interrupted while the second of three files is written: none of them is replaced."""
    report, urdf, before = _old_outputs(tmp_path)
    calls: list[int] = []
    real_write = pincal.files._write_all

    def interrupted(fd: int, payload: bytes) -> None:
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        real_write(fd, payload)

    monkeypatch.setattr(pincal.files, "_write_all", interrupted)
    code, _, err = _run(capfd, *_calibrate(data, "-o", urdf, "--report", report, "--force"))
    assert code == 130
    _one_line(err, "interrupted")
    _unchanged(tmp_path, before)


def test_a_real_ctrl_c_between_the_renames_leaves_new_files_together(
    capfd: pytest.CaptureFixture[str], data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """SIGINT arrives after the first of three renames: it is held until the last one is done, so
    the URDF, its sidecar and the report are all new (never a new URDF beside an old sidecar),
    and the command then ends as interrupted (130), with no temporary file left."""
    report, urdf, _ = _old_outputs(tmp_path)
    renames: list[str] = []
    real_replace = os.replace

    def replace(src: str, dst: str | Path) -> None:
        real_replace(src, dst)
        renames.append(str(dst))
        if len(renames) == 1:
            os.kill(os.getpid(), signal.SIGINT)

    monkeypatch.setattr(pincal.files.os, "replace", replace)
    # Ctrl-C as a terminal delivers it (a shell starts background jobs with SIGINT ignored)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        code, _, err = _run(capfd, *_calibrate(data, "-o", urdf, "--report", report, "--force"))
    finally:
        signal.signal(signal.SIGINT, previous)
    assert code == 130, err
    assert len(renames) == 3
    assert json.loads(report.read_text(encoding="utf-8")).get("old") is None
    sidecar = json.loads(pincal.export.urdf_writer.sidecar_path(urdf).read_text(encoding="utf-8"))
    assert sidecar and urdf.read_text(encoding="utf-8").startswith("<?xml")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [report.name, urdf.name, pincal.export.urdf_writer.sidecar_path(urdf).name]
    )


#: A child that runs ``pincal calibrate`` whose fit waits to be interrupted.
_CHILD = """
import signal, sys, time
signal.signal(signal.SIGINT, signal.default_int_handler)  # as from a terminal, even in the background
import pincal.auto.fitting
from pincal.cli import main

def slow_solve(*args, **kwargs):
    print("fitting", file=sys.__stdout__, flush=True)  # the command's own stdout waits for its end
    time.sleep(60)

pincal.auto.fitting.solve = slow_solve
sys.exit(main(sys.argv[1:]))
"""


def test_sigint_during_a_fit_in_a_child_process(data: Path, tmp_path: Path) -> None:
    """A real Ctrl-C (SIGINT) while the fit runs: exit code 130, one line, the old report kept."""
    report, urdf, before = _old_outputs(tmp_path)
    args = [str(a) for a in _calibrate(data, "-o", urdf, "--report", report, "--force")]
    child = subprocess.Popen(
        [sys.executable, "-c", _CHILD, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        assert child.stdout is not None
        for line in child.stdout:
            if line.strip() == "fitting":
                break
        child.send_signal(signal.SIGINT)
        _, err = child.communicate(timeout=60)
    finally:
        child.kill()
    assert child.returncode == 130, err
    _one_line(err, "interrupted")
    _unchanged(tmp_path, before)


def test_atomic_write_refuses_what_is_not_a_regular_file(tmp_path: Path) -> None:
    """The library refuses too (without opening a pipe, which would block)."""
    os.mkfifo(tmp_path / "pipe")
    for path in (tmp_path / "pipe", tmp_path, Path("-")):
        with pytest.raises(pincal.OutputError):
            pincal.files.atomic_write(path, "x")
    assert stat.S_ISFIFO((tmp_path / "pipe").stat().st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pipe"]


def test_standard_output_closed_early_ends_quietly(tmp_path: Path) -> None:
    """``pincal twists ur5 | head -0``: no traceback, exit code 141 (as a shell reports SIGPIPE)."""
    read_end, write_end = os.pipe()
    os.close(read_end)  # every write to the pipe fails with EPIPE
    try:
        result = subprocess.run(
            [sys.executable, "-m", "pincal.cli", "twists", "ur5"],
            stdout=write_end,
            stderr=subprocess.PIPE,
            text=True,
            timeout=120,
        )
    finally:
        os.close(write_end)
    assert result.returncode == 141, result.stderr
    assert result.stderr == ""
