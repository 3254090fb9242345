"""UR calibration in and out: a UR kinematics YAML (``ur_description``'s format) as the nominal
model on the UR URDF, and the calibrated result written back in that format.

The reference is ``ur_description``'s own construction (``urdf/ur_macro.xacro``), written here
from the YAML's raw entries with NumPy alone: ``base_link`` -> ``base_link_inertia`` turned by π
about z, each joint's origin ``xyz = (x, y, z)``, ``rpy = (roll, pitch, yaw)`` (R = Rz Ry Rx) and
axis z, then ``flange`` (rpy 0, -π/2, -π/2) and ``tool0`` (rpy π/2, 0, π/2). The factory YAML
below is what a real ``calibration.conf`` turns into: the three parallel axes' frames moved
hundreds of millimetres along the axes and turned by tenths of a radian about them (compensated
by the next origin), with millimetre and milliradian errors that leave the axes nearly, not
exactly, parallel.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml
from cli_run import one_error_line, run

import pincal
import pincal.data.program
from pincal.export.ur_yaml import write_ur_kinematics
from pincal.robot.ur_frames import DEFAULT_DH, SEGMENTS, default_ur_kinematics, read_ur_kinematics

KEYS = ("x", "y", "z", "roll", "pitch", "yaw")
FACTORY_HASH = "calib_12788084448423163542"
URDF_HASH = "calib_5571163327412394921"


def _rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = (math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch),
                              math.cos(yaw), math.sin(yaw))  # fmt: skip
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    return rz @ ry @ rx


def _origin(xyz: tuple[float, ...], rpy: tuple[float, ...]) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = _rpy(*rpy), xyz
    return out


def ur_description_tool0(path: Path, q: np.ndarray) -> np.ndarray:
    """``base_link_T_tool0`` (4, 4) at joint angles ``q`` (6,), built as ur_macro.xacro does."""
    section = yaml.safe_load(path.read_text())["kinematics"]
    out = _origin((0, 0, 0), (0, 0, math.pi))
    for segment, angle in zip(SEGMENTS, q):
        entry = [float(section[segment][k]) for k in KEYS]
        out = out @ _origin(entry[:3], entry[3:]) @ _origin((0, 0, 0), (0, 0, angle))
    return (
        out
        @ _origin((0, 0, 0), (0, -math.pi / 2, -math.pi / 2))
        @ _origin((0, 0, 0), (math.pi / 2, 0, math.pi / 2))
    )


def _write(path: Path, entries: list[tuple[float, ...]], calibration_hash: str) -> Path:
    lines = ["kinematics:"]
    for segment, entry in zip(SEGMENTS, entries):
        lines += [f"  {segment}:"] + [f"    {k}: {float(v)!r}" for k, v in zip(KEYS, entry)]
    path.write_text("\n".join([*lines, f"  hash: {calibration_hash}"]) + "\n")
    return path


def _default_entries(name: str) -> list[tuple[float, ...]]:
    d1, a2, a3, d4, d5, d6 = DEFAULT_DH[name]
    pi = math.pi
    return [(0, 0, d1, 0, 0, 0), (0, 0, 0, pi / 2, 0, 0), (a2, 0, 0, 0, 0, 0), (a3, 0, d4, 0, 0, 0),
            (0, -d5, 0, pi / 2, 0, 0), (0, d6, 0, pi / 2, pi, pi)]  # fmt: skip


def _factory_entries() -> list[tuple[float, ...]]:
    """ur5's default entries with frames 2-4 moved along (s) and turned about (t) their axes, then
    small errors on every origin."""
    origins = [pin.SE3(pin.rpy.rpyToMatrix(*e[3:]), np.array(e[:3], float)) for e in _default_entries("ur5")]
    slide = [0.0, 0.1236, -0.3071, 0.1829, 0.0, 0.0]  # [m] along each joint's axis
    turn = [0.0, 0.2917, -0.6240, 0.3318, 0.0, 0.0]  # [rad] about it
    moves = [pin.SE3(pin.rpy.rpyToMatrix(0, 0, t), np.array([0, 0, s])) for s, t in zip(slide, turn)]
    rng = np.random.default_rng(7)
    out = []
    for k, origin in enumerate(origins):
        before = moves[k - 1].inverse() if k > 0 else pin.SE3.Identity()
        error = pin.exp6(pin.Motion(np.concatenate([rng.normal(0, 4e-4, 3), rng.normal(0, 6e-4, 3)])))
        placed = before * origin * error * moves[k]
        out.append((*placed.translation, *pin.rpy.matrixToRpy(placed.rotation)))
    return out


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("ur_yaml")
    out = {n: _write(folder / f"{n}_default.yaml", _default_entries(n), f"calib_{n}") for n in DEFAULT_DH}
    out["factory"] = _write(folder / "factory.yaml", _factory_entries(), FACTORY_HASH)
    return out


def _max_gap(robot: pincal.Robot, path: Path, seed: int = 0) -> float:
    """Largest difference of ``base_T_tip`` between the robot and the YAML's construction."""
    rng = np.random.default_rng(seed)
    return max(
        np.abs(robot.frame_placement(q).homogeneous - ur_description_tool0(path, q)).max()
        for q in rng.uniform(-math.pi, math.pi, (20, 6))
    )


@pytest.mark.parametrize("name", sorted(DEFAULT_DH))
def test_bundled_urdfs_are_the_default_yaml(files: dict[str, Path], name: str) -> None:
    """example-robot-data's ur3/ur5/ur10 (joints about y, no base_link_inertia) are exactly
    ur_description's construction from the default YAML, and so is the robot with it applied."""
    assert _max_gap(pincal.load_robot(name), files[name]) < 1e-9
    applied = pincal.load_robot(name, kinematics=files[name])
    assert _max_gap(applied, files[name]) < 1e-12
    assert 'name="base_link_inertia"' in applied.urdf_text
    default = default_ur_kinematics(name)
    q = np.random.default_rng(1).uniform(-3, 3, 6)
    assert np.abs(default.chain(q).homogeneous - ur_description_tool0(files[name], q)).max() < 1e-12


def test_factory_yaml_loads_exactly_and_keeps_the_robot(files: dict[str, Path]) -> None:
    """The factory YAML's frames are hundreds of mm and tenths of a radian from the nominal ones,
    its axes nearly parallel; on the bundled ur5 the chain is the YAML's exactly, tool0 within a
    few mm of the nominal robot's, the inertias where they were (centre of mass within 5 mm)."""
    kin = read_ur_kinematics(files["factory"])
    assert kin.calibration_hash == FACTORY_HASH
    z = [o.rotation[:, 2] for o in kin.origins]
    assert 0 < math.acos(min(1.0, abs(z[2] @ np.array([0, 0, 1])))) < 5e-3  # nearly, not exactly
    assert max(abs(kin.origins[k].translation[2]) for k in (2, 3)) > 0.1
    robot, nominal = pincal.load_robot("ur5", kinematics=files["factory"]), pincal.load_robot("ur5")
    assert _max_gap(robot, files["factory"]) < 1e-12
    rng = np.random.default_rng(2)
    for q in rng.uniform(-3, 3, (10, 6)):
        assert (
            np.linalg.norm(robot.frame_placement(q).translation - nominal.frame_placement(q).translation)
            < 5e-3
        )
        full, full0 = (pin.buildModelFromXML(r.urdf_text) for r in (robot, nominal))
        com = [pin.centerOfMass(m, m.createData(), pincal_q(m, q)) for m in (full, full0)]
        assert np.linalg.norm(com[0] - com[1]) < 5e-3


def pincal_q(model: pin.Model, q: np.ndarray) -> np.ndarray:
    """A full configuration with the six UR joints at ``q`` (by name)."""
    out = pin.neutral(model)
    for k, name in enumerate(("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
                              "wrist_2_joint", "wrist_3_joint")):  # fmt: skip
        out[model.joints[model.getJointId(name)].idx_q] = q[k]
    return out


@pytest.mark.parametrize("model", ["placements", "poe", "mdh", "offsets"])
def test_written_yaml_is_the_calibration(files: dict[str, Path], tmp_path: Path, model: str) -> None:
    """Calibrate on the factory YAML, write the YAML: ur_description's construction from it is the
    calibrated chain to 1e-9 m (and 1e-9 rad); it keeps the source's hash; the held-out error drops."""
    robot = pincal.load_robot("ur5", kinematics=files["factory"])
    truth, fit, test = pincal.simulate(robot, 60, 40, seed=4, rot_noise=2e-4)
    cal = pincal.calibrate(robot, fit, model, test=test, params="all")
    path, side = write_ur_kinematics(cal, tmp_path / "robot_calibration.yaml", FACTORY_HASH)
    assert read_ur_kinematics(path).calibration_hash == FACTORY_HASH
    assert json.loads(side.read_text())["ur_kinematics"] == path.name
    q = np.random.default_rng(3).uniform(-math.pi, math.pi, (20, 6))
    rot, pos = cal.base_T_tip(q)
    for k in range(len(q)):
        built = ur_description_tool0(path, q[k])
        assert np.abs(built[:3, 3] - pos[k]).max() < 1e-9 and np.abs(built[:3, :3] - rot[k]).max() < 1e-9
    assert cal.test_before is not None and cal.test_after is not None
    if model != "offsets":  # joint offsets alone cannot take up the placement errors
        assert cal.test_after.rms_mm < cal.test_before.rms_mm / 5


def _ur_description_urdf(entries: list[tuple[float, ...]]) -> str:
    """A URDF as ur_description's xacro writes it (its links, fixed joints and frames)."""
    links = ["base_link_inertia", "shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link",
             "wrist_2_link", "wrist_3_link"]  # fmt: skip
    joints = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
              "wrist_3_joint")  # fmt: skip
    inertial = '<inertial><mass value="2.0"/><origin xyz="0 0 0.05" rpy="0 0 0"/>' \
        '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>'  # fmt: skip
    parts = ['<robot name="ur5">', '<link name="base_link"/>', '<link name="base"/>', '<link name="flange"/>',
             '<link name="tool0"/>'] + [f'<link name="{n}">{inertial}</link>' for n in links]  # fmt: skip

    def fixed(name: str, parent: str, child: str, rpy: str) -> str:
        return (f'<joint name="{name}" type="fixed"><parent link="{parent}"/><child link="{child}"/>'
                f'<origin xyz="0 0 0" rpy="{rpy}"/></joint>')  # fmt: skip

    parts += [fixed("base_link-base_link_inertia", "base_link", "base_link_inertia", f"0 0 {math.pi!r}"),
              fixed("base_link-base_fixed_joint", "base_link", "base", f"0 0 {math.pi!r}"),
              fixed("wrist_3-flange", "wrist_3_link", "flange", f"0 {-math.pi / 2!r} {-math.pi / 2!r}"),
              fixed("flange-tool0", "flange", "tool0", f"{math.pi / 2!r} 0 {math.pi / 2!r}")]  # fmt: skip
    for k, (joint, entry) in enumerate(zip(joints, entries)):
        xyz, rpy = " ".join(repr(float(v)) for v in entry[:3]), " ".join(repr(float(v)) for v in entry[3:])
        parts.append(
            f'<joint name="{joint}" type="revolute"><parent link="{links[k]}"/><child link="{links[k + 1]}"/>'
            f'<origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="0 0 1"/>'
            '<limit lower="-6.283" upper="6.283" effort="150" velocity="3.15"/></joint>'
        )
    parts.append(  # as ur.ros2_control.xacro writes the YAML's hash
        '<ros2_control name="ur" type="system"><hardware><plugin>ur_robot_driver/URPositionHardwareInterface'
        f'</plugin><param name="kinematics/hash">{URDF_HASH}</param></hardware></ros2_control>'
    )
    return "\n".join([*parts, "</robot>"]) + "\n"


def _predicts(yaml_file: Path, side: Path, test: pincal.Dataset) -> float:
    """RMS [m] of held-out measurements against the YAML's chain (ur_description's
    construction) with the sidecar's registration and tool."""
    spec = json.loads(side.read_text())
    reg, tool = np.array(spec["instrument_T_base"]["matrix"]), np.array(spec["tip_T_tool"]["matrix"])
    predicted = np.array([(reg @ ur_description_tool0(yaml_file, q) @ tool)[:3, 3] for q in test.q])
    return float(np.sqrt(np.mean(np.sum((predicted - test.points) ** 2, axis=1))))


@pytest.mark.parametrize("given", ["factory", "none"])
def test_cli_writes_the_yaml(
    capsys: pytest.CaptureFixture[str], files: dict[str, Path], tmp_path: Path, given: str
) -> None:
    """`calibrate ur5 DATA [--kinematics factory.yaml] -o robot_calibration.yaml`: the YAML, applied
    as ur_description does, with the sidecar's registration and tool, predicts held-out
    measurements to the noise; it keeps the source's hash (or makes one for the bundled default)."""
    source = files["factory"] if given == "factory" else files["ur5"]
    robot = pincal.load_robot("ur5", kinematics=source)
    _, fit, test = pincal.simulate(robot, 60, 30, seed=5)
    pincal.write_csv(tmp_path / "fit.csv", fit, units="mm")
    out, report = tmp_path / "robot_calibration.yaml", tmp_path / "report.json"
    kinematics = ["--kinematics", source] if given == "factory" else []
    code, text, err = run(
        capsys, "calibrate", "ur5", tmp_path / "fit.csv", "--units", "mm", *kinematics, "--params", "all",
        "-o", out, "--report", report,
    )  # fmt: skip
    assert code == 0, err
    assert f"UR kinematics YAML written to {out}" in text
    assert json.loads(report.read_text())["ur_kinematics"] == str(out)
    found = read_ur_kinematics(out).calibration_hash
    assert found == FACTORY_HASH if given == "factory" else str(found).startswith("calib_pincal_")
    assert _predicts(out, out.with_name("robot_calibration.calibration.json"), test) < 1.5e-4


def test_ur_description_urdf_takes_the_yaml_as_is(
    capsys: pytest.CaptureFixture[str], files: dict[str, Path], tmp_path: Path
) -> None:
    """A URDF in ur_description's frames takes the YAML's origins unchanged, and writes a YAML
    without --kinematics, with the hash of its ros2_control tag."""
    urdf = tmp_path / "ur5_description.urdf"
    urdf.write_text(_ur_description_urdf(_default_entries("ur5")))
    assert _max_gap(pincal.load_robot(urdf), files["ur5"]) < 1e-12
    applied = pincal.load_robot(urdf, kinematics=files["factory"])
    assert _max_gap(applied, files["factory"]) < 1e-12
    assert applied.urdf_text.count("base_link_inertia") == urdf.read_text().count("base_link_inertia")
    _, fit, test = pincal.simulate(applied, 50, 30, seed=6)
    pincal.write_csv(tmp_path / "fit.csv", fit)
    code, _, err = run(
        capsys, "calibrate", urdf, tmp_path / "fit.csv", "--params", "all", "-o", tmp_path / "k.yaml"
    )
    assert code == 0, err
    assert _predicts(tmp_path / "k.yaml", tmp_path / "k.calibration.json", test) < 1.5e-4
    assert read_ur_kinematics(tmp_path / "k.yaml").calibration_hash == URDF_HASH


def test_what_cannot_be_a_ur_yaml_is_one_line(
    capsys: pytest.CaptureFixture[str], files: dict[str, Path], tmp_path: Path
) -> None:
    """Another robot, another UR type, a broken YAML, the YAML as its own output, a locked joint."""
    data = tmp_path / "d.csv"
    pincal.write_csv(data, pincal.simulate(pincal.load_robot("ur5"), 30, 1, seed=0)[1])
    assert "UR robot" in one_error_line(capsys, "twists", "panda", "--kinematics", files["ur5"])
    assert "same UR type" in one_error_line(capsys, "twists", "ur10", "--kinematics", files["ur5"])
    broken = tmp_path / "broken.yaml"
    broken.write_text(files["ur5"].read_text().replace("wrist_3:", "wrist_9:"))
    assert "kinematics.wrist_3" in one_error_line(capsys, "twists", "ur5", "--kinematics", broken)
    broken.write_text("kinematics: [1, 2\n")
    assert "cannot read the kinematics YAML" in one_error_line(
        capsys, "twists", "ur5", "--kinematics", broken
    )
    line = one_error_line(
        capsys, "calibrate", "ur5", data, "--kinematics", files["ur5"], "-o", files["ur5"], "--force"
    )
    assert "is the kinematics YAML" in line
    panda = pincal.simulate(pincal.load_robot("panda"), 30, 1, seed=0)[1]
    pincal.write_csv(tmp_path / "p.csv", panda)
    assert "UR robot" in one_error_line(
        capsys, "calibrate", "panda", tmp_path / "p.csv", "-o", tmp_path / "x.yaml"
    )
    line = one_error_line(
        capsys, "calibrate", "ur5", data, "--lock", "wrist_3_joint", "-o", tmp_path / "x.yaml"
    )
    assert "six UR joints" in line
    assert "--add-frame needs" in one_error_line(
        capsys, "calibrate", "ur5", data, "-o", tmp_path / "x.yaml", "--add-frame", "smr"
    )


def test_compensate_takes_the_yaml(
    capsys: pytest.CaptureFixture[str], files: dict[str, Path], tmp_path: Path
) -> None:
    """`compensate ur5 --kinematics factory.yaml robot_calibration.yaml PROGRAM`: the YAML (and its
    sidecar's tool) is the calibrated robot, the factory YAML the program's nominal one; the true
    robot, driven with the compensated commands, puts its tool where the nominal one did for the
    program, within the calibration's held-out error."""
    nominal = pincal.load_robot("ur5", kinematics=files["factory"])
    truth, fit, test = pincal.simulate(nominal, 60, 30, seed=8)
    pincal.write_csv(tmp_path / "fit.csv", fit)
    pincal.write_csv(tmp_path / "test.csv", test)
    out, report = tmp_path / "robot_calibration.yaml", tmp_path / "report.json"
    code, _, err = run(
        capsys, "calibrate", "ur5", tmp_path / "fit.csv", "--kinematics", files["factory"], "--params", "all",
        "--test", tmp_path / "test.csv", "-o", out, "--report", report,
    )  # fmt: skip
    assert code == 0, err
    program = nominal.random_configurations(40, np.random.default_rng(9), 0.1)
    lines = [",".join(nominal.joint_names)] + [",".join(repr(float(v)) for v in q) for q in program]
    (tmp_path / "program.csv").write_text("\n".join(lines) + "\n")
    compensated = tmp_path / "compensated.csv"
    code, text, err = run(
        capsys, "compensate", "ur5", "--kinematics", files["factory"], out, tmp_path / "program.csv",
        "-o", compensated,
    )  # fmt: skip
    assert code == 0, err
    # the whole pose (issue 43): a row at a wrist or elbow singularity may be refused, and says so
    status = [line.rsplit(",", 1)[1] for line in compensated.read_text().splitlines()[1:]]
    ok = np.array([s == "ok" for s in status])
    assert ok.sum() >= 36 and set(status) <= {"ok", "singular"}, text
    assert f"compensated {ok.sum()} of 40 rows (pose task)" in text
    loaded = pincal.load_calibration(out, nominal="ur5")
    assert loaded.robot.urdf_text != nominal.urdf_text  # the calibrated chain, not the factory one
    reg = loaded.instrument_T_base
    assert reg is not None
    commands = pincal.data.program.read_program(compensated, nominal, False, "m")
    targets = np.array([(nominal.frame_placement(q) * loaded.tool).translation for q in program])

    def reached(q: np.ndarray) -> np.ndarray:  # the true tool in the calibration's base frame
        return (truth.target(q)[0] - reg.translation) @ reg.rotation

    error = np.linalg.norm(reached(commands) - targets, axis=1)[ok]
    before = np.linalg.norm(reached(program) - targets, axis=1)
    fitted = json.loads(report.read_text())["test"]["after"]["rms_mm"] * 1e-3  # [m]
    assert np.sqrt(np.mean(before**2)) > 20 * fitted  # the factory YAML is off: there is work to do
    assert np.sqrt(np.mean(error**2)) < fitted  # the held-out RMS holds the measurement noise too
    with pytest.raises(pincal.DataError, match="UR robot it applies to"):
        pincal.load_calibration(out)
