"""A corrected joint ``<origin>`` written for review: close to the input's text, and its change.

A rotation has several ``rpy`` triples (R = Rz(y) Ry(p) Rx(r)): the other branch
``(r + π, π - p, y + π)``, any angle plus a whole turn, and, at ``p = ±π/2`` (gimbal lock), every
split of ``r ∓ y``. Pinocchio's ``matrixToRpy`` picks one, which may sit a turn or a branch away
from the URDF's own: a diff then shows swings of 90° or 360° for a change of a fraction of a
milliradian. :func:`nearest_rpy` picks, among the exact triples, the one nearest the input's.

Digits below :data:`DECIMALS` (1e-12 m, 1e-12 rad: a picometre, a nanometre at a metre's reach,
a million times below what a calibration resolves) are dropped, and a component within that of
the input's value keeps the input's text, so that an origin the fit did not move reads as written.

:func:`origin_change` is what a reviewer reads instead: how far the origin moved [mm] and turned
[mrad], in its parent link's frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin
from lxml import etree

#: Decimals kept of an origin's metres and radians.
DECIMALS = 12
#: Largest rotation [rad] between a triple and the rotation it must write.
EXACT = 1e-12
#: |cos p| below which ``r`` and ``y`` turn about one axis and only ``r ∓ y`` is fixed.
LOCK = 1e-6


def nearest_rpy(rotation: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """The ``rpy`` triple of ``rotation`` nearest ``reference`` [rad].

    Args:
        rotation: the rotation to write (3, 3).
        reference: the input's ``rpy`` (3,) [rad].

    Returns:
        (3,) [rad]: ``rpyToMatrix`` of it is ``rotation`` within :data:`EXACT`.
    """
    r, p, y = (float(v) for v in pin.rpy.matrixToRpy(rotation))
    found = [np.array([r, p, y]), np.array([r + math.pi, math.pi - p, y + math.pi])]
    if abs(math.cos(p)) < LOCK:
        found += [_split_at_lock(r, p, y, reference)]
    best = np.array([r, p, y])
    for candidate in found:
        turned = candidate + 2 * math.pi * np.round((reference - candidate) / (2 * math.pi))
        exact = _angle(pin.rpy.rpyToMatrix(*turned), rotation) <= EXACT
        if exact and np.linalg.norm(turned - reference) < np.linalg.norm(best - reference):
            best = turned
    return best


def _split_at_lock(r: float, p: float, y: float, reference: np.ndarray) -> np.ndarray:
    """At gimbal lock only ``r - y`` (``p = π/2``) or ``r + y`` (``p = -π/2``) is fixed: the split
    of it nearest the reference's ``r`` and ``y``."""
    sign = 1.0 if p > 0 else -1.0  # r - y at +π/2, r + y at -π/2
    fixed = r - sign * y
    given = reference[0] - sign * reference[2]
    d = math.remainder(fixed - given, 2 * math.pi)
    return np.array([reference[0] + d / 2, p, reference[2] - sign * d / 2])


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    """The angle [rad] of the rotation between two rotation matrices."""
    return float(np.linalg.norm(pin.log3(a.T @ b)))


def _numbers(text: str | None) -> list[str]:
    tokens = (text or "0 0 0").split()
    return tokens if len(tokens) == 3 else ["0", "0", "0"]


def _written(values: np.ndarray, given: list[str]) -> str:
    """``values`` rounded to :data:`DECIMALS`, each within that of the input's keeping its text."""
    out = []
    for value, token in zip(values, given):
        try:
            same = abs(float(token) - value) <= 10.0**-DECIMALS
        except ValueError:
            same = False
        out.append(token if same else repr(round(float(value), DECIMALS) + 0.0))
    return " ".join(out)


def origin_attributes(placement: pin.SE3, xyz: str | None = None, rpy: str | None = None) -> tuple[str, str]:
    """The ``xyz`` and ``rpy`` texts of an ``<origin>`` for ``placement``, near the input's.

    Args:
        placement: the origin to write.
        xyz, rpy: the input's attributes (None: absent, read as zeros).

    Returns:
        The ``xyz`` and ``rpy`` attribute texts.
    """
    given_xyz, given_rpy = _numbers(xyz), _numbers(rpy)
    reference = np.array([_float(v) for v in given_rpy])
    angles = nearest_rpy(placement.rotation, reference)
    return _written(placement.translation, given_xyz), _written(angles, given_rpy)


def _float(token: str) -> float:
    try:
        value = float(token)
    except ValueError:
        return 0.0
    return value if math.isfinite(value) else 0.0


@dataclass(frozen=True)
class OriginChange:
    """How a joint's ``<origin>`` moved, in its parent link's frame.

    Attributes:
        joint: the joint.
        xyz_mm: the origin's shift (3,) [mm].
        rotation_mrad: the rotation vector from the input's orientation to the new one, in the
            input origin's frame (3,) [mrad].
    """

    joint: str
    xyz_mm: np.ndarray
    rotation_mrad: np.ndarray

    @property
    def translation_mm(self) -> float:
        """How far the origin moved [mm]."""
        return float(np.linalg.norm(self.xyz_mm))

    @property
    def angle_mrad(self) -> float:
        """How far the origin turned [mrad]."""
        return float(np.linalg.norm(self.rotation_mrad))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return {
            "joint": self.joint,
            "translation_mm": self.translation_mm,
            "rotation_mrad": self.angle_mrad,
            "xyz_mm": [float(v) for v in self.xyz_mm],
            "rotation_vector_mrad": [float(v) for v in self.rotation_mrad],
        }

    def text(self) -> str:
        """One line: the joint, mm, mrad."""
        return f"{self.joint}: {self.translation_mm:.4f} mm, {self.angle_mrad:.4f} mrad"


def origin_change(joint: str, before: pin.SE3, after: pin.SE3) -> OriginChange:
    """The change of ``joint``'s origin from ``before`` to ``after`` (both in its parent's frame)."""
    shift = (after.translation - before.translation) * 1e3
    turn = pin.log3(before.rotation.T @ after.rotation) * 1e3
    return OriginChange(joint, np.asarray(shift), np.asarray(turn))


def read_origin(element: etree._Element | None) -> pin.SE3:
    """SE3 of a URDF ``<origin>`` (missing: identity); rpy as URDF: R = Rz(y) Ry(p) Rx(r)."""
    if element is None:
        return pin.SE3.Identity()
    xyz = [float(v) for v in (element.get("xyz") or "0 0 0").split()]
    rpy = [float(v) for v in (element.get("rpy") or "0 0 0").split()]
    return pin.SE3(pin.rpy.rpyToMatrix(*rpy), np.array(xyz))


def write_origin(joint: etree._Element, placement: pin.SE3) -> None:
    """Write ``placement`` as the joint's ``<origin>``, near its text as it was
    (:func:`origin_attributes`: the nearest rpy, no digits below 1e-12)."""
    origin = joint.find("origin")
    origin = etree.SubElement(joint, "origin") if origin is None else origin
    xyz, rpy = origin_attributes(placement, origin.get("xyz"), origin.get("rpy"))
    origin.set("xyz", xyz)
    origin.set("rpy", rpy)
