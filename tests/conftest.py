"""Shared fixtures: a session-wide cache of the bundled robots, and urdfdom's check of every
corrected URDF.

Loading a URDF and reducing it to its chain is cheap but not free, and the property tests ask for
the same handful of robots many times; ``get_robot(name)`` loads each one once per session.

Every corrected URDF a test writes (through :func:`pincal.write_corrected_urdf`, the API or the
command) is parsed as it is written by urdfdom's own ``check_urdf`` from the system (Debian's
``liburdfdom-tools``, which ``.ci/run`` installs; not the Python environment's copy, the build
Pinocchio parses with), and a rejection fails that test. Where it is not on PATH the check is
off, and the tests asking for the ``check_urdf`` fixture are skipped with the reason.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

import pincal
import pincal.cli  # before NumPy, as the command: BLAS loads with one thread, its workers start none
import pincal.export.urdf_writer
from pincal.export import urdf_writer

#: The bundled robots the property tests run on.
ROBOT_NAMES = ("ur5", "ur10", "panda", "z1", "mrres5", "zu3")


def _system_check_urdf() -> str | None:
    """The system's ``check_urdf`` on PATH (Debian's ``liburdfdom-tools``, the urdfdom ROS tools
    load URDFs with), or None. The copy inside the Python environment (``cmeel-urdfdom``, the build
    Pinocchio itself parses with) is passed over: it would check nothing Pinocchio does not."""
    environment = Path(sys.prefix).resolve()
    for folder in os.environ.get("PATH", "").split(os.pathsep):
        found = shutil.which("check_urdf", path=folder) if folder else None
        if found is not None and environment not in Path(found).resolve().parents:
            return found
    return None


#: urdfdom's command-line parser, or None where it is not installed.
CHECK_URDF = _system_check_urdf()
CHECK_URDF_MISSING = (
    "the system's check_urdf (urdfdom's parser, Debian's liburdfdom-tools) is not on PATH: "
    "corrected URDFs are not checked with it; install it (apt-get install liburdfdom-tools, as "
    ".ci/run does)"
)


@pytest.fixture(scope="session")
def get_robot() -> Callable[[str], pincal.Robot]:
    """``get_robot(name)``: ``pincal.load_robot(name)``, loaded once per test session."""
    cache: dict[str, pincal.Robot] = {}

    def get(name: str) -> pincal.Robot:
        if name not in cache:
            cache[name] = pincal.load_robot(name)
        return cache[name]

    return get


def urdfdom_error(document: bytes | Path) -> str | None:
    """What ``check_urdf`` says against a URDF (a file or its bytes), or None if it accepts it.

    Requires :data:`CHECK_URDF`.
    """
    assert CHECK_URDF is not None, CHECK_URDF_MISSING
    with tempfile.TemporaryDirectory() as folder:
        if isinstance(document, bytes):
            path = Path(folder) / "corrected.urdf"
            path.write_bytes(document)
        else:
            path = Path(document)
        result = subprocess.run([CHECK_URDF, str(path)], capture_output=True, text=True, timeout=60)
    if result.returncode == 0 and "robot name is:" in result.stdout:
        return None
    return f"check_urdf exit {result.returncode}: {result.stdout[-2000:]}{result.stderr[-2000:]}"


@pytest.fixture(scope="session", autouse=True)
def _urdfdom_checks_corrected_urdfs() -> Iterator[None]:
    """While the tests run, every document :func:`pincal.export.urdf_writer.corrected_urdf` returns
    (what ``write_corrected_urdf`` writes) must pass ``check_urdf``, if installed."""
    if CHECK_URDF is None:
        yield
        return
    original = urdf_writer.corrected_urdf

    def checked(*args: Any, **kwargs: Any) -> bytes:
        document = original(*args, **kwargs)
        error = urdfdom_error(document)
        assert error is None, f"urdfdom rejects the corrected URDF: {error}"
        return document

    urdf_writer.corrected_urdf = checked
    try:
        yield
    finally:
        urdf_writer.corrected_urdf = original


@pytest.fixture()
def check_urdf() -> Callable[[bytes | Path], None]:
    """``check_urdf(path_or_bytes)``: assert that urdfdom's ``check_urdf`` accepts the URDF;
    skipped when ``check_urdf`` is not installed."""
    if CHECK_URDF is None:
        pytest.skip(CHECK_URDF_MISSING)

    def check(document: bytes | Path) -> None:
        error = urdfdom_error(document)
        assert error is None, error

    return check


@pytest.fixture(scope="session")
def ur5_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """30 simulated UR5 poses (radians, metres) as a measurement CSV."""
    import pincal

    robot = pincal.load_robot("ur5")
    _, fit, _ = pincal.simulate(robot, 30, 5, seed=0)
    path = tmp_path_factory.mktemp("data") / "data.csv"
    pincal.write_csv(path, fit)
    return path
