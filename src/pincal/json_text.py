"""JSON text that is JSON: every output file pincal writes in JSON goes through :func:`json_text`.

Python's :func:`json.dumps` writes ``Infinity`` and ``NaN``, which no JSON parser outside Python
reads. Here a number that is not finite becomes ``null`` (a figure that could not be computed,
such as the condition number of a rank-deficient fit), NumPy scalars and arrays become numbers
and lists, tuples become lists, and anything else is refused by ``allow_nan=False``.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np


def finite_or_null(obj: Any) -> Any:
    """``obj`` with every non-finite float (at any depth) replaced by None, NumPy values as Python's."""
    if isinstance(obj, np.ndarray):
        obj = obj.tolist()
    elif isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: finite_or_null(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [finite_or_null(v) for v in obj]
    return obj


def json_text(obj: Any) -> str:
    """``obj`` as indented JSON text ending in a newline, without ``Infinity`` or ``NaN``."""
    return json.dumps(finite_or_null(obj), indent=2, allow_nan=False) + "\n"
