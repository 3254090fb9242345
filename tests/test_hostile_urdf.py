"""Hostile and mistaken URDFs (issue 17): refused with one line before any URDF parser sees them.

A link that is its own parent, or a closed loop of joints, used to kill the process with SIGSEGV
inside Pinocchio's URDF parser; a joint axis ``0 0 0`` gave a model that rotates nothing (and
``pincal twists`` printed "max error 3.14" and exited 0); a 1,000-joint chain exhausted the memory;
limits with ``lower > upper`` were planned with. Each case here must end with exit code 2, one
``pincal: error:`` line naming the joint or link, no traceback, and every file unchanged. The
cases that crashed run in a child process, so that a regression fails one test instead of
killing the test run.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import pincal
import pincal.robot.robots
import pincal.robot.urdf_parse
from pincal.cli import main
from pincal.options import BUNDLED
from pincal.robot.urdf_checks import MAX_CHAIN, MAX_JOINTS, check_urdf_structure


def _joint(
    name: str, parent: str, child: str, kind: str = "revolute", axis: str = "0 0 1", limit: str = ""
) -> str:
    limit = limit or 'lower="-3" upper="3"'
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="{axis}"/>'
        f'<limit {limit} effort="1" velocity="1"/></joint>'
    )


def _robot(links: list[str], joints: list[str]) -> str:
    return '<robot name="r">' + "".join(f'<link name="{n}"/>' for n in links) + "".join(joints) + "</robot>"


def _arm(n: int = 3, **first: str) -> str:
    """A chain l0 - j0 - l1 - ... - l<n>; keyword arguments replace those of joint j0."""
    joints = [_joint(f"j{k}", f"l{k}", f"l{k + 1}", **(first if k == 0 else {})) for k in range(n)]
    return _robot([f"l{k}" for k in range(n + 1)], joints)


L4 = ["l0", "l1", "l2", "l3"]
CHAIN = [_joint("a", "l0", "l1"), _joint("b", "l1", "l2"), _joint("c", "l2", "l3")]

#: name -> (URDF text, words the error line must hold)
REFUSED: dict[str, tuple[str, tuple[str, ...]]] = {
    "own_parent": (_robot(L4, [*CHAIN, _joint("s", "l3", "l3", "fixed")]), ("'s'", "own parent")),
    "own_parent_root": (_robot(["l0", "l1"], [_joint("s", "l0", "l0"), _joint("a", "l0", "l1")]), ("'s'",)),
    "two_parents": (_robot(L4, [*CHAIN, _joint("d", "l3", "l1")]), ("'l1'", "two joints", "loop")),
    "diamond": (
        _robot(
            L4,
            [
                _joint("a", "l0", "l1"),
                _joint("b", "l0", "l2"),
                _joint("c", "l1", "l3"),
                _joint("d", "l2", "l3"),
            ],
        ),
        ("'l3'", "two joints"),
    ),
    "ring_no_root": (
        _robot(["l0", "l1"], [_joint("a", "l0", "l1"), _joint("b", "l1", "l0")]),
        ("no root", "loop"),
    ),
    "detached_ring": (
        _robot(
            L4, [_joint("a", "l0", "l1"), _joint("b", "l2", "l3", "fixed"), _joint("c", "l3", "l2", "fixed")]
        ),
        ("l2", "loop"),
    ),
    "two_roots": (_robot([*L4, "m0", "m1"], [*CHAIN, _joint("m", "m0", "m1")]), ("2 root links",)),
    "zero_axis": (_arm(axis="0 0 0"), ("'j0'", "axis", "zero")),
    "zero_axis_prismatic": (_arm(kind="prismatic", axis="0 0 0"), ("'j0'", "zero")),
    "tiny_axis": (_arm(axis="0 0 1e-9"), ("'j0'", "zero")),
    "nan_axis": (_arm(axis="0 nan 1"), ("'j0'", "axis")),
    "two_component_axis": (_arm(axis="0 1"), ("'j0'", "axis")),
    "limits_swapped": (_arm(limit='lower="2" upper="-2"'), ("'j0'", "lower", "upper")),
    "inf_limit": (_arm(limit='lower="-inf" upper="1"'), ("'j0'", "limit")),
    "nan_origin": (_arm().replace('xyz="0 0 0.1"', 'xyz="0 nan 0.1"', 1), ("'j0'", "origin")),
    # Regression (was a bug): twists blamed "the twists disagree with Pinocchio by 5.56e+285", plan
    # planned with an overflowing model and exited 0
    "huge_origin": (_arm().replace('xyz="0 0 0.1"', 'xyz="1e300 0 0.1"', 1), ("'j0'", "origin", "metres")),
    "huge_prismatic_limit": (
        _arm(kind="prismatic", limit='lower="-1e300" upper="1"'),
        ("'j0'", "limit", "metres"),
    ),
    "undefined_link": (_robot(L4, [*CHAIN[:2], _joint("c", "l2", "nowhere")]), ("'nowhere'",)),
    "no_child": (
        _robot(["l0"], ['<joint name="a" type="fixed"><parent link="l0"/></joint>']),
        ("'a'", "child"),
    ),
    "duplicate_joint": (_robot(L4, [*CHAIN, _joint("a", "l0", "l3")]), ("'a'", "unique")),
    "duplicate_link": (_robot([*L4, "l2"], CHAIN), ("'l2'", "unique")),
    "unnamed_link": (_robot(L4, CHAIN).replace('<link name="l3"/>', "<link/>"), ("no name",)),
    "no_links": ('<robot name="r"></robot>', ("no <link>",)),
    "not_xml": ('<robot name="r"><link name="a">', ("XML",)),
    "not_a_robot": ('<sdf><link name="a"/></sdf>', ("<sdf>",)),
    "long_chain": (_arm(MAX_JOINTS), ("movable joints in a row",)),
    "chain_just_too_long": (_arm(MAX_CHAIN + 1), (f"{MAX_CHAIN + 1} movable",)),
    "too_many_joints": (
        _robot(
            ["b"] + [f"s{k}" for k in range(MAX_JOINTS + 1)],
            [_joint(f"j{k}", "b", f"s{k}", "fixed") for k in range(MAX_JOINTS + 1)],
        ),
        (f"{MAX_JOINTS + 1} joints",),
    ),
}
#: The ones that crashed the process (SIGSEGV inside the URDF parser) before the check.
CRASHED = ("own_parent", "own_parent_root", "two_parents")


def _urdf(folder: Path, text: str, name: str = "robot.urdf") -> Path:
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


def _error_line(code: int, out: str, err: str) -> str:
    assert code == 2, (code, out, err)
    assert "Traceback" not in out + err
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("pincal: error: "), err
    return lines[0]


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_structure_is_refused_before_the_parser(case: str, tmp_path: Path) -> None:
    """The check alone refuses each case, naming what is wrong."""
    text, words = REFUSED[case]
    with pytest.raises(pincal.RobotError) as info:
        check_urdf_structure(text, tmp_path / "robot.urdf")
    for word in words:
        assert word in str(info.value), (word, str(info.value))


@pytest.mark.parametrize("case", sorted(set(REFUSED) - set(CRASHED)))
def test_commands_refuse_a_bad_structure_with_one_line(
    case: str, capfd: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """``twists`` and ``plan`` (the commands that take only a URDF) end with one line, files unchanged."""
    urdf = _urdf(tmp_path, REFUSED[case][0])
    before = urdf.read_bytes()
    for args in (["twists", urdf], ["plan", urdf, "--poses", "5", "-o", tmp_path / "p.csv"]):
        capfd.readouterr()
        code = main([str(a) for a in args])
        captured = capfd.readouterr()
        line = _error_line(code, captured.out, captured.err)
        assert "robot.urdf" in line
    assert urdf.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["robot.urdf"]


@pytest.mark.parametrize("case", CRASHED)
def test_urdfs_that_crashed_the_parser_end_in_one_line(case: str, tmp_path: Path) -> None:
    """In a child process (a regression would be a signal, not an exit code): exit 2, one line."""
    urdf = _urdf(tmp_path, REFUSED[case][0])
    result = subprocess.run(
        [sys.executable, "-m", "pincal.cli", "twists", str(urdf)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    _error_line(result.returncode, result.stdout, result.stderr)


def test_real_urdfs_pass_the_check() -> None:
    """No false refusal: every bundled robot's URDF passes, and loads."""
    for name in BUNDLED:
        path = pincal.robot.robots.bundled_urdf(name)
        check_urdf_structure(pincal.robot.descriptions.read_urdf_text(path), path)
        assert pincal.load_robot(name).n_joints > 0


def test_a_long_but_sane_chain_loads(tmp_path: Path) -> None:
    """The bound is not a limit on real arms: a chain of :data:`MAX_CHAIN` joints loads."""
    robot = pincal.load_robot(_urdf(tmp_path, _arm(MAX_CHAIN)))
    assert robot.n_joints == MAX_CHAIN


@pytest.mark.parametrize("axis", ["0 0 2", "0 1 1", "0.0001 0 0.001"])
def test_an_axis_not_of_unit_length_is_read_as_its_direction(axis: str, tmp_path: Path) -> None:
    """A nonzero axis is normalised (as Pinocchio, KDL and MoveIt read it): the same kinematics as
    its unit vector, and every model's twist has a unit rotation."""
    unit = np.array([float(v) for v in axis.split()])
    unit /= np.linalg.norm(unit)
    scaled = pincal.load_robot(_urdf(tmp_path, _arm(axis=axis), "scaled.urdf"))
    exact = pincal.load_robot(_urdf(tmp_path, _arm(axis=" ".join(repr(float(v)) for v in unit)), "unit.urdf"))
    rng = np.random.default_rng(0)
    for q in scaled.random_configurations(20, rng):
        a, b = scaled.frame_placement(q), exact.frame_placement(q)
        assert np.allclose(a.homogeneous, b.homogeneous, atol=1e-12)
    assert np.allclose(np.linalg.norm(scaled.axes[:, 3:], axis=1), 1.0)


def test_twists_exits_2_when_pinocchio_disagrees(
    capfd: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Past the structure check (switched off here), the zero-axis arm's twists disagree with
    Pinocchio by about π: ``twists`` ends with exit 2 and one line, and prints no table (a
    refused run prints nothing on stdout)."""
    monkeypatch.setattr(pincal.robot.urdf_parse, "check_urdf_structure", lambda text, path: None)
    urdf = _urdf(tmp_path, _arm(axis="0 0 0"))
    capfd.readouterr()
    code = main(["twists", str(urdf)])
    captured = capfd.readouterr()
    line = _error_line(code, captured.out, captured.err)
    assert "disagree with Pinocchio" in line
    assert captured.out == ""


def test_twists_of_a_sound_arm_exit_0(capfd: pytest.CaptureFixture[str]) -> None:
    assert main(["twists", "ur5"]) == 0
    assert "max error" in capfd.readouterr().out
