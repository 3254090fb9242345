"""Joint kinds users have in their chains: each calibrated exactly, or refused with one line.

A small 4-joint arm with a two-finger gripper (the second finger mimics the first) is written by
the test in variants:

- calibrated (every model, simulated position data, then ``write_corrected_urdf``, reload and
  compare to 1e-9 m / 1e-9 rad at random configurations; urdfdom's ``check_urdf`` checks each file
  through the session hook): a continuous joint, a prismatic joint, the gripper with its mimic
  finger off the chain, and a ``world`` link in front of the base through a fixed, a floating or
  a planar joint (held at neutral: the base stands still). The joints off the chain and the
  base's joint keep their ``<origin>`` as written;
- refused with one ``pincal: error:`` line (exit 2) that says what to do: a mimic joint on the
  chain (tip on the finger), a floating joint between the arm's joints, a tip with only the
  floating base joint before it, a value to lock a floating joint at.
A locked continuous joint is held at the value asked for (its (cos, sin) coordinates).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from lxml import etree

import pincal
from pincal.cli import main

TOL = 1e-9  # [m] and [rad]
N_POSES = 30
#: Variant -> (type of the base joint from a world link or None, type of j2, type of j3).
KINDS = {
    "continuous": (None, "continuous", "revolute"),
    "prismatic": (None, "revolute", "prismatic"),
    "fixed_world": ("fixed", "revolute", "revolute"),
    "floating_world": ("floating", "revolute", "revolute"),
    "planar_world": ("planar", "revolute", "revolute"),
    "floating_mid_chain": (None, "floating", "revolute"),
}


def _joint(
    name: str, kind: str, parent: str, child: str, xyz: str, rpy: str, axis: str, extra: str = ""
) -> str:
    limit = (
        '<limit lower="-2" upper="2" effort="10" velocity="1"/>' if kind in ("revolute", "prismatic") else ""
    )
    ax = "" if kind in ("fixed", "floating") else f'<axis xyz="{axis}"/>'
    return (
        f'  <joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}" rpy="{rpy}"/>{ax}{limit}{extra}</joint>\n'
    )


def _link(name: str) -> str:
    return (
        f'  <link name="{name}"><inertial><mass value="1"/><origin xyz="0 0 0.05"/>'
        '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>\n'
    )


def write_arm(folder: Path, variant: str) -> Path:
    """The small arm of ``variant`` (a key of :data:`KINDS`) as ``folder/<variant>.urdf``."""
    base, j2, j3 = KINDS[variant]
    text = '<?xml version="1.0"?>\n<!-- a test arm -->\n<robot name="arm">\n'
    if base is not None:
        text += '  <link name="world"/>\n'
        text += _joint("world_joint", base, "world", "base_link", "0.1 0.2 0.3", "0 0 0.5", "0 0 1")
    text += _link("base_link")
    text += _joint("j1", "revolute", "base_link", "l1", "0 0 0.1", "0 0 0", "0 0 1") + _link("l1")
    text += _joint("j2", j2, "l1", "l2", "0 0.1 0.2", "1.5707963 0 0", "0 0 1") + _link("l2")
    text += _joint("j3", j3, "l2", "l3", "0.3 0 0", "0 0 0", "0 1 0") + _link("l3")
    text += _joint("j4", "revolute", "l3", "tool", "0.2 0 0.05", "0 0 0.3", "1 0 0") + _link("tool")
    text += _joint("f1", "prismatic", "tool", "finger1", "0 0.02 0.05", "0 0 0", "0 1 0") + _link("finger1")
    mimic = '<mimic joint="f1" multiplier="1" offset="0"/>'
    text += _joint("f2", "prismatic", "tool", "finger2", "0 -0.02 0.05", "0 0 0", "0 -1 0", mimic)
    text += _link("finger2") + "</robot>\n"
    path = folder / f"{variant}.urdf"
    path.write_text(text, encoding="utf-8")
    return path


def _origins(path: Path) -> dict[str, tuple[str | None, str | None]]:
    """Every joint's ``<origin>`` attributes as written: name -> (xyz, rpy)."""
    root = etree.parse(str(path)).getroot()
    return {
        j.get("name"): (j.find("origin").get("xyz"), j.find("origin").get("rpy")) for j in root.iter("joint")
    }


SUPPORTED = ("continuous", "prismatic", "fixed_world", "floating_world", "planar_world")


@pytest.mark.parametrize("model", pincal.MODELS)
@pytest.mark.parametrize("variant", SUPPORTED)
def test_kind_calibrates_and_exports_exactly(tmp_path: Path, variant: str, model: str) -> None:
    """Load, calibrate on simulated data, export, reload: the URDF is the calibrated model.

    Args:
        tmp_path: a fresh folder.
        variant: the joint kind in the chain.
        model: the calibration model.
    """
    urdf = write_arm(tmp_path, variant)
    robot = pincal.load_robot(str(urdf), tip="tool")
    assert robot.joint_names == ("j1", "j2", "j3", "j4")  # no base joint, no finger
    assert robot.prismatic == (False, False, variant == "prismatic", False)
    truth = pincal.random_truth(robot, 1)
    q = robot.random_configurations(N_POSES, np.random.default_rng(2), 0.05)
    forced = pincal.Pull(force_fit=True)  # the export is tested, not the guard's verdict
    cal = pincal.calibrate(robot, truth.measure(q, seed=3), model, params="all", pull=forced)
    out, _ = pincal.write_corrected_urdf(cal, tmp_path / "out.urdf")

    exported = pincal.load_robot(str(out), tip="tool")
    assert exported.joint_names == robot.joint_names
    check = robot.random_configurations(50, np.random.default_rng(4))
    if variant == "continuous":  # beyond ±π too: a continuous joint turns freely
        check[:, 1] *= 3.0
    rotations, positions = cal.base_T_tip(check)
    moved = 0.0
    for qi, r, p in zip(check, rotations, positions):
        placement = exported.frame_placement(qi)
        assert np.linalg.norm(placement.translation - p) <= TOL
        assert np.linalg.norm(pin.log3(placement.rotation.T @ r)) <= TOL
        moved = max(moved, float(np.linalg.norm(robot.frame_placement(qi).translation - p)))
    assert moved > 1e-5, "the calibration changed nothing: nothing is tested"

    before, after = _origins(urdf), _origins(out)
    for name in ("world_joint", "f1", "f2"):  # off the chain, or the base: as written
        assert after.get(name) == before.get(name), name
    assert any(after[j] != before[j] for j in robot.joint_names)


def test_floating_base_is_held_at_identity(tmp_path: Path) -> None:
    """A floating or planar base joint is held at neutral (the identity): the same arm as a fixed one.

    Args:
        tmp_path: a fresh folder.
    """
    fixed = pincal.load_robot(str(write_arm(tmp_path, "fixed_world")), tip="tool")
    q = fixed.random_configurations(10, np.random.default_rng(0))
    for variant in ("floating_world", "planar_world"):
        robot = pincal.load_robot(str(write_arm(tmp_path, variant)), tip="tool")
        assert "world_joint" in robot.urdf_joints and "world_joint" not in robot.joint_names
        for qi in q:
            a, b = robot.frame_placement(qi), fixed.frame_placement(qi)
            assert np.allclose(a.homogeneous, b.homogeneous, atol=1e-12), variant


def test_locked_continuous_joint_takes_its_value(tmp_path: Path) -> None:
    """``locked={"j2": v}`` on a continuous joint turns it by ``v`` (not a bare cos).

    Args:
        tmp_path: a fresh folder.
    """
    urdf = write_arm(tmp_path, "continuous")
    full = pincal.load_robot(str(urdf), tip="tool")
    locked = pincal.load_robot(str(urdf), tip="tool", joints=["j1", "j3", "j4"], locked={"j2": 2.5})
    for qi in full.random_configurations(5, np.random.default_rng(1)):
        qi[1] = 2.5
        expected = full.frame_placement(qi)
        got = locked.frame_placement(np.delete(qi, 1))
        assert np.allclose(got.homogeneous, expected.homogeneous, atol=1e-12)


#: Refusals: (variant, tip, joints, locked, words the line must hold).
REFUSALS = {
    "mimic_on_chain": ("continuous", "finger2", None, None, ("'f2' mimics 'f1'", "tip=")),
    "floating_mid_chain": ("floating_mid_chain", "tool", None, None, ("'j2' is a floating joint", "fixed")),
    "only_the_base": ("floating_world", "base_link", None, None, ("no revolute", "tip=")),
    "base_in_data": ("floating_world", "tool", ["world_joint", "j1", "j2"], None, ("base", "no data column")),
    "lock_floating": ("floating_world", "tool", ["j1", "j2"], {"world_joint": 1.0}, ("cannot lock",)),
}


@pytest.mark.parametrize("case", sorted(REFUSALS))
def test_unsupported_kind_is_refused(tmp_path: Path, case: str) -> None:
    """The API raises RobotError with a line that says what to do.

    Args:
        tmp_path: a fresh folder.
        case: a key of :data:`REFUSALS`.
    """
    variant, tip, joints, locked, words = REFUSALS[case]
    urdf = write_arm(tmp_path, variant)
    with pytest.raises(pincal.RobotError) as info:
        pincal.load_robot(str(urdf), tip=tip, joints=joints, locked=locked)
    message = str(info.value)
    assert "\n" not in message
    for word in words:
        assert word in message, message


@pytest.mark.parametrize(("variant", "tip"), [("continuous", "finger2"), ("floating_mid_chain", "tool")])
def test_cli_refuses_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], variant: str, tip: str
) -> None:
    """``pincal calibrate``: exit 2, one ``pincal: error:`` line naming the joint, nothing written.

    Args:
        tmp_path: a fresh folder.
        capsys: the captured output.
        variant: the arm.
        tip: the measured frame.
    """
    good = pincal.load_robot(str(write_arm(tmp_path, "fixed_world")), tip="tool")
    data = tmp_path / "data.csv"
    pincal.write_csv(data, pincal.simulate(good, 20, 1, seed=0)[1])
    urdf = write_arm(tmp_path, variant)
    capsys.readouterr()
    code = main(["calibrate", str(urdf), str(data), "--tip", tip, "-o", str(tmp_path / "out.urdf")])
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.splitlines()) == 1 and err.startswith("pincal: error:"), err
    assert ("'f2'" if tip == "finger2" else "'j2'") in err
    assert not (tmp_path / "out.urdf").exists()


def test_cli_calibrates_floating_base_arm(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``pincal calibrate`` on the floating-base arm: exit 0, and the written URDF reloads.

    Args:
        tmp_path: a fresh folder.
        capsys: the captured output.
    """
    urdf = write_arm(tmp_path, "floating_world")
    robot = pincal.load_robot(str(urdf), tip="tool")
    data = tmp_path / "data.csv"
    pincal.write_csv(data, pincal.simulate(robot, 40, 1, seed=0)[1])
    out = tmp_path / "out.urdf"
    code = main(["calibrate", str(urdf), str(data), "--tip", "tool", "--params", "all", "-o", str(out)])
    assert code == 0, capsys.readouterr().err
    assert pincal.load_robot(str(out), tip="tool").joint_names == robot.joint_names
