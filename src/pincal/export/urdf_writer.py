"""The corrected URDF: the identified geometry written back as joint origins, nothing else.

Every model's calibrated chain (see :mod:`pincal.kinematics.chain`) is brought to the URDF's own
joint frames and axes, then each chain joint's ``<origin>`` is solved for:

1. ``X_j``: the constant transform from the model's frame of joint ``j`` to the URDF's, taken
   at the nominal geometry (identity for ``placements``, ``offsets`` and ``poe``; for ``mdh`` a
   rotation taking z to the URDF axis and a shift along the axis). Then
   ``C̃_j = X_{j-1}⁻¹ · C_j · X_j`` is the same chain with the URDF's joint axes, exactly.
2. The tip's placement on the last link is the URDF's; whatever the model moved there must be a
   rotation about or a shift along the last joint's axis (an ``mdh`` ``d``), which commutes with
   that joint and moves into its origin.
3. ``C̃_j = K_j · O'_j``, where ``K_j`` is what stands between the previous chain joint and this
   joint's ``<origin>`` (fixed and locked joints, unchanged): ``O'_j = K_j⁻¹ · C̃_j``.

Joint offsets are folded into ``<origin rpy>``, never into ``<calibration>``; axes stay as written.
For fixed-point data the tip is the ball the sockets held: its calibrated centre moves the origin
of the fixed joint that carries the tip link (MUKCa's ``ball_joint``), and the sidecar's tool is
then the identity.
The instrument registration and the tool go to a JSON sidecar next to the URDF. An origin's
numbers are written near the input's text (:mod:`pincal.export.origins`: the rpy triple nearest
the input's, no digits below 1e-12 m or rad); the sidecar's with ``repr`` (shortest
round-trip). The XML is parsed with entity resolution, DTD loading and network access off.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from lxml import etree

from pincal.errors import DataError, ImplausibleError, PincalError
from pincal.export.added_frame import add_tool_frame, check_frame_name
from pincal.export.effects_json import effects_json
from pincal.export.origins import OriginChange, origin_change, read_origin, write_origin
from pincal.files import atomic_write_many
from pincal.identify.calibration import Calibration
from pincal.identify.validity import region_dict
from pincal.json_text import json_text
from pincal.kinematics.chain import Chain, forward
from pincal.robot.robots import Robot

_PARSER = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False, remove_comments=False)


def origin_changes(cal: Calibration) -> list[OriginChange]:
    """How each joint origin the corrected URDF rewrites moved and turned, as written (the chain's
    joints, and for fixed-point data the joint that carries the ball)."""
    before = {j.get("name"): j for j in _read(cal.robot).findall("joint")}
    after = {j.get("name"): j for j in etree.fromstring(corrected_urdf(cal), _PARSER).findall("joint")}
    ball = _ball_joint(_read(cal.robot), cal)
    names = [*cal.robot.joint_names, *([ball.get("name")] if ball is not None else [])]
    return [
        origin_change(name, read_origin(before[name].find("origin")), read_origin(after[name].find("origin")))
        for name in names
    ]


def _frames_at_zero(chain: Chain) -> list[pin.SE3]:
    n = chain.axes.shape[0]
    frames = forward(chain, np.zeros((1, n)))
    return [pin.SE3(frames.rotations[2 * j, 0], frames.translations[2 * j, 0]) for j in range(n)]


def urdf_chain(cal: Calibration) -> list[pin.SE3]:
    """The calibrated chain's placements ``C̃_0 … C̃_{n-1}`` in the URDF's joint frames and axes.

    The tip placement ``C̃_n`` is the URDF's own. Raises PincalError (a bug) if the model moved
    the tip in a way no joint origin can hold.
    """
    robot = cal.robot
    n = robot.n_joints
    model_zero = _frames_at_zero(cal.model.chain(np.zeros(cal.model.n_params)))
    urdf_zero = _frames_at_zero(Chain.nominal(robot))
    x = [m.actInv(u) for m, u in zip(model_zero, urdf_zero)]
    placements = cal.chain().placements
    out = [placements[0] * x[0]]
    out += [x[j - 1].actInv(placements[j] * x[j]) for j in range(1, n)]
    tip = x[n - 1].actInv(placements[n])
    delta = pin.log6(tip * robot.placements[n].inverse()).vector
    axis = robot.axes[n - 1, 3:] if np.any(robot.axes[n - 1, 3:]) else robot.axes[n - 1, :3]
    off_axis = max(np.linalg.norm(np.cross(delta[:3], axis)), np.linalg.norm(np.cross(delta[3:], axis)))
    if off_axis > 1e-9:
        raise PincalError(f"internal: the {cal.model.kind} model moved the tip off the last joint's axis")
    out[n - 1] = out[n - 1] * pin.exp6(pin.Motion(delta))
    return out


def robot_source(robot: Robot) -> bytes:
    """The URDF the robot was built from (a xacro's output, a kinematics YAML applied, the masses
    lent by ``inertias`` written in)."""
    text = robot.lent_text or robot.urdf_text
    return text.encode("utf-8") if text else Path(robot.urdf_path).read_bytes()


def _read(robot: Robot) -> Any:
    """The robot's URDF as an XML element."""
    try:
        return etree.fromstring(robot_source(robot), _PARSER)
    except (OSError, etree.XMLSyntaxError) as exc:
        raise DataError(f"cannot parse URDF {robot.urdf_path}: {exc}") from None


def corrected_origins(cal: Calibration, root: etree._Element | None = None) -> dict[str, pin.SE3]:
    """Each chain joint's corrected ``<origin>`` (in its parent link's frame), by joint name."""
    joints = {j.get("name"): j for j in (_read(cal.robot) if root is None else root).findall("joint")}
    out = {}
    for name, c_tilde, c_nominal in zip(cal.robot.joint_names, urdf_chain(cal), cal.robot.placements):
        between = c_nominal * read_origin(joints[name].find("origin")).inverse()  # K_j: fixed, locked joints
        out[name] = between.actInv(c_tilde)
    return out


def corrected_urdf(cal: Calibration, add_frame: str | None = None) -> bytes:
    """The corrected URDF document: the geometry of ``cal.written`` (the best URDF alone).

    Args:
        cal: the calibration.
        add_frame: if given, a fixed joint ``<add_frame>_joint`` and link ``<add_frame>`` at the
            calibrated tool (point, and orientation for pose data) on the tip link.
    """
    cal = cal.written
    robot = cal.robot
    root = _read(robot)
    check_frame_name(add_frame)
    joints = {j.get("name"): j for j in root.findall("joint")}
    for name, origin in corrected_origins(cal, root).items():
        write_origin(joints[name], origin)
    ball = _ball_joint(root, cal)
    if ball is not None:
        write_origin(ball, read_origin(ball.find("origin")) * pin.SE3(np.eye(3), cal.split()[2].translation))
    if add_frame is not None:
        tool = cal.split()[2]
        tool = tool if cal.measurement.measure.tool_dof == 6 else pin.SE3(np.eye(3), tool.translation)
        add_tool_frame(root, robot.tip, add_frame, tool, ball is not None)
    return _document_head(robot) + etree.tostring(root, encoding="UTF-8") + b"\n"


def moved_origins(source: bytes, moves: dict[str, pin.SE3]) -> bytes:
    """A URDF document with the ``<origin>`` of each joint of ``moves`` times its transform
    (``origin · M``, as the sidecar's ``complete`` says)."""
    root = etree.fromstring(source, _PARSER)
    joints = {j.get("name"): j for j in root.findall("joint")}
    for name, move in moves.items():
        if name not in joints:
            raise DataError(f"complete names the joint {name!r}, which the URDF does not have")
        write_origin(joints[name], read_origin(joints[name].find("origin")) * move)
    return _prolog(source) + etree.tostring(root, encoding="UTF-8") + b"\n"


def _as_written(origin: pin.SE3, given: etree._Element | None = None) -> pin.SE3:
    """An origin as the URDF's text holds it (its numbers written and read back), written near
    the input's ``<origin>`` ``given`` as the corrected URDF writes it."""
    element = etree.Element("joint")
    if given is not None:
        etree.SubElement(element, "origin", {k: v for k, v in given.attrib.items() if k in ("xyz", "rpy")})
    write_origin(element, origin)
    return read_origin(element.find("origin"))


def complete(cal: Calibration) -> dict[str, Any] | None:
    """The sidecar's ``complete``: what the full model ``cal`` changes beyond the written URDF
    (each chain joint's origin, as written, times a matrix; its own registration and tool), or
    None when the URDF holds the full model's geometry."""
    if cal.urdf_fit is None:
        return None
    root = _read(cal.robot)  # the input URDF, read once: both geometries are corrections of it
    written, full = corrected_origins(cal.written, root), corrected_origins(cal, root)
    given = {j.get("name"): j.find("origin") for j in root.findall("joint")}
    moves = {
        name: _as_written(written[name], given[name]).actInv(full[name]) for name in cal.robot.joint_names
    }
    _, reg, tool = cal.split()
    if cal.measurement.measure.fixed_points and _ball_joint(root, cal) is not None:
        ball = cal.written.split()[2].translation  # the written tip is the URDF alone's ball
        tool = pin.SE3(np.eye(3), tool.translation - ball)
    return {
        "joint_origins": {name: {"matrix": m.homogeneous.tolist()} for name, m in moves.items()},
        "instrument_T_base": {"matrix": reg.homogeneous.tolist()} if cal.measurement.n_instrument else None,
        "tip_T_tool": None if cal.measurement.markers else {"matrix": tool.homogeneous.tolist()},
        "markers": markers_entry(cal),
    }


def _ball_joint(root: etree._Element, cal: Calibration) -> etree._Element | None:
    """For fixed-point data, the fixed joint whose child is the tip link (it takes the ball's
    calibrated centre), else None."""
    if not cal.measurement.measure.fixed_points:
        return None
    for joint in root.findall("joint"):
        child = joint.find("child")
        if joint.get("type") == "fixed" and child is not None and child.get("link") == cal.robot.tip:
            return joint
    return None


_BOM = b"\xef\xbb\xbf"  # a UTF-8 byte-order mark


def _document_head(robot: Robot) -> bytes:
    """The head of the robot's URDF (:func:`_prolog`), with the byte-order mark its file starts
    with: the loader drops it from the text it parses, and the corrected file keeps it."""
    try:
        with open(robot.urdf_path, "rb") as fh:
            bom = fh.read(len(_BOM)) == _BOM
    except OSError:
        bom = False
    return (_BOM if bom else b"") + _prolog(robot_source(robot)).removeprefix(_BOM)


def _prolog(source: bytes) -> bytes:
    """The input's bytes before the root element (declaration, comments, doctype), kept as
    written: everything before the first ``<`` that opens an element (the root's start tag may
    span several lines, with its attributes on the next)."""
    pos = len(_BOM) if source.startswith(_BOM) else 0
    ends = {b"<?": b"?>", b"<!--": b"-->", b"<!": b">"}
    while True:
        while source[pos : pos + 1].isspace():
            pos += 1
        opener = next((o for o in ends if source.startswith(o, pos)), None)
        if opener is None:
            break
        end = source.find(ends[opener], pos + len(opener))
        if end < 0:
            break
        pos = end + len(ends[opener])
    prolog = source[:pos]
    return prolog if prolog.strip() else b'<?xml version="1.0" encoding="UTF-8"?>\n'


def sidecar(cal: Calibration, urdf_name: str) -> dict[str, Any]:
    """What the URDF cannot hold: the instrument registration and the tool of the URDF alone, and
    the full model (``complete``: its own geometry, registration and tool; ``extension``: its
    effects)."""
    full, cal = cal, cal.written
    _, reg, tool = cal.split()
    ball = cal.measurement.measure.fixed_points and _ball_joint(_read(cal.robot), cal) is not None
    if ball:  # the corrected URDF's tip link is the ball's centre
        tool = pin.SE3.Identity()

    def pose(se3: pin.SE3) -> dict[str, Any]:
        return {
            "xyz_m": [float(v) for v in se3.translation],
            "rpy_rad": [float(v) for v in pin.rpy.matrixToRpy(se3.rotation)],
            "matrix": se3.homogeneous.tolist(),
        }

    fitted = cal.measurement.n_instrument > 0
    return {
        "urdf": urdf_name,
        "robot": cal.robot.name,
        "tip": cal.robot.tip,
        "joints": list(cal.robot.joint_names),
        "model": cal.model.kind,
        "measure": cal.measurement.kind,
        "instrument_T_base": pose(reg) if fitted else None,
        "instrument_T_base_note": "identified"
        if fitted
        else "not identified (given, or distance or fixed-point data)",
        "tip_T_tool": None if cal.measurement.markers else pose(tool),
        "markers": markers_entry(cal),
        "extension": effects_json(full.extension, full.effect_params),
        "complete": complete(full),
        "validity_region": None if full.guard is None else region_dict(full.guard.region),
        "tool_note": (
            "the measured point (and target orientation for pose data) on the tip frame. Only what "
            "was measured is calibrated: with point data, frames other than the measured point "
            "(the tip frame's orientation, other tool frames) are not determined by the data"
        ),
    }


def markers_entry(cal: Calibration) -> dict[str, Any] | None:
    """The sidecar's ``markers``: ``{LABEL: {"frame", "point_m"}}`` of several markers, else None."""
    points = cal.markers()
    if not points:
        return None
    frames = marker_frames(cal.robot, tuple(points))
    return {k: {"frame": frames[k], "point_m": [float(v) for v in p]} for k, p in points.items()}


def marker_frames(robot: Robot, labels: tuple[str, ...]) -> dict[str, str]:
    """The frame each marker is on (``tip=1=FRAME_A,2=FRAME_B``; else the tip for every marker)."""
    return {k: robot.marker_frames.get(k, robot.tip) for k in labels}


def sidecar_path(urdf: str | Path) -> Path:
    """Where the sidecar of a corrected URDF lives: ``<stem>.calibration.json`` beside it."""
    urdf = Path(urdf)
    return urdf.with_name(urdf.stem + ".calibration.json")


def check_output(path: Path, robot: Robot) -> None:
    """Refuse an output that is the input URDF or sits in a folder that does not exist."""
    if path.resolve() == Path(robot.urdf_path).resolve():
        raise DataError(f"-o {path} is the input URDF: write the corrected URDF to another file")
    if not path.parent.resolve().is_dir():
        raise DataError(f"the output folder {path.parent} does not exist: create it first")


def write_corrected_urdf(
    cal: Calibration, path: str | Path, add_frame: str | None = None, *, accept_implausible: bool = False
) -> tuple[Path, Path]:
    """Write the corrected URDF and its sidecar ``<stem>.calibration.json``, both or neither.

    Args:
        cal: the calibration (:func:`pincal.calibrate`).
        path: the URDF to write; the sidecar goes beside it.
        add_frame: a frame to add at the calibrated tool point, on the tip link.
        accept_implausible: write a calibration its plausibility verdict refuses.

    Raises:
        DataError: the output is the input URDF, or its folder does not exist.
        ImplausibleError: the calibration cannot describe a real arm (``cal.plausibility``).
    """
    check_plausible(cal, accept_implausible)
    files = corrected_files(cal, path, add_frame)
    atomic_write_many(files)
    return files[0][0], files[1][0]


def check_plausible(cal: Calibration, accept_implausible: bool = False) -> None:
    """Refuse to write a calibration whose plausibility verdict says it cannot be right.

    Raises:
        ImplausibleError: ``cal.plausibility`` failed and not ``accept_implausible``.
    """
    verdict = cal.plausibility
    if verdict is not None and not verdict.plausible and not accept_implausible:
        raise ImplausibleError(verdict.message())


def corrected_files(
    cal: Calibration, path: str | Path, add_frame: str | None = None
) -> list[tuple[Path, str]]:
    """The corrected URDF at ``path`` and its sidecar beside it: [(path, text), (sidecar, text)]."""
    path = Path(path)
    check_output(path, cal.robot)
    text = corrected_urdf(cal, add_frame).decode("utf-8")
    return [(path, text), (sidecar_path(path), json_text(sidecar(cal, path.name)))]
