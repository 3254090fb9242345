"""Data measured past the tip: the data's columns name joints of the URDF that come after
``--tip`` and move, and the nominal robot with a tip after them fits the measured points many
times better than with ``--tip`` (a registration-only fit each, as the plausibility verdict's
other readings). Such a calibration is a silent wrong answer: the tool fitted on the tip takes
the motion of the joints after it as noise, which can stay below the verdict's limits.

The check runs only when such columns exist: joint columns logged past the tip that do not
explain the data (a gripper's fingers) are kept and ignored, as before.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pincal.data.dataset import Dataset, csv_columns, read_csv
from pincal.errors import DataError, PincalError
from pincal.identify.evaluation import evaluate
from pincal.identify.solver import register, set_up
from pincal.options import ROTATION_WEIGHT
from pincal.plausibility.readings import IMPROVEMENT, WITHIN
from pincal.plausibility.verdict import robot_size, score_mm
from pincal.robot.robots import Robot, load_robot


def joints_after(urdf_text: str, tip: str) -> list[tuple[str, str]]:
    """The movable joints after the link (or joint) ``tip``, each with its path from the tip:
    ``(joint, child link)`` in the order of a walk from the tip, parents before children."""
    root = ET.fromstring(urdf_text)
    children: dict[str, list[tuple[str, str, str]]] = {}
    for joint in root.iter("joint"):
        parent_element, child_element = joint.find("parent"), joint.find("child")
        if parent_element is None or child_element is None:
            continue
        entry = (joint.get("name", ""), child_element.get("link", ""), joint.get("type", ""))
        children.setdefault(parent_element.get("link", ""), []).append(entry)
    start = next((c for entries in children.values() for j, c, _ in entries if j == tip), tip)
    found: list[tuple[str, str]] = []
    todo = [start]
    while todo:
        link = todo.pop(0)
        for name, child, kind in children.get(link, []):
            if kind in ("revolute", "continuous", "prismatic"):
                found.append((name, child))
            todo.append(child)
    return found


@dataclass(frozen=True)
class Reading:
    """How a measurement CSV was read: what :func:`check_past_tip` reads it again with.

    Attributes:
        measure: the measurement kind asked for (None: by the columns).
        degrees: revolute joints in degrees.
        units: ``m`` or ``mm`` for lengths.
        rotation_weight: weight of orientation residuals [m/rad] (pose data).
        robot_options: :func:`pincal.load_robot`'s keyword arguments for the robot file.
    """

    measure: str | None = None
    degrees: bool = False
    units: str = "m"
    rotation_weight: float = ROTATION_WEIGHT
    robot_options: dict[str, Any] = field(default_factory=dict)


def check_past_tip(robot: Robot, data: Dataset, path: Path, reading: Reading = Reading()) -> None:
    """Refuse data measured after joints past ``robot.tip`` (see the module docstring).

    Args:
        robot: the chain to the tip; data: its dataset read from ``path``.
        reading: how the file was read.

    Raises:
        DataError: columns past the tip move and a tip after them fits the data far better.
    """
    if data.labels is not None or reading.measure not in (None, "position", "pose"):
        return
    header = set(csv_columns(path))
    past = [(j, link) for j, link in joints_after(robot.urdf_text, robot.tip) if j in header]
    if not past:
        return
    tip = past[-1][1]  # the deepest: after every column past the tip when they are on one path
    try:
        deeper = load_robot(robot.name, tip=tip, **reading.robot_options)
        if not {j for j, _ in past} <= set(deeper.joint_names):
            return  # on branches: no one frame comes after all of them
        joints = [*robot.joint_names, *(j for j, _ in past)]
        deeper = load_robot(robot.name, tip=tip, joints=joints, **reading.robot_options)
        extra = read_csv(
            path,
            deeper.joint_names,
            degrees=reading.degrees,
            units=reading.units,
            prismatic=deeper.prismatic,
            measure=reading.measure,
        )
        moved = np.ptp(extra.q[:, robot.n_joints :], axis=0)
        if not np.any(moved > 1e-9):
            return
        here, there = _nominal_mm(robot, data, reading), _nominal_mm(deeper, extra, reading)
    except (PincalError, np.linalg.LinAlgError, ValueError):
        return
    if here >= IMPROVEMENT * there and there * 1e-3 <= WITHIN * robot_size(deeper):
        names = ", ".join(j for j, _ in past)
        raise DataError(
            f"{path}: the column(s) {names} are joints after the tip {robot.tip} and move: the data "
            f"looks measured after them (the nominal robot fits it within {there:.3g} mm with tip="
            f"{tip}, {here:.3g} mm with tip={robot.tip}): pass tip={tip} (or a frame after it)"
        )


def _nominal_mm(robot: Robot, data: Dataset, reading: Reading) -> float:
    """The nominal robot's error [mm] on the data, registration and tool fitted."""
    weight = reading.rotation_weight
    setup = set_up(robot, data, "placements", reading.measure, rotation_weight=weight)
    theta = register(setup)
    return score_mm(evaluate(setup.model, setup.problem.measurement, theta, data), weight)
