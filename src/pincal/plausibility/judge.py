"""Plausibility: whether a calibration is what a rigid arm can be and, when it is not, the likely cause.

A least-squares fit always returns numbers. On data read wrongly (degrees read as radians, two
position columns swapped, quaternions in another order, ``--instrument-frame base`` for data
that is not in the base frame) or too poor to calibrate (noise as large as the robot, many
outliers), those numbers describe no arm that can exist. :func:`judge_calibration` compares a
:class:`~pincal.Calibration` with what a rigid arm of its URDF can be. Each check is a value and
its limit; the report gives both and the margin ``limit / value``. Lengths are compared with
the robot's size (:func:`robot_size`, the lengths of its chain).

- ``outliers``: the share of the poses far off a robust refit's typical residual (the noise the
  data itself shows), :data:`~pincal.options.THRESHOLD` robust standard deviations as the fit's
  own screen counts them. That screen leaves out up to a fifth of the poses and none beyond:
  more than :data:`OUTLIERS` of them still in the fit drag it.
- ``fit``: the fitted residual (RMS; fixed points: each row from its point's mean) against the
  robot's size: a rigid arm fits a usable instrument's data within a small share of it.
- ``orientation`` (pose data): the orientation error after calibration.
- ``before``: the error of the nominal robot with the instrument and tool fitted against the
  robot's size: a real arm is within millimetres of its URDF.
- ``correction``: how far the calibration moves the measured point from where the nominal robot
  (registration and tool fitted) puts it, beyond a rigid motion of the whole set-up, RMS over the
  poses, against the robot's size. Judged
  by its effect on the measured point, not parameter by parameter: with data that hardly sees
  some combination of parameters (fixed points), two large corrections that cancel each other,
  or one the registration takes back, are no sign of a wrong reading.
- ``distance`` (fixed points with known distances): how far the nominal robot puts the points
  from their known distances, against :data:`DISTANCE` of the distance: the scale of the fit
  comes from them, so a wrong value (or unit) would shrink or stretch the arm to match it.
- ``gain``: the error after against before (both the fit's own measure: position, and the
  weighted orientation for pose data): a least-squares calibration never fits worse than the
  nominal robot it starts from, unless its data and model disagree.
- ``tool``: the measured point's (or target frame's) distance from the tip frame against the
  robot's size.

When a check fails, cheap other readings of the same data are tried, each a registration-only
fit of the nominal robot (as "before"): degrees (or radians), two of ``x,y,z`` exchanged,
quaternions in the other order, a fitted instrument registration instead of
``--instrument-frame base``, a fitted tool instead of ``--tool-point``. A reading that the
nominal robot fits :data:`IMPROVEMENT` times better, and within :data:`BEFORE`, names the cause
and its fix; otherwise the first failed check (in the order above) does.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace

import numpy as np

from pincal.data.dataset import Dataset
from pincal.identify.calibration import Calibration
from pincal.identify.measurements import Problem
from pincal.identify.outliers import THRESHOLD, far_off, pose_scores, robust_scale
from pincal.identify.registration import kabsch
from pincal.plausibility.readings import IMPROVEMENT, WITHIN, model_mismatch, other_reading
from pincal.plausibility.verdict import (
    TOOL,
    Check,
    Verdict,
    err_text,
    mm_text,
    robot_size,
    score_mm,
    share_text,
)

__all__ = ["IMPROVEMENT", "TOOL", "Check", "Verdict", "judge_calibration", "robot_size"]

#: Share of the fitted poses (outliers left out by the fit's screen not counted) far off a robust
#: refit, beyond which they drag the fit.
OUTLIERS = 0.1
#: Fitted residual RMS / robot size.
FIT = 0.05
#: Orientation error after calibration [rad].
ORIENTATION = 0.1
#: Error before (the nominal robot, registration and tool fitted) / robot size.
BEFORE = WITHIN
#: RMS displacement of the measured point by the model's corrections / robot size.
CORRECTION = 0.1
#: Fixed points: how far the nominal robot may put two points off their known distance, as a
#: share of the distance, or at least :data:`DISTANCE_FLOOR` [m]: a real arm is within millimetres
#: of its URDF, and a distance is a difference of two nearby positions (MUKCa's URDFs: 3.3 mm at
#: worst on 50 mm). A wrong ``--point-distance`` (or its unit) would otherwise rescale the arm.
DISTANCE, DISTANCE_FLOOR = 0.2, 0.01
#: Error after / error before.
GAIN = 1.1
#: Per-pose residuals whose RMS exceeds their median this many times get a robust refit (a
#: normal 3-D error has about 1.13).
HEAVY_TAIL = 1.3


def judge_calibration(
    cal: Calibration,
    data: Dataset,
    *,
    degrees: bool = False,
    quaternion_order: str = "wxyz",
    loss: str = "linear",
) -> Verdict:
    """Compare a calibration with what a rigid arm can be (see the module docstring).

    Args:
        cal: the calibration.
        data: the poses given to the fit (the outliers it left out are found by row number).
        degrees, quaternion_order: how the data was read (for the other readings tried).
        loss: the loss the fit used: robust losses keep outliers on purpose, so ``outliers`` and
            ``gain`` are not checked and ``fit`` is judged on the poses they do not down-weight.
    """
    kept = _kept(cal, data)
    size = robot_size(cal.robot)
    problem = Problem(cal.model, cal.measurement, kept, cal.extension)
    checks = (*_fit_checks(cal, problem, size, loss), *_model_checks(cal, problem, size, loss))
    verdict = Verdict(checks, size)
    if verdict.plausible:
        return verdict
    off = model_mismatch(cal, kept)
    if off > 1e-3 * size:
        hint = (
            f"the {cal.model.kind} model does not reproduce this URDF: its nominal tip is {mm_text(off)} off "
            "the URDF's at the data's poses (a pincal limitation for this robot): use model=placements"
        )
        return replace(verdict, cause="model", hint=hint)
    found = other_reading(cal, kept, degrees, quaternion_order)
    if found is not None:
        cause, fix, stats = found
        evidence = (
            f"{verdict.failed[0].text}; read so, the nominal robot fits within {err_text(stats)} "
            f"instead of {err_text(cal.train_before)}"
        )
        return replace(verdict, cause=cause, hint=f"{fix} ({evidence})")
    first = verdict.failed[0]
    return replace(verdict, cause=first.name, hint=f"{first.text}: {_fix(first.name, cal)}")


def _kept(cal: Calibration, data: Dataset) -> Dataset:
    """The poses the calibration fitted (without the outliers it left out)."""
    if not cal.excluded or len(data) == cal.n_poses:
        return data
    rows = [row for row, _ in cal.excluded]
    return data.subset(np.flatnonzero(~np.isin(data.row_numbers, rows)))


def _fit_checks(cal: Calibration, problem: Problem, size: float, loss: str) -> Iterator[Check]:
    """``outliers``, ``fit`` and ``orientation``."""
    data, robust = problem.data, loss != "linear"
    scores = pose_scores(problem, cal.theta)
    far = np.zeros(len(scores), dtype=bool)
    if len(scores) >= 8:
        rms, median = float(np.sqrt(np.mean(scores**2))), float(np.median(scores))
        if robust:
            far = far_off(scores, THRESHOLD)
        elif rms > HEAVY_TAIL * median:  # heavy tails: what does a robust fit see?
            far = far_off(_robust_scores(cal, problem), THRESHOLD)
    share = float(far.mean()) if len(far) else 0.0
    if not robust:
        out, total = len(cal.excluded), len(far) + len(cal.excluded)
        many = int(far.sum()) + out
        where = f"{out} left out by the screen, {int(far.sum())} still in the fit" if out else "in the fit"
        yield Check(
            "outliers",
            share,
            OUTLIERS,
            "ratio",
            f"{many} of {total} poses ({100 * many / max(total, 1):.0f} %) are far off the others under a "
            f"robust fit ({where}: rows {_rows(data, far)})",
        )
    fit_mm = cal.train_after.rms_mm
    if robust and far.any() and cal.measurement.measure.registered:
        pos, _ = problem.predict(cal.theta)
        errors = np.linalg.norm(pos - data.points, axis=1)[~far]
        fit_mm = float(np.sqrt(np.mean(errors**2))) * 1e3
    yield Check(
        "fit",
        fit_mm * 1e-3 / size,
        FIT,
        "ratio",
        f"{cal.measurement.measure.misses} by "
        f"{mm_text(fit_mm * 1e-3)} RMS, {share_text(fit_mm * 1e-3, size)}",
    )
    after = cal.train_after
    if after.rot_rms_mrad is not None:
        yield Check(
            "orientation",
            after.rot_rms_mrad * 1e-3,
            ORIENTATION,
            "rad",
            f"the orientations miss by {after.rot_rms_mrad:.4g} mrad RMS after calibration",
        )


def _rows(data: Dataset, mask: np.ndarray, most: int = 5) -> str:
    rows = [data.row_name(int(r)).removeprefix("row ") for r in data.row_numbers[mask]]
    return (", ".join(rows[:most]) + (" ..." if len(rows) > most else "")) if rows else "none"


def _robust_scores(cal: Calibration, problem: Problem) -> np.ndarray:
    """Per-pose scores [m] of a ``soft_l1`` refit from the calibration (what its screen sees)."""
    from pincal.identify.identifiability import natural_scale
    from pincal.identify.solver import Setup, solve  # here: the solver's users import this module

    setup = Setup(problem, natural_scale(problem), cal.measurement.tool)
    f_scale = max(robust_scale(problem.residuals(cal.theta)), 1e-9)
    theta, _ = solve(setup, cal.theta, cal.identifiability.identifiable, "soft_l1", f_scale)
    return pose_scores(problem, theta)


def _model_checks(cal: Calibration, problem: Problem, size: float, loss: str) -> Iterator[Check]:
    """``before``, ``distance``, ``correction``, ``gain`` and ``tool``."""
    weight = cal.measurement.rotation_weight
    before = score_mm(cal.train_before, weight) * 1e-3  # [m] as the fit weighs it (for the gain)
    # against the size, an orientation error counts by what it moves at the robot's reach,
    # whatever --rotation-weight the fit used
    reach_before = score_mm(cal.train_before, size) * 1e-3  # [m]
    m = cal.measurement
    fitted = [
        name
        for name, free in (("instrument", m.n_instrument), ("points", m.n_points), ("tool", m.n_tool))
        if free
    ]
    how = f" with the {' and '.join(fitted)} fitted" if fitted else ""
    what = m.measure.data_word
    yield Check(
        "before",
        reach_before / size,
        BEFORE,
        "ratio",
        f"the nominal robot misses the {what} by {err_text(cal.train_before)}{how}, "
        f"{share_text(reach_before, size)}",
    )
    known = [d for _, _, d in m.point_distances] if m.measure.fixed_points else []
    off_mm = cal.train_before.point_distance_error_mm
    if known and off_mm is not None:
        slack = max(DISTANCE * min(known), DISTANCE_FLOOR)  # [m]
        yield Check(
            "distance",
            off_mm * 1e-3 / slack,
            1.0,
            "ratio",
            f"the nominal robot puts the points {mm_text(off_mm * 1e-3)} off the known "
            f"distance{'s' if len(known) > 1 else ''} ({', '.join(mm_text(d) for d in known)}), more than "
            f"{mm_text(slack)}",
        )
    after, nominal = _points(problem, cal.theta), _points(problem, cal.nominal_theta)
    fit = kabsch(nominal, after)  # a motion of the whole set-up is no correction (gauges)
    moved = after - (nominal @ fit.rotation.T + fit.translation)
    rms = float(np.sqrt(np.mean(np.sum(moved**2, axis=1))))
    yield Check(
        "correction",
        rms / size,
        CORRECTION,
        "ratio",
        f"the calibration moves the measured point {mm_text(rms)} RMS from where the nominal robot puts it "
        "(beyond a rigid motion of the whole set-up), "
        f"{share_text(rms, size)} (largest correction: {_largest(cal)})",
    )
    if loss == "linear":
        worse = score_mm(cal.train_after, weight) * 1e-3 / max(before, 1e-12)
        yield Check(
            "gain",
            worse,
            GAIN,
            "ratio",
            f"the fit after calibration against before (above {GAIN:g}: calibration makes it worse): "
            f"{err_text(cal.train_before)} before, {err_text(cal.train_after)} after",
        )
    _, _, tool = cal.split()
    reach = float(np.linalg.norm(tool.translation))
    thing = cal.measurement.measure.thing
    yield Check(
        "tool",
        reach / size,
        TOOL,
        "ratio",
        f"the {thing} is {reach:.4g} m from the tip frame, {reach / size:.2g} times the robot's size "
        f"({size:.3g} m)",
    )


def _points(problem: Problem, theta: np.ndarray) -> np.ndarray:
    """Where a fit puts the measured point (N, 3) [m]: in the instrument's frame, else (distance,
    fixed points) in the base frame."""
    if problem.measurement.measure.registered:
        return problem.predict(theta)[0]
    return problem.target_frames(theta)[2]


def _largest(cal: Calibration) -> str:
    """The model's largest length correction (else angle), in words."""
    n = cal.model.n_params
    free = cal.identifiability.identifiable[:n]
    mine = free & (np.array(cal.units[:n]) == "m")
    mine = mine if mine.any() else free
    if not mine.any():
        return "none"
    k = int(np.flatnonzero(mine)[np.argmax(np.abs(cal.x[mine]))])
    return f"{cal.names[k]} {cal.x[k] * 1e3:+.4g} {'mm' if cal.units[k] == 'm' else 'mrad'}"


# ------------------------------------------------------------------------------ generic fixes

_DATA = (
    "the joint columns (names, units: degrees=True, order), x,y,z, and that the data belongs to this "
    "robot and tip="
)
_FIXES = {
    "outliers": "too many outliers to leave out (the screen leaves out a fifth of the poses at most): check "
    "those rows and the instrument, or fit with a robust loss=soft_l1",
    "orientation": "the measured orientations are not the tip's: check the quaternion columns (their order: "
    "--quaternion-order) and that they belong to the measured target",
    "before": f"the data is not this robot's as read: check {_DATA}, and instrument_frame= / tool=",
    "gain": "the data does not fit this robot's kinematics: check the columns (--quaternion-order) and tip=",
    "tool": "no arm carries that: check x,y,z and their unit (units=), and that the data belongs to this "
    "robot and tip=",
}
_FIXES["correction"] = _FIXES["before"]
_FIXES["distance"] = (
    "check point_distances= (the points' names, the value and its unit: units=) and the joint columns "
    "(degrees=True)"
)


def _fix(name: str, cal: Calibration) -> str:
    """What to check when the check ``name`` failed and no other reading explains it."""
    if name != "fit":
        return _FIXES[name]
    before, after = cal.train_before.rms_mm, cal.train_after.rms_mm
    if after > 0.5 * before:  # calibration explains little of it: scatter, not geometry
        return (
            f"calibration removes little of it ({mm_text(before * 1e-3)} before): the measurements scatter "
            "about as far as the robot reaches (instrument noise, or another robot's or tip's data): "
            "check the instrument, the columns and tip="
        )
    return f"no rigid arm of this URDF fits the data: check {_DATA}"
