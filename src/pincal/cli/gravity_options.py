"""``--payload`` and ``--inertias`` are only for the effects that carry a gravity torque.

They change what a joint carries (:func:`pincal.kinematics.gravity.gravity_torques`), which only
the effects that follow it read (``joint_compliance``, ``backlash``). With ``--extend none`` or
only other named effects they would change nothing: refused before the fit. With ``--extend
auto`` they shape the candidates, but a model that keeps no gravity effect writes nothing of them:
said in a warning.
"""

from __future__ import annotations

import argparse
import re
from typing import Any

from pincal.cli.common import warn
from pincal.errors import DataError
from pincal.kinematics.effects import KINDS

#: Effects whose value depends on the gravity torque a joint carries.
GRAVITY_EFFECTS = tuple(name for name, kind in KINDS.items() if kind.loaded)


def _given(args: argparse.Namespace) -> list[str]:
    """The gravity options given on the command line."""
    named = ["--payload"] if getattr(args, "payload", None) is not None else []
    return named + (["--inertias"] if getattr(args, "inertias", None) is not None else [])


def check_gravity_options(args: argparse.Namespace, extend: str) -> None:
    """Refuse ``--payload`` / ``--inertias`` when ``--extend`` (as the run will use it) names no
    gravity effect: they would change nothing.

    Raises:
        DataError: naming the options and the effects that use them.
    """
    named = _given(args)
    if not named or extend == "auto":
        return
    effects = [part.split(":")[0].strip() for part in re.split(r"[,+;]", extend) if part.strip()]
    if any(effect in GRAVITY_EFFECTS for effect in effects):
        return
    raise DataError(
        f"{' and '.join(named)}: not used with --extend {extend}: only the effects that carry a gravity "
        f"torque ({', '.join(GRAVITY_EFFECTS)}) read them: drop {' '.join(named)}, or name such an "
        "effect (--extend joint_compliance:JOINT) or --extend auto"
    )


def kept_effects(cal: Any) -> list[str]:
    """The effects a calibration kept (its ``extension``: none, one, or several)."""
    found = cal.extension
    items = [] if found is None else list(getattr(found, "parts", (found,)))
    return [str(getattr(item, "effect", "")) for item in items]


def warn_unused_gravity(args: argparse.Namespace, cal: Any) -> None:
    """Warn when ``--payload`` / ``--inertias`` were given and the kept model has no gravity effect."""
    named = _given(args)
    if named and not any(effect in GRAVITY_EFFECTS for effect in kept_effects(cal)):
        warn(
            args,
            f"{' and '.join(named)} changed nothing written: the model kept no effect that carries a "
            f"gravity torque ({', '.join(GRAVITY_EFFECTS)})",
        )
