"""``--tip 1=FRAME_A,2=FRAME_B``: one frame per marker label (the branches of a tree, issue 41).

A plain ``--tip FRAME`` puts every marker on FRAME. A list of ``LABEL=FRAME`` pairs names each
marker's frame; the chain is then every joint between the base and any of those frames.
"""

from __future__ import annotations

import re

from pincal.errors import RobotError

#: A marker label: digits or letters, compared as written (``01`` is not ``1``).
_LABEL = re.compile(r"[A-Za-z0-9]+")


def is_marker_spec(tip: str | None) -> bool:
    """Whether a ``--tip`` value names frames per marker label (``1=FRAME_A,2=FRAME_B``)."""
    return tip is not None and "=" in tip


def parse_marker_tips(tip: str) -> dict[str, str]:
    """``1=FRAME_A,2=FRAME_B`` -> ``{"1": "FRAME_A", "2": "FRAME_B"}`` (in the order given).

    Raises:
        RobotError: a pair without ``=``, a label that is not digits or letters, an empty frame,
            a label given twice.
    """
    out: dict[str, str] = {}
    for part in tip.split(","):
        label, sep, frame = (p.strip() for p in part.partition("="))
        if not sep or not frame or not _LABEL.fullmatch(label):
            raise RobotError(
                f"tip={tip!r}: give LABEL=FRAME pairs separated by commas (labels of digits or letters, "
                "as in the data's xK,yK,zK columns), for example 1=left_hand,2=right_hand"
            )
        if label in out:
            raise RobotError(f"tip={tip!r}: marker {label} is given twice")
        out[label] = frame
    return out


def marker_spec(frames: dict[str, str]) -> str:
    """The ``--tip`` value of a label -> frame map (:func:`parse_marker_tips`'s inverse)."""
    return ",".join(f"{label}={frame}" for label, frame in frames.items())
