"""Tests of the corrected-URDF export (:mod:`pincal.export.urdf_writer` and ``pincal calibrate -o``).

What is checked:

- round trip: Pinocchio's kinematics of the exported URDF is the identified model, to 1e-9;
- minimal diff: only the ``xyz``/``rpy`` of the chain joints' ``<origin>`` change (plus, with
  ``--add-frame``, one fixed joint and one link); comments, axes and everything else are kept,
  and joint offsets go into ``rpy``, never into ``<calibration>``;
- the file loads in Pinocchio and in yourdfpy (without meshes), and both agree; urdfdom's own
  ``check_urdf`` accepts it (skipped where it is not installed; ``conftest.py`` also runs it on
  every corrected URDF any test writes);
- the command writes byte-identical files when run twice, and a sidecar with the registration;
- the URDF plus its sidecar alone predict held-out measurements at the noise floor;
- ``-o`` naming the input URDF, or a folder that does not exist, is refused and writes nothing.

Every experiment is simulated (:func:`pincal.simulate`) with fixed seeds.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yourdfpy
from lxml import etree

import pincal
from pincal.cli import main
from pincal.export.urdf_writer import write_corrected_urdf
from pincal.robot.robots import bundled_urdf

#: Agreement required between the exported URDF and the identified model [m] and [rad].
TOL = 1e-9
#: 1σ of each simulated position coordinate [m].
NOISE = 0.03e-3
#: The name of the frame added at the calibrated tool (``--add-frame``).
FRAME = "smr"
ROUND_TRIP_ROBOTS = ("ur5", "panda", "z1", "mrres5")
DIFF_ROBOTS = ("ur5", "panda")
_PARSER = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False, remove_comments=False)

GetRobot = Callable[[str], pincal.Robot]
GetCalibration = Callable[[str, str], pincal.Calibration]


@pytest.fixture(scope="module")
def get_calibration(get_robot: GetRobot) -> GetCalibration:
    """``get_calibration(robot, model)``: fitted to ``simulate(robot, 60, 20, seed=0)``, cached."""
    cache: dict[tuple[str, str], pincal.Calibration] = {}

    def get(name: str, model: str) -> pincal.Calibration:
        if (name, model) not in cache:
            robot = get_robot(name)
            _, fit, _ = pincal.simulate(robot, n_fit=60, n_test=20, seed=0)
            cache[name, model] = pincal.calibrate(robot, fit, model)
        return cache[name, model]

    return get


def _rotation_error(a: np.ndarray, b: np.ndarray) -> float:
    """Angle [rad] of the rotation between rotation matrices ``a`` and ``b``."""
    return float(np.linalg.norm(pin.log3(a.T @ b)))


def _nodes(tree: etree._ElementTree) -> list[etree._Element]:
    """Every node of a document in order: top-level comments, then the root's ``iter()``."""
    root = tree.getroot()
    before = list(root.itersiblings(preceding=True))[::-1]
    return [*before, *root.iter(), *root.itersiblings()]


def _vector(text: str | None) -> np.ndarray:
    """Three numbers of a URDF attribute such as ``xyz`` or ``rpy``."""
    assert text is not None
    values = np.array([float(v) for v in text.split()])
    assert values.shape == (3,)
    return values


def _origin(element: etree._Element) -> pin.SE3:
    """SE3 of a URDF ``<origin>`` element (both attributes required)."""
    return pin.SE3(pin.rpy.rpyToMatrix(*_vector(element.get("rpy"))), _vector(element.get("xyz")))


def _chain_origins(tree: etree._ElementTree, robot: pincal.Robot) -> list[etree._Element]:
    """The ``<origin>`` elements of the chain's joints, base to tip."""
    root = tree.getroot()
    out = []
    for name in robot.joint_names:
        (joint,) = root.findall(f"joint[@name='{name}']")
        (origin,) = joint.findall("origin")
        out.append(origin)
    return out


def _is_chain_origin(element: etree._Element, robot: pincal.Robot) -> bool:
    """Whether ``element`` is the ``<origin>`` of one of the chain's (top-level) joints."""
    joint = element.getparent()
    return (
        element.tag == "origin"
        and joint is not None
        and joint.tag == "joint"
        and joint.get("name") in robot.joint_names
        and joint.getparent() is element.getroottree().getroot()
    )


def _full_configuration(model: pin.Model, values: dict[str, float]) -> np.ndarray:
    """Configuration of an unreduced Pinocchio model: named joints set, the others neutral."""
    q = pin.neutral(model)
    for name, value in values.items():
        joint = model.joints[model.getJointId(name)]
        if joint.nq == 2:
            q[joint.idx_q : joint.idx_q + 2] = (np.cos(value), np.sin(value))
        else:
            q[joint.idx_q] = value
    return q


def _snapshot(folder: Path) -> dict[str, bytes | None]:
    """Every path under ``folder`` with its bytes (None for folders and links)."""
    return {
        str(p.relative_to(folder)): (p.read_bytes() if p.is_file() and not p.is_symlink() else None)
        for p in sorted(folder.rglob("*"))
    }


def _run(capsys: pytest.CaptureFixture[str], *args: str | Path) -> tuple[int, str, str]:
    """Run ``pincal ARGS`` in-process: exit code, stdout, stderr."""
    capsys.readouterr()
    code = main([str(a) for a in args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _assert_one_error_line(err: str) -> None:
    """stderr is exactly one ``pincal: error:`` line."""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("pincal: error:"), err


# 1. Round trip ------------------------------------------------------------------------------------


@pytest.mark.parametrize("model", pincal.MODELS)
@pytest.mark.parametrize("name", ROUND_TRIP_ROBOTS)
def test_round_trip_matches_identified_model(
    get_robot: GetRobot, get_calibration: GetCalibration, tmp_path: Path, name: str, model: str
) -> None:
    """Pinocchio's FK of the exported URDF is the identified model's tip, at 1,000 configurations.

    Args:
        get_robot: the session robot cache.
        get_calibration: the module calibration cache.
        tmp_path: a fresh folder.
        name: the bundled robot.
        model: the calibration model.
    """
    robot = get_robot(name)
    cal = get_calibration(name, model)
    path = tmp_path / "out.urdf"
    write_corrected_urdf(cal, path)
    exported = pincal.load_robot(str(path), tip=robot.tip)
    assert exported.joint_names == robot.joint_names

    q = robot.random_configurations(1000, np.random.default_rng(20240601))
    rotations, positions = cal.base_T_tip(q)
    pos_err = np.empty(len(q))
    rot_err = np.empty(len(q))
    moved = np.empty(len(q))  # how far the calibration moved the tip from the nominal URDF
    for i, qi in enumerate(q):
        placement = exported.frame_placement(qi)
        pos_err[i] = np.linalg.norm(placement.translation - positions[i])
        rot_err[i] = _rotation_error(placement.rotation, rotations[i])
        moved[i] = np.linalg.norm(robot.frame_placement(qi).translation - positions[i])
    assert moved.max() > 1e-5, "the calibration did not change the kinematics: nothing is tested"
    assert pos_err.max() <= TOL, f"position error {pos_err.max():.3e} m"
    assert rot_err.max() <= TOL, f"rotation error {rot_err.max():.3e} rad"


# 2. Minimal diff ----------------------------------------------------------------------------------


def _take_added_frame(tree: etree._ElementTree, tip: str) -> None:
    """Check the ``--add-frame`` joint and link, then remove them from ``tree``."""
    root = tree.getroot()
    joints = [j for j in root.iter("joint") if j.get("name") == f"{FRAME}_joint"]
    links = [link for link in root.iter("link") if link.get("name") == FRAME]
    assert len(joints) == 1 and len(links) == 1
    joint, link = joints[0], links[0]
    assert joint.getparent() is root and link.getparent() is root
    assert dict(joint.attrib) == {"name": f"{FRAME}_joint", "type": "fixed"}
    assert [child.tag for child in joint] == ["parent", "child", "origin"]
    assert dict(joint.find("parent").attrib) == {"link": tip}
    assert dict(joint.find("child").attrib) == {"link": FRAME}
    origin = joint.find("origin")
    assert set(origin.attrib) == {"xyz", "rpy"}
    _origin(origin)  # parses
    assert len(origin) == 0
    assert dict(link.attrib) == {"name": FRAME} and len(link) == 0 and not (link.text or "").strip()
    root.remove(joint)
    root.remove(link)


@pytest.mark.parametrize("add_frame", [None, FRAME])
@pytest.mark.parametrize("model", pincal.MODELS)
@pytest.mark.parametrize("name", DIFF_ROBOTS)
def test_only_chain_origins_change(
    get_robot: GetRobot,
    get_calibration: GetCalibration,
    tmp_path: Path,
    name: str,
    model: str,
    add_frame: str | None,
) -> None:
    """Input and output documents differ only in the chain joints' origin ``xyz``/``rpy``.

    Both trees are walked in parallel (top-level comments, then ``iter()`` with comments): same
    tags in the same order, same text, same attributes except ``xyz``/``rpy`` of the chain
    joints' ``<origin>``. With ``add_frame`` the only extra nodes are the frame's fixed joint
    (parent: the tip link) and its empty link.

    Args:
        get_robot: the session robot cache.
        get_calibration: the module calibration cache.
        tmp_path: a fresh folder.
        name: the bundled robot.
        model: the calibration model.
        add_frame: the ``--add-frame`` name, or None.
    """
    robot = get_robot(name)
    cal = get_calibration(name, model)
    path = tmp_path / "out.urdf"
    write_corrected_urdf(cal, path, add_frame=add_frame)
    before = etree.parse(str(robot.urdf_path), _PARSER)
    after = etree.parse(str(path), _PARSER)
    if add_frame is not None:
        _take_added_frame(after, robot.tip)

    chain_in = _chain_origins(before, robot)
    chain_out = _chain_origins(after, robot)
    nodes_in, nodes_out = _nodes(before), _nodes(after)
    assert len(nodes_in) == len(nodes_out)
    n_comments = n_chain = 0
    for a, b in zip(nodes_in, nodes_out):
        assert a.tag == b.tag, (a.tag, b.tag, a.sourceline)
        assert a.text == b.text, (a.tag, a.sourceline)
        if add_frame is None:
            assert a.tail == b.tail, (a.tag, a.sourceline)
        else:  # the element before the added frame is re-indented: whitespace only
            assert (a.tail or "").strip() == (b.tail or "").strip(), (a.tag, a.sourceline)
        n_comments += a.tag is etree.Comment
        if _is_chain_origin(b, robot):
            n_chain += 1
            kept_in = [(k, v) for k, v in a.attrib.items() if k not in ("xyz", "rpy")]
            kept_out = [(k, v) for k, v in b.attrib.items() if k not in ("xyz", "rpy")]
            assert kept_in == kept_out
            assert {"xyz", "rpy"} <= set(b.attrib)
        else:
            assert list(a.attrib.items()) == list(b.attrib.items()), (a.tag, a.sourceline)
    assert n_comments > 0, "the input has comments: they must be kept"
    assert n_chain == robot.n_joints

    # Something did change (else nothing is tested).
    changed = [
        not (
            np.array_equal(_vector(a.get("xyz")), _vector(b.get("xyz")))
            and np.array_equal(_vector(a.get("rpy")), _vector(b.get("rpy")))
        )
        for a, b in zip(chain_in, chain_out)
    ]
    assert any(changed)

    # Offsets folded into rpy: no new <calibration>, axes as written.
    n_calibration = len(before.getroot().findall(".//calibration"))
    assert len(after.getroot().findall(".//calibration")) == n_calibration
    joints_in, joints_out = before.getroot().findall("joint"), after.getroot().findall("joint")
    assert [j.get("name") for j in joints_in] == [j.get("name") for j in joints_out]
    for joint_in, joint_out in zip(joints_in, joints_out):
        axis_in, axis_out = joint_in.findall("axis"), joint_out.findall("axis")
        assert [list(a.attrib.items()) for a in axis_in] == [list(a.attrib.items()) for a in axis_out]


@pytest.mark.parametrize("name", DIFF_ROBOTS)
def test_offsets_are_folded_into_origin_rpy(
    get_robot: GetRobot, get_calibration: GetCalibration, tmp_path: Path, name: str
) -> None:
    """With the ``offsets`` model each origin turns about its joint's axis by the offset.

    ``O'_j = O_j · exp(ω_j o_j)``: the ``xyz`` stays, the rotation picks up the offset.

    Args:
        get_robot: the session robot cache.
        get_calibration: the module calibration cache.
        tmp_path: a fresh folder.
        name: the bundled robot.
    """
    robot = get_robot(name)
    cal = get_calibration(name, "offsets")
    offsets = cal.x
    assert np.abs(offsets).max() > 1e-5
    path = tmp_path / "out.urdf"
    write_corrected_urdf(cal, path)
    before = etree.parse(str(robot.urdf_path), _PARSER)
    after = etree.parse(str(path), _PARSER)
    for j, (a, b) in enumerate(zip(_chain_origins(before, robot), _chain_origins(after, robot))):
        nominal, exported = _origin(a), _origin(b)
        expected = nominal.rotation @ pin.exp3(robot.axes[j, 3:] * offsets[j])
        assert np.abs(exported.translation - nominal.translation).max() <= 1e-12
        assert _rotation_error(exported.rotation, expected) <= 1e-12


# 3. Pinocchio and yourdfpy ------------------------------------------------------------------------


@pytest.mark.parametrize("model", ["placements", "mdh"])
@pytest.mark.parametrize("name", ROUND_TRIP_ROBOTS)
def test_loads_in_pinocchio_and_yourdfpy(
    get_robot: GetRobot, get_calibration: GetCalibration, tmp_path: Path, name: str, model: str
) -> None:
    """The exported file (with ``--add-frame``) loads in both, and their FK agree to 1e-9.

    Args:
        get_robot: the session robot cache.
        get_calibration: the module calibration cache.
        tmp_path: a fresh folder.
        name: the bundled robot.
        model: the calibration model.
    """
    robot = get_robot(name)
    cal = get_calibration(name, model)
    path = tmp_path / "out.urdf"
    write_corrected_urdf(cal, path, add_frame=FRAME)
    model_pin = pin.buildModelFromUrdf(str(path))
    data_pin = model_pin.createData()
    urdf = yourdfpy.URDF.load(str(path), load_meshes=False, build_scene_graph=True)
    assert set(robot.joint_names) <= set(urdf.actuated_joint_names)
    frames = {f: model_pin.getFrameId(f) for f in (robot.tip, FRAME)}
    assert all(i < len(model_pin.frames) for i in frames.values())

    rng = np.random.default_rng(7)
    for q in robot.random_configurations(5, rng):
        values = {j: float(v) for j, v in zip(robot.joint_names, q)}
        pin.framesForwardKinematics(model_pin, data_pin, _full_configuration(model_pin, values))
        urdf.update_cfg(values)
        for frame, frame_id in frames.items():
            expected = data_pin.oMf[frame_id]
            got = urdf.get_transform(frame, urdf.base_link)
            assert np.abs(got[:3, 3] - expected.translation).max() <= TOL, frame
            assert _rotation_error(got[:3, :3], expected.rotation) <= TOL, frame
        # and the reduced chain of pincal agrees with the full model
        tip = pincal.load_robot(str(path), tip=robot.tip).frame_placement(q)
        assert np.abs(tip.translation - data_pin.oMf[frames[robot.tip]].translation).max() <= TOL


# 4. Deterministic output of the command -----------------------------------------------------------


def test_cli_output_is_byte_identical(
    get_robot: GetRobot, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``pincal calibrate ur5 data.csv -o FILE`` twice (``--force``) writes the same bytes, with a sidecar.

    Args:
        get_robot: the session robot cache.
        tmp_path: a fresh folder.
        capsys: the captured output.
    """
    _, fit, _ = pincal.simulate(get_robot("ur5"), n_fit=60, n_test=20, seed=0)
    data = tmp_path / "data.csv"
    pincal.write_csv(data, fit)

    outputs = {}
    for stem in ("out1", "out2", "out", "out"):
        target = tmp_path / f"{stem}.urdf"
        sidecar = tmp_path / f"{stem}.calibration.json"
        previous = (target.read_bytes(), sidecar.read_bytes()) if target.exists() else None
        if previous is not None:  # an existing output is replaced only with --force
            code, _, err = _run(capsys, "calibrate", "ur5", data, "-o", target)
            assert code == 2 and "--force" in err
            assert (target.read_bytes(), sidecar.read_bytes()) == previous
        force = ["--force"] if previous is not None else []
        code, out, err = _run(capsys, "calibrate", "ur5", data, "-o", target, *force)
        assert code == 0, err
        assert err == ""
        assert "corrected URDF written to" in out
        current = (target.read_bytes(), sidecar.read_bytes())
        if previous is not None:  # the same path, written again
            assert current == previous
        outputs[stem] = current

    assert outputs["out1"][0] == outputs["out2"][0] == outputs["out"][0]
    sidecars = {stem: json.loads(side) for stem, (_, side) in outputs.items()}
    for stem, side in sidecars.items():
        assert side["urdf"] == f"{stem}.urdf"
        assert np.asarray(side["instrument_T_base"]["matrix"]).shape == (4, 4)
        assert np.asarray(side["tip_T_tool"]["matrix"]).shape == (4, 4)
    assert {k: v for k, v in sidecars["out1"].items() if k != "urdf"} == {
        k: v for k, v in sidecars["out2"].items() if k != "urdf"
    }
    # atomic writes leave no temporary files behind
    written = {f"{s}.urdf" for s in outputs} | {f"{s}.calibration.json" for s in outputs}
    assert {p.name for p in tmp_path.iterdir()} == {"data.csv"} | written


# 5. The files alone predict held-out measurements -------------------------------------------------


@pytest.mark.parametrize("model", ["placements", "poe", "mdh"])
@pytest.mark.parametrize("name", DIFF_ROBOTS)
def test_files_predict_held_out_points(get_robot: GetRobot, tmp_path: Path, name: str, model: str) -> None:
    """URDF (with ``--add-frame``) and sidecar registration predict test points at the noise floor.

    Only the files are used for the prediction: the chain to the added frame from the URDF,
    ``instrument_T_base`` from the sidecar.

    Args:
        get_robot: the session robot cache.
        tmp_path: a fresh folder.
        name: the bundled robot.
        model: the calibration model.
    """
    robot = get_robot(name)
    _, fit, test = pincal.simulate(robot, 60, 100, seed=0, noise=NOISE)
    cal = pincal.calibrate(robot, fit, model)
    path, side = write_corrected_urdf(cal, tmp_path / "out.urdf", add_frame=FRAME)
    del cal  # from here on, only the files

    sidecar = json.loads(side.read_text(encoding="utf-8"))
    assert sidecar["tip"] == robot.tip and sidecar["model"] == model
    registration = pin.SE3(np.asarray(sidecar["instrument_T_base"]["matrix"], dtype=float))
    exported = pincal.load_robot(str(path), tip=FRAME)
    assert exported.joint_names == test.joint_names
    (joint,) = etree.parse(str(path), _PARSER).getroot().findall(f"joint[@name='{FRAME}_joint']")
    assert np.array_equal(_vector(joint.find("origin").get("rpy")), np.zeros(3))  # position data

    predicted = np.array([registration.act(exported.frame_placement(q).translation) for q in test.q])
    rms = float(np.sqrt(np.mean(np.sum((predicted - test.points) ** 2, axis=1))))
    assert rms <= 1.2 * NOISE * np.sqrt(3), f"held-out RMS {rms * 1e3:.4f} mm"


# 6. Refusals --------------------------------------------------------------------------------------


@pytest.fixture()
def mrres5_copy(get_robot: GetRobot, tmp_path: Path) -> tuple[Path, Path]:
    """A copy of the bundled MRRES5 URDF in ``tmp_path/robot`` and a measurement CSV for it."""
    folder = tmp_path / "robot"
    folder.mkdir()
    urdf = folder / "mrres5.urdf"
    shutil.copyfile(bundled_urdf("mrres5"), urdf)
    _, fit, _ = pincal.simulate(get_robot("mrres5"), n_fit=40, n_test=1, seed=0)
    data = tmp_path / "data.csv"
    pincal.write_csv(data, fit)
    return urdf, data


def _same_file_spelling(urdf: Path, spelling: str) -> str:
    """The path of ``urdf`` spelled as ``same``, ``dotdot`` or ``relative`` (to its grandparent)."""
    return {
        "same": str(urdf),
        "dotdot": str(urdf.parent / ".." / urdf.parent.name / urdf.name),
        "relative": str(Path(urdf.parent.name) / urdf.name),
    }[spelling]


@pytest.mark.parametrize("spelling", ["same", "dotdot", "relative", "symlink"])
def test_cli_refuses_output_that_is_the_input(
    mrres5_copy: tuple[Path, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    spelling: str,
) -> None:
    """``-o`` naming the input URDF (however spelled): exit 2, one error line, input untouched.

    Args:
        mrres5_copy: the URDF copy and its data.
        tmp_path: the folder holding both.
        capsys: the captured output.
        monkeypatch: to run in ``tmp_path``.
        spelling: how ``-o`` names the input.
    """
    urdf, data = mrres5_copy
    monkeypatch.chdir(tmp_path)
    if spelling == "symlink":
        output = str(tmp_path / "link.urdf")
        Path(output).symlink_to(urdf)
    else:
        output = _same_file_spelling(urdf, spelling)
    original = urdf.read_bytes()
    snapshot = _snapshot(tmp_path)

    code, _, err = _run(capsys, "calibrate", urdf, data, "-o", output)
    assert code == 2
    _assert_one_error_line(err)
    assert urdf.read_bytes() == original
    assert _snapshot(tmp_path) == snapshot


def test_api_refuses_output_that_is_the_input(mrres5_copy: tuple[Path, Path]) -> None:
    """``write_corrected_urdf`` to the robot's own URDF raises DataError and writes nothing.

    Args:
        mrres5_copy: the URDF copy and its data.
    """
    urdf, data = mrres5_copy
    robot = pincal.load_robot(str(urdf))
    cal = pincal.calibrate(robot, pincal.read_csv(data, robot.joint_names), "placements")
    original = urdf.read_bytes()
    snapshot = _snapshot(urdf.parent)
    with pytest.raises(pincal.DataError):
        write_corrected_urdf(cal, urdf)
    assert urdf.read_bytes() == original
    assert _snapshot(urdf.parent) == snapshot


def test_cli_refuses_missing_output_folder(
    mrres5_copy: tuple[Path, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``-o`` in a folder that does not exist: exit 2, one error line, nothing written anywhere.

    A ``--report`` is asked for too: the refusal comes before anything is written.

    Args:
        mrres5_copy: the URDF copy and its data.
        tmp_path: the folder holding both (and the working directory).
        capsys: the captured output.
        monkeypatch: to run in ``tmp_path``.
    """
    urdf, data = mrres5_copy
    monkeypatch.chdir(tmp_path)
    snapshot = _snapshot(tmp_path)
    output = tmp_path / "missing" / "out.urdf"
    args = ("-o", output, "--add-frame", FRAME, "--report", "report.json")
    code, _, err = _run(capsys, "calibrate", urdf, data, *args)
    assert code == 2
    _assert_one_error_line(err)
    assert not output.parent.exists()
    assert _snapshot(tmp_path) == snapshot


# 7. Pose data: the added frame carries the tool orientation ---------------------------------------


@pytest.mark.parametrize("model", ["placements", "poe", "mdh"])
@pytest.mark.parametrize("name", DIFF_ROBOTS)
def test_added_frame_carries_tool_orientation(
    get_robot: GetRobot, tmp_path: Path, name: str, model: str
) -> None:
    """With pose data, URDF frame and sidecar registration reproduce the model's predictions.

    Args:
        get_robot: the session robot cache.
        tmp_path: a fresh folder.
        name: the bundled robot.
        model: the calibration model.
    """
    robot = get_robot(name)
    _, fit, test = pincal.simulate(robot, 60, 20, seed=0, rot_noise=1e-4)
    cal = pincal.calibrate(robot, fit, model)
    assert cal.measurement.kind == "pose"
    positions, rotations = cal.problem(test).predict(cal.theta)
    path, side = write_corrected_urdf(cal, tmp_path / "out.urdf", add_frame=FRAME)

    (joint,) = etree.parse(str(path), _PARSER).getroot().findall(f"joint[@name='{FRAME}_joint']")
    assert np.linalg.norm(_vector(joint.find("origin").get("rpy"))) > 1e-3  # not the identity
    sidecar = json.loads(side.read_text(encoding="utf-8"))
    registration = pin.SE3(np.asarray(sidecar["instrument_T_base"]["matrix"], dtype=float))
    exported = pincal.load_robot(str(path), tip=FRAME)
    for q, position, rotation in zip(test.q, positions, rotations):
        placement = registration * exported.frame_placement(q)
        assert np.abs(placement.translation - position).max() <= TOL
        assert _rotation_error(placement.rotation, rotation) <= TOL


# 8. urdfdom's own parser --------------------------------------------------------------------------


@pytest.mark.parametrize("model", pincal.MODELS)
@pytest.mark.parametrize("name", (*ROUND_TRIP_ROBOTS, "zu3"))
def test_check_urdf_accepts_corrected_urdf(
    check_urdf: Callable[[bytes | Path], None],
    get_calibration: GetCalibration,
    tmp_path: Path,
    name: str,
    model: str,
) -> None:
    """``check_urdf`` (urdfdom, as ROS tools parse URDFs) accepts the file, with ``--add-frame``.

    Args:
        check_urdf: asserts that urdfdom accepts a URDF (skips when it is not installed).
        get_calibration: the module calibration cache.
        tmp_path: a fresh folder.
        name: the bundled robot.
        model: the calibration model.
    """
    path, _ = write_corrected_urdf(get_calibration(name, model), tmp_path / "out.urdf", add_frame=FRAME)
    check_urdf(path)


def test_check_urdf_rejects_what_urdfdom_cannot_parse(check_urdf: Callable[[bytes | Path], None]) -> None:
    """The check is not vacuous: a revolute joint without ``<limit>`` is refused by urdfdom.

    Args:
        check_urdf: asserts that urdfdom accepts a URDF (skips when it is not installed).
    """
    text = (
        b'<robot name="r"><link name="a"/><link name="b"/><joint name="j" type="revolute">'
        b'<parent link="a"/><child link="b"/></joint></robot>'
    )
    with pytest.raises(AssertionError, match="check_urdf"):
        check_urdf(text)


# 6. The document's head, however it is spelled ----------------------------------------------------

#: Heads of a URDF document before the robot's first child: each must come back as written.
HEADS = {
    "start tag over two lines": (
        b'<?xml version="1.0"?>\n<robot\n  xmlns:xacro="http://ros.org/wiki/xacro" name="ur5">'
    ),
    "attributes one per line": b'<robot\n  name="ur5"\n  xmlns:xacro="http://ros.org/wiki/xacro"\n>',
    "comment naming <robot>": b'<!-- a <robot> of ours -->\n<!-- two\nlines -->\n<robot name="ur5">',
    "doctype": b'<?xml version="1.0"?>\n<!DOCTYPE robot>\n<robot name="ur5">',
    "byte-order mark": b'\xef\xbb\xbf<?xml version="1.0" encoding="UTF-8"?>\n<robot name="ur5">',
    "no declaration": b'<robot name="ur5">',
}


@pytest.mark.parametrize("head", HEADS)
def test_document_head_kept_and_loadable(
    check_urdf: Callable[[bytes | Path], None], tmp_path: Path, head: str
) -> None:
    """A URDF whose root start tag spans lines, or with comments, a doctype or a byte-order mark
    before it, exports to a file that loads and is the identified model, its head as written.

    Args:
        check_urdf: asserts that urdfdom accepts a URDF (skips when it is not installed).
        tmp_path: a fresh folder.
        head: the name of the head in :data:`HEADS`.
    """
    text = Path(bundled_urdf("ur5")).read_bytes()
    start = text.index(b"<robot ")
    body = text[text.index(b">", start) + 1 :]
    source = tmp_path / "in.urdf"
    source.write_bytes(HEADS[head] + body)
    robot = pincal.load_robot(str(source), tip="tool0")
    _, fit, _ = pincal.simulate(robot, n_fit=40, n_test=0, seed=3)
    cal = pincal.calibrate(robot, fit, "placements")
    path, _ = write_corrected_urdf(cal, tmp_path / "out.urdf")
    written = path.read_bytes()
    before_root = HEADS[head][: HEADS[head].rindex(b"<robot")]
    assert written.startswith(before_root or b"<?xml")
    assert written.count(b"<robot") == 1 + before_root.count(b"<robot")
    check_urdf(path)
    exported = pincal.load_robot(str(path), tip="tool0")
    q = robot.random_configurations(50, np.random.default_rng(5))
    _, positions = cal.base_T_tip(q)
    got = np.array([exported.frame_placement(qi).translation for qi in q])
    assert np.abs(got - positions).max() <= TOL
    assert np.abs(got - np.array([robot.frame_placement(qi).translation for qi in q])).max() > 1e-5
