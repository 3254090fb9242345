"""What ``pincal --help`` shows beside the options: their groups, the version and where the
documentation is. Importing nothing heavy: ``pincal --help`` loads neither NumPy nor Pinocchio.

The groups are given by option name, after the sub-commands are built, so that a command's
options stay written in one place (:mod:`pincal.cli.parser`); an option named in no group
is listed under "options", as argparse lists it.
"""

from __future__ import annotations

import argparse
from pathlib import Path

#: Where a user reads what the commands, files and report keys mean.
DOCS = "docs/ in pincal's source: getting started, data formats, every report key, results"

#: Option -> the group ``--help`` lists it in; the groups in this order.
GROUPS: dict[str, list[str]] = {
    "data": [
        "--tip",
        "--measure",
        "--units",
        "--degrees",
        "--instrument-frame",
        "--tool-point",
        "--point-distance",
        "--quaternion-order",
        "--payload",
        "--lock",
        "--test",
        "--holdout",
        "--pairs",
        "--columns",
        "--robot",
        "--task",
        "--pose",
        "--points",
        "--markers",
        "--noise",
        "--joint-topic",
        "--measure-topic",
        "--measure-frame",
        "--time-offset",
        "--static-band",
        "--static-time",
        "--calibration",
        "--pose-tolerance",
    ],
    "robot description": ["--xacro-arg", "--package-path", "--kinematics", "--inertias"],
    "model": [
        "--model",
        "--geometry",
        "--orientation",
        "--rotation-weight",
        "--loss",
        "--outliers",
        "--partial",
        "--prior",
    ],
    "automatic choice": ["--params", "--extend", "--folds", "--nested", "--seed"],
    "planning": [
        "--poses",
        "--candidates",
        "--criterion",
        "--tool-tolerance",
        "--sockets",
        "--clearance",
        "--instrument",
        "--reach",
    ],
    "output": [
        "--report",
        "--output",
        "--add-frame",
        "--plot",
        "--plots",
        "--force",
        "--force-fit",
        "--accept-implausible",
    ],
}


def version() -> str:
    """The installed distribution's version (the package's own when run from a source tree)."""
    from importlib import metadata  # here: 40 ms of imports that only --version needs

    try:
        return metadata.version("pincal")
    except metadata.PackageNotFoundError:  # pragma: no cover - run without installing
        from pincal import __version__

        return __version__


def report_option(command: argparse.ArgumentParser, what: str) -> None:
    """``--report FILE.json``, the one name of the JSON a command writes on every command; the
    former ``--json`` is kept as an alias (outside scripts use it). Stored as ``args.json``."""
    command.add_argument(
        "--report", "--json", dest="json", type=Path, metavar="FILE.json", help=f"write {what} as JSON here"
    )


def group_options(parser: argparse.ArgumentParser) -> None:
    """Sort every sub-command's options into :data:`GROUPS` for its ``--help``; every
    ``--help`` ends with where the documentation is."""
    parser.epilog = f"Documentation: {DOCS}"
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for command in dict.fromkeys(action.choices.values()):  # aliases share a parser
                _group(command)


def _group(command: argparse.ArgumentParser) -> None:
    """Move ``command``'s options from argparse's "options" into their groups."""
    where = {flag: title for title, flags in GROUPS.items() for flag in flags}
    optionals = command._optionals._group_actions
    groups: dict[str, list[argparse.Action]] = {title: [] for title in GROUPS}
    for action in list(optionals):
        title = next((where[f] for f in action.option_strings if f in where), None)
        if title is not None:
            optionals.remove(action)
            groups[title].append(action)
    for title, actions in groups.items():
        if actions:
            command.add_argument_group(title)._group_actions.extend(actions)
    for action in command._actions:
        _show_default(action)
    command.epilog = command.epilog or f"Documentation: {DOCS}"


def _show_default(action: argparse.Action) -> None:
    """Add ``(default: VALUE)`` to the help of an option whose help does not say its default (a
    switch's is off; an option without one says what it does when not given itself)."""
    value = action.default
    if not action.help or not action.option_strings or value in (None, False, [], (), argparse.SUPPRESS):
        return
    text = str(value)
    if "default" in action.help.lower() or f"({text})" in action.help:
        return
    action.help += f" (default: {text.replace('%', '%%')})"
