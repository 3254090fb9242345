"""Options on what is delivered and judged: ``--noise``, ``--geometry``, ``diagnose --params``."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

from pincal.cli.numeric import real


def noise(text: str) -> float:
    """``--noise`` [mm, RMS per axis]: above 0, at most 100 mm."""
    return real(text, "the instrument's noise [mm, RMS per axis]", 0.0, 100.0, strict=True)


def add_noise(cmd: argparse.ArgumentParser) -> None:
    """``--noise MM``: the residual verdict's noise figure."""
    cmd.add_argument(
        "--noise",
        type=noise,
        metavar="MM",
        help="the instrument's noise, RMS per axis, in mm whatever the data's units: the residual verdict "
        "(explained / unexplained) is judged against it (default: estimated from repeated poses, if any)",
    )


def add_geometry(cmd: argparse.ArgumentParser) -> None:
    """``--geometry first|joint``: how geometry and an effect share the fit."""
    cmd.add_argument(
        "--geometry",
        choices=["first", "joint"],
        default="first",
        help="with an effect: 'first' (default) keeps the written URDF the best URDF alone and lets the "
        "sidecar's effect complete it; 'joint' fits geometry and effect together (best with the sidecar; "
        "the URDF alone is then worse, and the table says by how much)",
    )


def add_baseline_params(cmd: argparse.ArgumentParser, parameters: Callable[[str], Any]) -> None:
    """``diagnose --params``: the geometric baseline's parameters, chosen as ``calibrate`` does."""
    cmd.add_argument(
        "--params",
        type=parameters,
        default="auto",
        metavar="all|auto|NAME,...|@FILE",
        help="the geometric baseline's parameters: 'auto' (default, as pincal calibrate), 'all' or names",
    )
