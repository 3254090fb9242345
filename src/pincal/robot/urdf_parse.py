"""A URDF's text parsed by Pinocchio, its structure checked first and urdfdom's own error line
caught when it writes one."""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

import pinocchio as pin

from pincal.errors import RobotError
from pincal.robot.joint_kinds import mimic_joints
from pincal.robot.urdf_checks import check_urdf_structure


@contextlib.contextmanager
def _stderr_captured() -> Iterator[Callable[[], list[str]]]:
    """Capture what C++ code writes to file descriptor 2 (urdfdom's parse errors)."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as sink:
        os.dup2(sink.fileno(), 2)
        lines: list[str] = []
        try:
            yield lambda: lines
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            lines.extend(sink.read().decode("utf-8", "replace").splitlines())


def parse_urdf(path: Path, text: str) -> tuple[pin.Model, dict[str, str]]:
    """The full Pinocchio model of a URDF's ``text`` (read from ``path``), and its mimic joints
    (name -> the joint it mimics).

    Raises:
        RobotError: a structure that is not a tree of well-formed joints
            (:func:`~pincal.robot.urdf_checks.check_urdf_structure`), or a URDF Pinocchio cannot parse
            (with urdfdom's own error line when it wrote one).
    """
    check_urdf_structure(text, path)  # what would crash or mislead the parser, refused first
    with _stderr_captured() as said:
        try:
            return pin.buildModelFromXML(text), mimic_joints(text)
        except (RuntimeError, ValueError) as exc:
            error = " ".join(str(exc).split())
    detail = next((ln.strip() for ln in said() if ln.strip().lower().startswith("error")), "")
    raise RobotError(f"cannot load URDF {path}: {detail or error}: fix the URDF (check it with check_urdf)")
