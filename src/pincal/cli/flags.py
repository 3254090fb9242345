"""The command line's names for the library's arguments.

A library message names an argument as a Python caller writes it: ``measure=points``,
``point_distances='A,B=D'``, ``folds=`` (the argument itself), ``degrees=True`` (a switch). The
command shows each as its flag: ``--measure points``, ``--point-distance 'A,B=D'``, ``--folds``,
``--degrees`` (:func:`as_flags`), in its one error line and its warnings.
"""

from __future__ import annotations

import re

#: The flag of each library argument a message may name.
FLAGS = {
    "accept_implausible": "--accept-implausible",
    "add_frame": "--add-frame",
    "band": "--static-band",
    "candidates": "--candidates",
    "degrees": "--degrees",
    "deliver": "--geometry",
    "duration": "--static-time",
    "extension": "--extend",
    "force_fit": "--force-fit",
    "folds": "--folds",
    "fraction": "--holdout",
    "inertias": "--inertias",
    "instrument_frame": "--instrument-frame",
    "joint_topic": "--joint-topic",
    "kinematics": "--kinematics",
    "locked": "--lock",
    "loss": "--loss",
    "measure": "--measure",
    "measure_frame": "--measure-frame",
    "measure_topic": "--measure-topic",
    "model": "--model",
    "n_poses": "--poses",
    "nested": "--nested yes",
    "noise_mm": "--noise",
    "orientation": "--orientation",
    "package_paths": "--package-path",
    "params": "--params",
    "pairs": "--pairs",
    "partial": "--partial",
    "payload": "--payload",
    "point_distances": "--point-distance",
    "quaternion_order": "--quaternion-order",
    "rename": "--columns",
    "seed": "--seed",
    "sockets": "--sockets",
    "time_offset": "--time-offset",
    "tip": "--tip",
    "tool": "--tool-point",
    "units": "--units",
    "xacro_args": "--xacro-arg",
}
_NAMED = re.compile(r"(?<![\w.])(" + "|".join(sorted(FLAGS, key=len, reverse=True)) + r")=(True\b)?(?=(.?))")


def as_flags(text: str) -> str:
    """``text`` with each library argument it names written as its flag (see the module docstring).

    Only the lines holding an ``=`` are searched: a report of a million poses is megabytes of
    numbers, which the search of every name would read at each character."""
    if "=" not in text:
        return text
    lines = text.splitlines(keepends=True)  # a line keeps its end: the search sees what follows
    return "".join(_NAMED.sub(_flag, line) if "=" in line else line for line in lines)


def _flag(match: re.Match[str]) -> str:
    """The flag of one ``name=`` that :data:`_NAMED` found."""
    name, switch, after = match.group(1), match.group(2), match.group(3)
    if switch or not after or after in " ),;:.":
        return FLAGS[name]
    return f"{FLAGS[name]} "
