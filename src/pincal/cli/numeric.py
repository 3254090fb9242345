"""Value types of the numeric options: each accepts a finite number in its range, or gives argparse
one error (``pincal: error: argument --NAME: ...``, exit code 2) before anything is read.

``nan``, ``inf`` and absurd magnitudes (``--rotation-weight 1e300``) would otherwise reach the
solver and end in a traceback, or in a fit that means nothing.
"""

from __future__ import annotations

import argparse
import math

#: Most BLAS threads ``--threads`` may ask for.
MAX_THREADS = 1024
#: Largest length an option takes [m or mm]: a robot cell is far smaller.
MAX_LENGTH = 1e6


def whole(text: str, minimum: int, what: str) -> int:
    """A whole number of at least ``minimum``."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < minimum:
        raise argparse.ArgumentTypeError(f"{what} is {minimum} or more, got {value}")
    return value


def real(
    text: str, what: str, low: float = -MAX_LENGTH, high: float = MAX_LENGTH, strict: bool = False
) -> float:
    """A finite number in ``[low, high]`` (``(low, high]`` when ``strict``)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{what} must be a finite number, got {text}")
    if value < low or value > high or (strict and value == low):
        bound = "above" if strict else "at least"
        raise argparse.ArgumentTypeError(f"{what} must be {bound} {low:g} and at most {high:g}, got {text}")
    return value


def rotation_weight(text: str) -> float:
    """``--rotation-weight`` [m/rad]: above 0, at most 1000."""
    return real(text, "the rotation weight [m/rad]", 0.0, 1e3, strict=True)


def sigmas(text: str) -> float:
    """``--outliers`` [robust standard deviations]: 0 (keep every pose) or more."""
    return real(text, "the outlier threshold [robust std]", 0.0, MAX_LENGTH)


def fraction(text: str) -> float:
    """``--holdout``: a fraction strictly between 0 and 1."""
    value = real(text, "the fraction held out", 0.0, 1.0, strict=True)
    if value == 1.0:
        raise argparse.ArgumentTypeError(
            f"the fraction held out must be below 1 (some poses are fitted), got {text}"
        )
    return value


def height(text: str) -> float:
    """``--clearance`` [m]: a finite height, at most 1000 m either way."""
    return real(text, "the clearance [m]", -1e3, 1e3)


def reach(text: str) -> float:
    """``--reach`` [units]: a positive finite range."""
    return real(text, "the reach", 0.0, MAX_LENGTH, strict=True)


def count(text: str) -> int:
    """A number of things: 1 or more."""
    return whole(text, 1, "a count")


def folds(text: str) -> int:
    """``--folds``: 2 or more."""
    return whole(text, 2, "the number of cross-validation folds")


def seed(text: str) -> int:
    """``--seed``: 0 or more."""
    return whole(text, 0, "a seed")


def threads(text: str) -> int:
    """``--threads``: 0 (BLAS as it is) to :data:`MAX_THREADS`."""
    value = whole(text, 0, "--threads")
    if value > MAX_THREADS:
        raise argparse.ArgumentTypeError(f"--threads is at most {MAX_THREADS}, got {value}")
    return value
