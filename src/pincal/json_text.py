"""JSON text that is JSON: every output file pincal writes in JSON goes through :func:`json_text`.

Python's :func:`json.dumps` writes ``Infinity`` and ``NaN``, which no JSON parser outside Python
reads. Here a number that is not finite becomes ``null`` (a figure that could not be computed,
such as the condition number of a rank-deficient fit), NumPy scalars and arrays become numbers
and lists, tuples become lists, and anything else is refused by ``allow_nan=False``.

The text is indented, and a list of numbers is written on one line: the rows a report scored
(``train.rows``, a million of them on a large data set) stay one line, and are written by the
standard library's C encoder rather than its indenting one, a number at a time.
"""

from __future__ import annotations

import json
import math
import re
from typing import Any

import numpy as np

#: What stands for the k-th list of numbers in the indented text, before its one line replaces it
#: (a NUL, which no text pincal writes holds, makes it unmistakable).
_INLINE = "\0inline-{}\0"
_INLINED = re.compile(r'"\\u0000inline-(\d+)\\u0000"')
#: The types of the items of a list written on one line (numbers; null for a non-finite one).
_NUMBERS = {int, float, bool, type(None)}


def finite_or_null(obj: Any) -> Any:
    """``obj`` with every non-finite float (at any depth) replaced by None, NumPy values as Python's."""
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind in "iub" or (obj.dtype.kind == "f" and np.isfinite(obj).all()):
            return obj.tolist()  # every number finite: nothing to replace
        obj = obj.tolist()
    elif isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: finite_or_null(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        if set(map(type, obj)) <= {int}:  # whole numbers only (a report's rows): nothing to replace
            return list(obj)
        return [finite_or_null(v) for v in obj]
    return obj


def json_text(obj: Any) -> str:
    """``obj`` as indented JSON text ending in a newline, without ``Infinity`` or ``NaN``; a list
    of numbers on one line."""
    inline: list[str] = []
    text = json.dumps(_marked(finite_or_null(obj), inline), indent=2, allow_nan=False)
    return _INLINED.sub(lambda found: inline[int(found.group(1))], text) + "\n"


def _marked(obj: Any, inline: list[str]) -> Any:
    """``obj`` (of JSON's types) with each non-empty list of numbers written on one line into
    ``inline`` and replaced by its mark (:data:`_INLINE`)."""
    if isinstance(obj, dict):
        return {key: _marked(value, inline) for key, value in obj.items()}
    if not isinstance(obj, list):
        return obj
    if obj and set(map(type, obj)) <= _NUMBERS:
        inline.append(json.dumps(obj, allow_nan=False))
        return _INLINE.format(len(inline) - 1)
    return [_marked(value, inline) for value in obj]
