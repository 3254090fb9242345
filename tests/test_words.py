"""What the commands print, read by an engineer who has not read the code: every figure says what
it counts and in what unit, nothing names a cause the test refused, and every line says what to
do next.

- ``calibrate``'s summary names each group of unknowns (joint placements, instrument
  registration, tool) where it counts them, says the pull toward the URDF and the guard in mm
  and standard errors (no "natural unit", no "gain ... standard errors"), and a ``cause: none``
  line names no effect;
- an undetermined verdict asks for ``--noise`` once, and says it is RMS per axis;
- ``diagnose`` (which writes no URDF) does not speak of "the corrected URDF" as written, and
  its plot without a cause is drawn against the joint its summary names;
- ``pincal template`` shows ``--noise`` and how a datasheet figure becomes RMS per axis.
"""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import numpy as np
import pytest
from cli_run import run

import pincal
from pincal.auto.residual import ResidualVerdict
from pincal.cli import main

EFFECTS = ("joint_compliance", "gear_harmonic", "encoder_scale", "backlash", "lost_motion")


@pytest.fixture(scope="module")
def clean_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """60 simulated UR5 poses with geometric errors only (metres, radians, 0.03 mm noise)."""
    robot = pincal.load_robot("ur5")
    _, fit, _ = pincal.simulate(robot, n_fit=60, n_test=1, seed=0)
    path = tmp_path_factory.mktemp("words") / "ur5.csv"
    pincal.write_csv(path, fit)
    return path


@pytest.fixture(scope="module")
def calibrate_out(clean_csv: Path) -> str:
    """What ``pincal calibrate ur5 CSV --holdout 0.3`` prints (no --noise, no -o)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(["calibrate", "ur5", str(clean_csv), "--tip", "tool0", "--holdout", "0.3"])
    assert code == 0
    return out.getvalue()


def _line(out: str, start: str) -> str:
    lines = [line for line in out.splitlines() if line.startswith(start)]
    assert lines, f"no line starts with {start!r}:\n{out}"
    return lines[0]


def test_the_parameter_count_names_registration_and_tool(calibrate_out: str) -> None:
    """ "27 of 45" says which 45: the joint placements, the instrument's pose and the tool."""
    line = _line(calibrate_out, "parameters: 27 of 45")
    assert "joint placement 18 of 36" in line
    assert "instrument registration 6 of 6" in line and "tool 3 of 3" in line
    chosen = _line(calibrate_out, "parameters: all 18")
    assert "the 9 of instrument registration and tool are always fitted" in chosen


def test_prior_and_guard_speak_in_mm_and_standard_errors(calibrate_out: str) -> None:
    """The pull's weight is said as what a correction of 1 mm costs; the guard's z as a multiple
    of a standard error against its threshold."""
    assert "natural unit" not in calibrate_out
    pull = _line(calibrate_out, "pull toward the URDF")
    assert re.search(r"a correction of 1 mm .* weighs as a residual of [0-9.e-]+ mm", pull), pull
    guard = _line(calibrate_out, "guard:")
    assert "standard errors)" not in guard
    said = r"is [0-9.]+ times its standard error above zero \(reliable above [0-9.]+\)"
    assert re.search(said, guard), guard


def test_cause_none_names_no_refused_effect(calibrate_out: str) -> None:
    """``cause: none`` never names a candidate the diagnosis' test refused."""
    line = _line(calibrate_out, "cause: none")
    assert not any(effect in line for effect in EFFECTS), line
    assert "pincal diagnose" in line  # where to see the candidates


def test_undetermined_verdict_asks_for_noise_once(calibrate_out: str) -> None:
    """Without --noise the verdict is undetermined and says once what to give, in what unit."""
    verdict = _line(calibrate_out, "verdict:")
    assert "undetermined" in verdict
    assert verdict.count("--noise") == 1, verdict
    assert "RMS per axis" in verdict
    assert "not written" in verdict  # no -o: no file is named as written


def test_diagnose_writes_no_urdf_and_says_so(
    capsys: pytest.CaptureFixture[str], clean_csv: Path, tmp_path: Path
) -> None:
    """``diagnose``'s verdict speaks of the URDF ``calibrate -o`` would write, not of one it wrote."""
    code, out, err = run(capsys, "diagnose", "ur5", clean_csv, "--plots", tmp_path)
    assert code == 0, err
    verdict = _line(out, "verdict:")
    assert "not written" in verdict and "pincal calibrate -o" in verdict, verdict
    assert "the corrected URDF alone gives" not in out


def test_residual_plot_is_drawn_against_the_joint_named() -> None:
    """Without a cause, the plot's axis is the joint the residual verdict found the errors depend
    on, else the best candidate's joint the summary names; never another chosen apart."""
    from pincal.report.plots import residual_joint

    data = pincal.Dataset(("a", "b", "c"), np.zeros((4, 3)), np.zeros((4, 3)))
    base = ResidualVerdict(np.nan, "estimated", 0.0, "undetermined", 0.1, np.nan, "")
    assert residual_joint(base, data, "c")[0] == 2
    found = ResidualVerdict(0.01, "estimated", 0.05, "unexplained", 0.1, 0.02, "", None, "b")
    assert residual_joint(found, data, "c")[0] == 1


def test_template_shows_noise_and_how_to_get_it(capsys: pytest.CaptureFixture[str]) -> None:
    """The template's comments give ``--noise MM`` (RMS per axis) and the datasheet conversions."""
    code, out, err = run(capsys, "template", "ur5", "--tip", "tool0")
    assert code == 0, err
    comments = "\n".join(line for line in out.splitlines() if line.startswith("#"))
    assert "--noise MM" in comments and "RMS per axis" in comments
    assert "U/2" in comments and "U/(2*sqrt(3))" in comments


def test_getting_started_names_the_statistics_the_table_prints(calibrate_out: str) -> None:
    """Getting started describes the printed table by the statistics its header names."""
    header = re.search(r"^position error \[mm\], (.*):$", calibrate_out, re.MULTILINE)
    assert header is not None, calibrate_out
    page = (Path(__file__).resolve().parents[1] / "docs" / "getting-started.md").read_text(encoding="utf-8")
    assert f"`{header.group(1)}`" in page
    assert "RMS, mean and max" not in page
