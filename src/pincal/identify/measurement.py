"""What is measured and what is known about the set-up: :class:`Measurement`, and how its
unknowns sit in θ (``[model | effects | instrument (6) | fixed points | tool or markers]``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pinocchio as pin

from pincal.data.dataset import Dataset
from pincal.errors import DataError
from pincal.identify.fixed_points import PointDistance, check_distances
from pincal.identify.kinds import MeasurementKind, get_kind
from pincal.options import ROTATION_WEIGHT
from pincal.robot.robots import Robot


@dataclass(frozen=True)
class Measurement:
    """What is measured and what is known about the set-up.

    Attributes:
        kind: ``position``, ``pose``, ``distance`` or ``points``.
        instrument_T_base: the registration, or its initial guess when ``fit_instrument``.
        fit_instrument: whether the registration is unknown (not used by ``distance``).
        tool: ``tip_T_target`` (pose) or a point on the tip (its translation), or initial guess.
        fit_tool: whether the tool is unknown.
        rotation_weight: weight of orientation residuals [m/rad] (``pose`` only).
        pairs: (m, 2) pose pairs for ``distance`` (default: all pairs).
        points: the fixed points whose positions are unknowns (``points``).
        point_distances: known distances between them (``points``), [m].
        markers: several markers per pose (:mod:`pincal.data.markers`): their labels; each is a
            point on the tip frame (3 unknowns [m] each, in the tool's place), else empty.
        marker_points: the markers' points (K, 3) [m] on the tip frame, given or initial guesses
            (None: at the tip frame's origin).
        marker_tips: a tree's frame of each marker (an index into the robot's ``tips``), else empty.
    """

    kind: str = "position"
    instrument_T_base: pin.SE3 = pin.SE3.Identity()
    fit_instrument: bool = True
    tool: pin.SE3 = pin.SE3.Identity()
    fit_tool: bool = True
    rotation_weight: float = ROTATION_WEIGHT
    pairs: np.ndarray | None = None
    points: tuple[str, ...] = ()
    point_distances: tuple[PointDistance, ...] = ()
    markers: tuple[str, ...] = ()
    marker_points: np.ndarray | None = None
    marker_tips: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        get_kind(self.kind)  # a DataError naming the kinds if there is none of that name
        check_distances(self.points, self.point_distances)

    @property
    def measure(self) -> MeasurementKind:
        """The measurement kind :attr:`kind` names (:mod:`pincal.identify.kinds`)."""
        return get_kind(self.kind)

    @property
    def n_instrument(self) -> int:
        """Number of registration unknowns."""
        return 6 if self.fit_instrument and self.measure.registered else 0

    @property
    def n_points(self) -> int:
        """Number of unknown point coordinates (fixed-point data)."""
        return 3 * len(self.points) if self.measure.fixed_points else 0

    @property
    def n_tool(self) -> int:
        """Number of tool unknowns (several markers: 3 per marker)."""
        if self.markers:
            return 3 * len(self.markers) if self.fit_tool else 0
        return self.measure.tool_dof if self.fit_tool else 0

    def points_on_tip(self) -> np.ndarray:
        """The markers' given or initial points (K, 3) [m] on the tip frame."""
        if self.marker_points is None:
            return np.zeros((len(self.markers), 3))
        return np.asarray(self.marker_points, dtype=float).reshape(len(self.markers), 3)

    def names(self) -> tuple[list[str], list[str]]:
        """Names and units of the measurement unknowns."""
        names, units = [], []
        if self.n_instrument:
            names += [f"instrument.{c}" for c in ("tx", "ty", "tz", "rx", "ry", "rz")]
            units += ["m"] * 3 + ["rad"] * 3
        if self.n_points:
            names += [f"point.{p}.{c}" for p in self.points for c in "xyz"]
            units += ["m"] * self.n_points
        if self.markers and self.n_tool:
            names += [f"marker.{k}.{c}" for k in self.markers for c in "xyz"]
            units += ["m"] * self.n_tool
        elif self.n_tool == 3:
            names += ["tool.x", "tool.y", "tool.z"]
            units += ["m"] * 3
        elif self.n_tool == 6:
            names += [f"tool.{c}" for c in ("tx", "ty", "tz", "rx", "ry", "rz")]
            units += ["m"] * 3 + ["rad"] * 3
        return names, units


def unpack(n_model: int, measurement: Measurement, theta: np.ndarray) -> tuple[np.ndarray, pin.SE3, pin.SE3]:
    """Split θ into model parameters, ``instrument_T_base`` and ``tip_T_target``."""
    x = theta[:n_model]
    k = n_model
    reg = measurement.instrument_T_base
    if measurement.n_instrument:
        reg = reg * pin.exp6(pin.Motion(theta[k : k + 6]))
        k += 6
    k += measurement.n_points
    tool = measurement.tool
    if measurement.markers:  # several markers: their points are :func:`marker_points`'
        return x, reg, tool
    if measurement.n_tool == 3:
        tool = pin.SE3(tool.rotation, theta[k : k + 3].copy())
    elif measurement.n_tool == 6:
        tool = tool * pin.exp6(pin.Motion(theta[k : k + 6]))
    return x, reg, tool


def marker_points(n_model: int, measurement: Measurement, theta: np.ndarray) -> np.ndarray:
    """The markers' points (K, 3) [m] on their frames for the unknowns θ (several markers)."""
    if not measurement.n_tool:
        return measurement.points_on_tip()
    k = n_model + measurement.n_instrument + measurement.n_points
    return theta[k : k + measurement.n_tool].reshape(-1, 3).copy()


def held_markers(measurement: Measurement, tool: pin.SE3) -> Measurement:
    """The measurement with its tool held as ``tool`` (every marker at its point, for several)."""
    held = replace(measurement, tool=tool, fit_tool=False)
    if measurement.markers and measurement.fit_tool:  # given points stay as given
        held = replace(held, marker_points=np.tile(tool.translation, (len(measurement.markers), 1)))
    return held


def check_markers(measurement: Measurement, data: Dataset) -> None:
    """Refuse several markers' measurement on data of one marker per pose, and the reverse.

    Raises:
        DataError: the data and the measurement disagree on the markers.
    """
    if measurement.markers and data.marker is None:
        raise DataError("the calibration has several markers: give data with xK,yK,zK columns per marker")
    if data.marker is not None and tuple(data.marker_names) != tuple(measurement.markers):
        given = ", ".join(data.marker_names)
        raise DataError(
            f"the data's markers ({given}) are not the calibration's ({', '.join(measurement.markers)}): "
            "give data with the same xK,yK,zK columns"
        )


def marker_setup(data: Dataset, tool: Any, robot: Robot) -> dict[str, Any]:
    """The :class:`Measurement` fields of several markers per pose: their labels, their frames on
    a tree and, given, their points (``tool``: one point for all, (K, 3), or ``{label: (3,)}`` [m]).

    Raises:
        DataError: the robot is a tree and the data has one marker per pose (``x,y,z``).
    """
    if data.marker is None:
        if robot.is_tree:
            raise DataError(
                f"tip= puts markers on {', '.join(robot.tips)}, and the data has one marker (x,y,z): "
                "give xK,yK,zK columns per marker, with the labels tip= names"
            )
        return {}
    k = len(data.marker_names)
    given = None
    if isinstance(tool, dict):  # a point per marker label
        missing = [label for label in data.marker_names if label not in tool]
        if missing or set(tool) - set(data.marker_names):
            raise DataError(
                f"tool= gives points for markers {', '.join(tool)}, the data has "
                f"{', '.join(data.marker_names)}: give a point for each of the data's markers"
            )
        given = np.array([np.asarray(tool[label], dtype=float) for label in data.marker_names])
    elif tool is not None:
        point = tool.translation if isinstance(tool, pin.SE3) else np.asarray(tool, dtype=float)
        given = np.tile(point, (k, 1)) if point.size == 3 else point.reshape(k, 3)
    tips = tuple(robot.marker_tip(label) for label in data.marker_names) if robot.is_tree else ()
    return {"markers": data.marker_names, "marker_points": given, "marker_tips": tips}
