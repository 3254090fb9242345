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


#: ``--geometry`` choices and the library's ``deliver=`` they stand for.
GEOMETRY = {"first": "complete", "joint": "joint", "balanced": "balanced"}


def add_geometry(cmd: argparse.ArgumentParser) -> None:
    """``--geometry first|joint|balanced``: which geometry the URDF and the sidecar hold with effects."""
    cmd.add_argument(
        "--geometry",
        choices=list(GEOMETRY),
        default="first",
        help="with effects: 'first' (default) writes two deliverables, a URDF that is the best URDF alone "
        "(the geometry fitted without the effects) and a sidecar whose full model (its own geometry, "
        "registration and tool, and the effects, fitted together) is the best model with the sidecar; "
        "'joint' writes the full model's geometry into the URDF (one geometry: worse alone, the table "
        "says by how much); 'balanced' one geometry weighted so that the URDF alone stays the best URDF",
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
