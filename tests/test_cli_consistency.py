"""The command line as one whole: ``--version``, one name for the JSON report (old names kept),
options in groups, ``pincal template``, the progress bar silent off a terminal, and a README
that is a short door.
"""

from __future__ import annotations

import csv
import io
import json
import re
from importlib import metadata
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from cli_run import run

import pincal
from pincal.cli import build_parser, main
from pincal.cli.common import ProgressBar, progress_line
from pincal.cli.help_groups import GROUPS

ROOT = Path(__file__).resolve().parents[1]
#: What ``pincal calibrate --help`` lists under each group, at least.
CALIBRATE_GROUPS = {
    "data": ("--tip", "--units", "--degrees", "--test"),
    "model": ("--model", "--loss", "--outliers"),
    "automatic choice": ("--params", "--extend", "--folds", "--nested"),
    "output": ("--report", "--output", "--force"),
}


def _help(*command: str) -> str:
    """The ``--help`` text of ``pincal COMMAND``."""
    parser = build_parser()
    for name in command:
        parser = next(
            a.choices[name] for a in parser._actions if getattr(a, "choices", None) and name in a.choices
        )
    return parser.format_help()


def _subcommands() -> list[str]:
    parser = build_parser()
    return [
        name for a in parser._actions if isinstance(getattr(a, "choices", None), dict) for name in a.choices
    ]


# --- --version ---------------------------------------------------------------------------------


def test_version_prints_the_installed_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0
    assert capsys.readouterr().out.strip() == f"pincal {metadata.version('pincal')}"


# --- --help: groups, and the documentation cited -----------------------------------------------


def test_calibrate_help_lists_its_options_in_groups_in_order() -> None:
    text = _help("calibrate")
    starts = [text.index(f"\n{title}:\n") for title in CALIBRATE_GROUPS]
    assert starts == sorted(starts), "groups out of order"
    ends = [*starts[1:], text.index("\nDocumentation:")]
    for (title, flags), start, end in zip(CALIBRATE_GROUPS.items(), starts, ends):
        section = text[start:end]
        for flag in flags:
            assert re.search(rf"\n  (-\w( \S+)?, )?{flag}\b", section), f"{flag} not under {title}"


def test_every_grouped_option_exists_and_no_option_is_lost() -> None:
    """Grouping moves options, never drops one: each sub-command's options before and after."""
    parser = build_parser()
    known = set()
    for action in parser._actions:
        for command in getattr(action, "choices", None) or {}:
            sub = action.choices[command]
            listed = [a for g in sub._action_groups for a in g._group_actions]
            assert sorted(map(id, listed)) == sorted(map(id, sub._actions)), command
            known |= {f for a in sub._actions for f in a.option_strings}
    grouped = {f for flags in GROUPS.values() for f in flags}
    assert grouped <= known, grouped - known


@pytest.mark.parametrize("command", ["", *_subcommands()])
def test_help_cites_the_documentation_not_the_contract(command: str) -> None:
    text = _help(*([command] if command else []))
    assert "docs/" in text
    assert "contracts.md" not in text


# --- one name for the JSON report --------------------------------------------------------------


def _flange_poses(path: Path, n: int = 8, seed: int = 0) -> Path:
    """Flange poses ``x,y,z,qw,qx,qy,qz`` [m] whose TCP (0.1, 0, 0.2) m touches one point."""
    rng = np.random.default_rng(seed)
    tcp, point = np.array([0.1, 0.0, 0.2]), np.array([0.5, 0.1, 0.3])
    rows = []
    for _ in range(n):
        rot = pin.exp3(rng.normal(0.0, 0.6, 3))
        quat = pin.Quaternion(rot)
        rows.append([*(point - rot @ tcp), quat.w, quat.x, quat.y, quat.z])
    lines = ["x,y,z,qw,qx,qy,qz"] + [",".join(repr(float(v)) for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_tcp_report_and_its_old_name_json_write_the_same(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    poses = _flange_poses(tmp_path / "poses.csv")
    written = {}
    for flag in ("--report", "--json"):
        out = tmp_path / f"tcp{flag}.json"
        code, _, err = run(capsys, "tcp", poses, flag, out)
        assert code == 0, err
        written[flag] = json.loads(out.read_text(encoding="utf-8"))
    assert written["--report"] == written["--json"]
    np.testing.assert_allclose(written["--report"]["tcp"], [0.1, 0.0, 0.2], atol=1e-9)


@pytest.mark.parametrize("command", ["calibrate", "diagnose", "tcp"])
def test_report_is_the_name_on_every_command_that_writes_json(command: str) -> None:
    args = ["tcp", "poses.csv"] if command == "tcp" else [command, "ur5", "d.csv"]
    parsed = build_parser().parse_args([*args, "--report", "r.json"])
    assert Path("r.json") in (getattr(parsed, "report", None), getattr(parsed, "json", None))


def test_diagnose_report_and_json_alias(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    robot = pincal.load_robot("ur5")
    _, data, _ = pincal.simulate(robot, n_fit=40, n_test=1, seed=3)
    path = tmp_path / "d.csv"
    pincal.write_csv(path, data)
    reports = []
    for flag in ("--report", "--json"):
        out = tmp_path / f"diag{flag}.json"
        code, _, err = run(capsys, "diagnose", "ur5", path, flag, out)
        assert code == 0, err
        reports.append(json.loads(out.read_text(encoding="utf-8")))
    assert {"baseline", "cause", "extended", "gain", "candidates"} <= set(reports[0])
    assert reports[0]["baseline"] == reports[1]["baseline"]
    assert reports[0]["cause"] == reports[1]["cause"]


# --- pincal template ---------------------------------------------------------------------------


def _fill(template: str, robot: pincal.Robot, data: pincal.Dataset, degrees: bool, mm: bool) -> str:
    """The template with one row per pose of ``data``, in the header's own column order and units."""
    lines = template.splitlines()
    header = next(line for line in lines if not line.startswith("#")).split(",")
    length, angle = (1e3 if mm else 1.0), (np.rad2deg(1.0) if degrees else 1.0)
    scale_q = np.where(np.array(robot.prismatic), length, angle)
    quats = data.quaternions if data.quaternions is not None else np.zeros((len(data), 4))
    out = io.StringIO()
    out.write(template)
    writer = csv.writer(out, lineterminator="\n")
    for i in range(len(data)):
        values = dict(zip(data.joint_names, data.q[i] * scale_q))
        values.update(zip("xyz", data.points[i] * length))
        values.update(zip(("qw", "qx", "qy", "qz"), quats[i]))
        writer.writerow([repr(float(values[c])) for c in header])
    return out.getvalue()


@pytest.mark.parametrize(("name", "flags"), [("ur5", ["--degrees", "--units", "mm"]), ("panda", ["--pose"])])
def test_template_filled_with_simulated_values_calibrates(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, name: str, flags: list[str]
) -> None:
    robot = pincal.load_robot(name)
    pose = "--pose" in flags
    degrees, mm = "--degrees" in flags, "mm" in flags
    template = tmp_path / "template.csv"
    code, out, err = run(capsys, "template", name, *flags, "-o", template)
    assert code == 0, err
    text = template.read_text(encoding="utf-8")
    header = [line for line in text.splitlines() if not line.startswith("#")]
    measured = ["x", "y", "z", *(["qw", "qx", "qy", "qz"] if pose else [])]
    assert header == [",".join([*robot.joint_names, *measured])]
    assert ("degrees" in text) == degrees and ("millimetres" in text) == mm
    _, fit, _ = pincal.simulate(robot, n_fit=40, n_test=1, seed=1, rot_noise=1e-4 if pose else None)
    filled = tmp_path / "filled.csv"
    filled.write_text(_fill(text, robot, fit, degrees, mm), encoding="utf-8")
    report = tmp_path / "report.json"
    units = ["--degrees"] * degrees + ["--units", "mm"] * mm
    code, _, err = run(capsys, "calibrate", name, filled, *units, "--extend", "none", "--report", report)
    assert code == 0, err
    result = json.loads(report.read_text(encoding="utf-8"))
    assert result["n_poses"] == 40
    assert result["measure"] == ("pose" if pose else "position")
    train = result["train"]
    assert train["after"]["rms_mm"] < 0.1 < train["before"]["rms_mm"]  # 0.03 mm noise, mm-size errors


def test_template_goes_to_stdout_and_refuses_to_overwrite(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    code, out, _ = run(capsys, "template", "mrres5", "--points")
    assert code == 0
    assert out.splitlines()[-1] == "joint1,joint2,joint3,joint4,joint5,point"
    existing = tmp_path / "t.csv"
    existing.write_text("keep\n", encoding="utf-8")
    code, _, err = run(capsys, "template", "ur5", "-o", existing)
    assert code == 2 and "--force" in err
    assert existing.read_text(encoding="utf-8") == "keep\n"


# --- the progress bar --------------------------------------------------------------------------


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_is_silent_when_stderr_is_not_a_terminal(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("sys.stderr", io.StringIO())
    assert progress_line("diagnosis") is None


def test_progress_bar_draws_on_a_terminal_and_clears_its_line(monkeypatch: pytest.MonkeyPatch) -> None:
    terminal = _Terminal()
    monkeypatch.setattr("sys.stderr", terminal)
    show = progress_line("diagnosis")
    assert isinstance(show, ProgressBar)
    for k in range(1, 5):
        show(k, 4, f"candidate {k}")
    assert "diagnosis" in terminal.getvalue() and "/4" in terminal.getvalue()
    assert show.bar is not None and show.bar.n == 4  # drawn at most every 0.1 s: counted each call
    show(1, 9, "next round")  # a new total: a new bar
    assert show.bar.total == 9 and show.bar.n == 1
    show.close()
    assert show.bar is None


def test_diagnose_off_a_terminal_prints_no_progress(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    robot = pincal.load_robot("ur5")
    _, data, _ = pincal.simulate(robot, n_fit=40, n_test=1, seed=4)
    path = tmp_path / "d.csv"
    pincal.write_csv(path, data)
    code, _, err = run(capsys, "diagnose", "ur5", path)
    assert code == 0
    assert "\r" not in err and "candidates" not in err


# --- the README: a door, not a diary -----------------------------------------------------------


#: A path that exists on one machine only.
MACHINE_PATH = re.compile(r"(?<![\w.])(/work/|/home/|/tmp/|/Users/|/root/|[A-Z]:\\)")


def test_readme_is_at_most_10_kb_and_names_no_machine_path() -> None:
    readme = (ROOT / "README.md").read_bytes()
    assert len(readme) <= 10 * 1024, f"README.md is {len(readme)} bytes"
    assert not MACHINE_PATH.findall(readme.decode("utf-8"))


def test_the_documentation_names_no_machine_path_and_every_readme_link_exists() -> None:
    pages = sorted((ROOT / "docs").rglob("*.md"))
    assert pages
    for page in pages:
        if "_build" not in page.parts:
            assert not MACHINE_PATH.findall(page.read_text(encoding="utf-8")), page
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    for target in re.findall(r"\]\(((?:docs|notebooks|benchmarks)/[^)#]*)", readme):
        assert (ROOT / target).exists(), target
