"""The one unit layer: every file pincal reads or writes converts through here.

Inside pincal, lengths are metres and angles radians. A file's lengths (``x,y,z``, prismatic
joint values, a tool point, a point distance, a TCP) are in its ``--units`` (``m`` or ``mm``) and
its revolute joint values in radians, or degrees with ``--degrees`` (a prismatic joint's value is
a length: ``--degrees`` never applies to it). Readers call :func:`joints_from_file` and
:func:`lengths_from_file`; writers the inverse, :func:`joints_to_file`, so a value written by a
command reads back as the same value with the same options.

Plausibility bounds on sizes (stated in ``docs/reliability.md``):

- :data:`MAX_TOOL_M`: a TCP farther than this from the flange is no tool an arm carries (a
  millimetre file read as metres gives one a thousand times too far).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from pincal.errors import DataError
from pincal.options import UNITS

#: Farthest a tool centre point may be from the flange [m].
MAX_TOOL_M = 2.0


def metres_per(units: str) -> float:
    """Metres per unit of ``units`` (``m`` or ``mm``).

    Raises:
        DataError: an unknown unit.
    """
    if units not in UNITS:
        raise DataError(f"unknown unit {units!r}: use m or mm")
    return UNITS[units]


def _prismatic(prismatic: Sequence[bool] | None, n: int) -> np.ndarray:
    return np.asarray(prismatic if prismatic is not None else [False] * n, dtype=bool)


def joints_from_file(
    values: np.ndarray, degrees: bool, units: str, prismatic: Sequence[bool] | None
) -> np.ndarray:
    """Joint columns as a file holds them (N, n) -> radians and metres."""
    q = np.array(values, dtype=float)
    prism = _prismatic(prismatic, q.shape[1])
    if degrees:
        q[:, ~prism] = np.deg2rad(q[:, ~prism])
    q[:, prism] *= metres_per(units)
    return q


def joints_to_file(q: np.ndarray, degrees: bool, units: str, prismatic: Sequence[bool] | None) -> np.ndarray:
    """Radians and metres (N, n) -> joint columns as a file holds them (the inverse of
    :func:`joints_from_file`)."""
    out = np.array(q, dtype=float)
    prism = _prismatic(prismatic, out.shape[1])
    if degrees:
        out[:, ~prism] = np.rad2deg(out[:, ~prism])
    out[:, prism] /= metres_per(units)
    return out
