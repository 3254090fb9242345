"""Value types of the ``pincal`` command line's options: each parses one option's text or
raises :class:`argparse.ArgumentTypeError` with what was expected."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any


def payload(text: str) -> Any:
    from pincal.kinematics.gravity import Payload  # here: --help does not load Pinocchio

    return Payload.parse(text)


def vector3(text: str) -> Any:
    import numpy as np  # here: --help does not load NumPy

    try:
        values = np.array([float(v) for v in text.split(",")])
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y,Z numbers, got {text!r}") from None
    if values.shape != (3,) or not np.all(np.abs(values) < 1e6):
        raise argparse.ArgumentTypeError(f"expected three finite numbers X,Y,Z (below 1e6), got {text!r}")
    return values


def tool_points(text: str) -> Any:
    """``X,Y,Z`` (one point, every marker's) -> (3,); ``1=X,Y,Z;2=X,Y,Z`` (a point per marker
    label) -> ``{label: (3,)}``."""
    if "=" not in text:
        return vector3(text)
    out = {}
    for part in text.split(";"):
        label, sep, xyz = (p.strip() for p in part.partition("="))
        if not sep or not label or label in out:
            raise argparse.ArgumentTypeError(
                f"expected X,Y,Z or LABEL=X,Y,Z;LABEL=X,Y,Z (one point per marker label), got {text!r}"
            )
        out[label] = vector3(xyz)
    return out


def vectors3(text: str) -> Any:
    """``X,Y,Z;X,Y,Z...`` -> (K, 3)."""
    import numpy as np

    return np.array([vector3(item) for item in text.replace(" ", "").split(";") if item])


#: Largest ``--params @FILE`` read [bytes].
_MAX_LIST_BYTES = 1_000_000


def parameters(text: str) -> str | tuple[str, ...]:
    """``auto``, ``all``, ``NAME,NAME,...`` or ``@FILE`` (names one a line or comma separated;
    ``#`` starts a comment)."""
    if text in ("auto", "all"):
        return text
    if text.startswith("@"):
        from pincal.errors import PincalError
        from pincal.inputs import read_bytes  # a regular file, bounded, and an input of the run (issue 33)

        path = Path(text[1:])
        try:
            lines = read_bytes(path, "parameter list", _MAX_LIST_BYTES).decode("utf-8-sig").splitlines()
        except PincalError as exc:
            raise argparse.ArgumentTypeError(f"cannot read the parameter list {path}: {exc}") from None
        except UnicodeDecodeError as exc:
            raise argparse.ArgumentTypeError(f"cannot read the parameter list {path}: {exc}") from None
        names = name_list(",".join(line.split("#", 1)[0] for line in lines))
    else:
        names = name_list(text)
    if not names:
        raise argparse.ArgumentTypeError(f"expected auto, all, names or @FILE, got {text!r}")
    return names


def name_list(text: str) -> tuple[str, ...]:
    return tuple(n.strip() for n in text.split(",") if n.strip())


def mapping(text: str) -> dict[str, str]:
    try:
        pairs = [item.split("=", 1) for item in text.split(",")]
        return {k.strip(): v.strip() for k, v in pairs}
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected NAME=COLUMN pairs separated by commas, got {text!r}"
        ) from None


def attach_vectors(argv: Sequence[str]) -> list[str]:
    """Write ``--tool-point -1,2,3`` as ``--tool-point=-1,2,3`` (also ``--instrument``): argparse
    takes ``-1,2,3`` for an option."""
    out: list[str] = []
    for arg in argv:
        if out and out[-1] in ("--tool-point", "--instrument") and arg.startswith("-"):
            out[-1] = f"{out[-1]}={arg}"
        else:
            out.append(arg)
    return out
