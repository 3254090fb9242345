"""Shared fixtures: a session-wide cache of the bundled robots.

Loading a URDF and reducing it to its chain is cheap but not free, and the property tests ask for
the same handful of robots many times; ``get_robot(name)`` loads each one once per session.
"""

from __future__ import annotations

from collections.abc import Callable

import pytest

import pincal

#: The bundled robots the property tests run on.
ROBOT_NAMES = ("ur5", "ur10", "panda", "z1", "mrres5", "zu3")


@pytest.fixture(scope="session")
def get_robot() -> Callable[[str], pincal.Robot]:
    """``get_robot(name)``: ``pincal.load_robot(name)``, loaded once per test session."""
    cache: dict[str, pincal.Robot] = {}

    def get(name: str) -> pincal.Robot:
        if name not in cache:
            cache[name] = pincal.load_robot(name)
        return cache[name]

    return get
