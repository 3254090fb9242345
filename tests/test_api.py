"""The public API (issue 32): a curated set of names, each listed once and each loading; one
typed options object that gives the same calibration as the keywords it replaces."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import pincal
from pincal.auto.settings import CalibrateOptions


def test_every_public_name_loads_and_is_listed_once() -> None:
    """``pincal.__all__`` holds about 40 names, none twice, and each resolves."""
    names = pincal.__all__
    assert len(names) == len(set(names)) <= 40
    for name in names:
        assert getattr(pincal, name) is not None, name
    assert callable(pincal.diagnose)  # the function, not the module
    with pytest.raises(AttributeError):
        pincal.no_such_name  # noqa: B018


def test_import_pincal_loads_no_numpy() -> None:
    """``import pincal`` stays light: the names load on first use (``pincal --help`` is fast)."""
    code = "import sys, pincal; print('numpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


def test_options_object_and_keywords_give_the_same_calibration(get_robot) -> None:
    """``calibrate(options=CalibrateOptions(...))`` and the same choices as keywords agree, and a
    keyword replaces the options object's field."""
    robot = get_robot("ur5")
    _, fit, _ = pincal.simulate(robot, n_fit=30, n_test=2, seed=3)
    by_keywords = pincal.calibrate(robot, fit, params="all", loss="huber", f_scale=2e-4)
    options = CalibrateOptions(params="all", loss="huber", f_scale=2e-4)
    by_object = pincal.calibrate(robot, fit, options=options)
    np.testing.assert_array_equal(by_object.theta, by_keywords.theta)
    replaced = pincal.calibrate(robot, fit, options=options, loss="linear")
    plain = pincal.calibrate(robot, fit, params="all")
    np.testing.assert_array_equal(replaced.theta, plain.theta)


def test_options_are_checked_where_given() -> None:
    """An unknown option, loss or delivery is one DataError naming it and the choices."""
    with pytest.raises(pincal.DataError, match="no option 'lose'.*loss"):
        CalibrateOptions.of(None, {"lose": "huber"})
    with pytest.raises(pincal.DataError, match="unknown loss 'hubber'"):
        CalibrateOptions(loss="hubber")
    with pytest.raises(pincal.DataError, match="unknown deliver 'both'.*balanced"):
        CalibrateOptions(deliver="both")
    with pytest.raises(pincal.DataError, match="params='some'"):
        CalibrateOptions(params="some").wanted()


@pytest.mark.parametrize(
    ("library", "command"),
    [
        ("measure=points needs a point column", "--measure points needs a point column"),
        ("point_distances='A,B': a point's distance to itself is 0", "--point-distance 'A,B': a point's"),
        ("or use fewer folds (folds=)", "or use fewer folds (--folds)"),
        ("pass degrees=True", "pass --degrees"),
        ("choose a tip on the arm with tip=", "choose a tip on the arm with --tip"),
    ],
)
def test_library_messages_name_arguments_the_command_names_flags(library: str, command: str) -> None:
    """A library message names the library's arguments; the command line shows them as flags."""
    from pincal.cli.flags import as_flags

    assert as_flags(library).startswith(command)
    assert "--" not in library
