"""Exceptions: one root, :class:`PincalError`, whose subclasses say what to fix in the input.

The command line turns any :class:`PincalError` into one ``pincal: error: ...`` line and exit
code 2. Anything else escaping is a bug (exit code 1, traceback).
"""

from __future__ import annotations


class PincalError(Exception):
    """Root of every error caused by unusable input. The message tells the user how to fix it."""


class RobotError(PincalError):
    """The robot cannot be loaded: unknown name, missing or malformed URDF, unknown frame."""


class DataError(PincalError):
    """The measurement data is unusable: missing file or columns, non-numeric values, units."""


class IdentifiabilityError(PincalError):
    """The data cannot identify what was asked (too few poses, rank deficiency).

    Attributes:
        poses_needed: the fewest poses that would do, when that is the trouble (else None).
    """

    def __init__(self, message: str, poses_needed: int | None = None) -> None:
        super().__init__(message)
        self.poses_needed = poses_needed


class OutputError(PincalError):
    """An output cannot be written: not a regular file, a folder that refuses it, a full disk."""


class ImplausibleError(PincalError):
    """The result cannot be right (:mod:`pincal.plausibility.judge`): the message names the likely
    cause and the fix."""


class NotSupportedError(PincalError):
    """A requested feature exists in the interface but not (yet) for this input."""
