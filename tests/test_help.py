"""Every command's ``--help`` tells what each option does and what it is when not given, and
files every option under a group; the same option means the same on every command."""

from __future__ import annotations

import argparse

import pytest
from cli_run import run

from pincal.cli.parser import build_parser

PARSER = build_parser()
COMMANDS = next(a for a in PARSER._actions if isinstance(a, argparse._SubParsersAction)).choices


def _options(command: str) -> list[argparse.Action]:
    return [a for a in COMMANDS[command]._actions if not isinstance(a, argparse._HelpAction)]


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_option_and_argument_has_help(command: str) -> None:
    missing = [a.option_strings or a.dest for a in _options(command) if not a.help]
    assert not missing, missing


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_default_is_shown(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    """An option with a default value says it (--seed, --candidates, --loss used not to)."""
    for action in _options(command):
        default = action.default
        if not action.option_strings or default in (None, False, [], (), argparse.SUPPRESS):
            continue
        assert "default" in action.help.lower() or f"({default})" in action.help, (
            action.option_strings,
            action.help,
        )


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_option_is_in_a_group(command: str) -> None:
    """No option is left under argparse's bare "options" (--prior, --force-fit were)."""
    bare = next(g for g in COMMANDS[command]._action_groups if g.title == "options")
    loose = [a.option_strings for a in bare._group_actions if not isinstance(a, argparse._HelpAction)]
    assert not loose, loose


def test_holdout_says_what_it_is_when_not_given() -> None:
    holdout = next(a for a in _options("calibrate") if "--holdout" in a.option_strings)
    assert "default" in holdout.help


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_units_cover_prismatic_joints_wherever_joints_are_read_or_written(command: str) -> None:
    units = [a for a in _options(command) if "--units" in a.option_strings]
    if units:
        assert "metres" not in units[0].help, units[0].help  # plan's said: prismatic joints in metres


def test_plot_is_one_name() -> None:
    """accuracy and diagnose both take ``--plot FILE.png``."""
    for command in ("accuracy", "diagnose"):
        assert any("--plot" in a.option_strings for a in _options(command)), command


def test_compensate_names_its_recording_the_program() -> None:
    groups = [g.title or "" for g in COMMANDS["compensate"]._action_groups]
    recording = next(t for t in groups if "ROS" in t)
    assert "PROGRAM" in recording and "as DATA" not in recording


@pytest.mark.parametrize("command", ["accuracy", "calibrate", "plan", "twists", "compensate"])
def test_robot_descriptions_are_read_alike(command: str) -> None:
    """Every command that takes ROBOT reads a xacro (its arguments and packages) and a bundled name."""
    flags = {f for a in _options(command) for f in a.option_strings}
    assert {"--xacro-arg", "--package-path"} <= flags
    robot = next(a for a in _options(command) if a.dest == "robot")
    assert ".xacro" in robot.help and "ur5" in robot.help


def test_accuracy_reads_a_xacro_with_its_packages(capsys: pytest.CaptureFixture[str], tmp_path) -> None:
    from pathlib import Path

    here = Path(__file__).parent / "data" / "xacro"
    code, _, err = run(
        capsys,
        "accuracy",
        here / "arm.urdf.xacro",
        tmp_path / "none.csv",
        "--package-path",
        f"pincal_test_parts={here / 'pincal_test_parts'}",
    )
    assert code == 2 and "none.csv" in err and "package" not in err, err  # past the robot, to the data
