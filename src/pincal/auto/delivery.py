"""What the user takes away: the best URDF alone, and the effects that complete it, scored as written.

A URDF holds geometry only. When the chosen model also holds an effect a URDF cannot carry
(compliance, a gear harmonic, an encoder scale, backlash), fitting the geometry together with
it would leave a URDF that leans on the effect: good with the sidecar, worse than a plain
geometric fit without it (TIAGo: 4.6 mm alone against 3.0). So the deliverable is built in two
stages, **geometry first**:

1. the geometry, registration and tool are the geometric fit (what ``extension=None`` gives on
   the same parameters): the best URDF a consumer can use alone;
2. the effects are fitted on top of it, that geometry, registration and tool held, their gravity
   torques computed on the corrected URDF itself (its geometry and the inertias it is written
   with), so that the written URDF plus its sidecar reproduce the fitted model exactly.

:func:`exported_errors` scores what was exported by writing the files and loading them back
(the URDF alone, with the sidecar's registration and tool; and the URDF with the whole sidecar),
never from the fit in memory.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from pincal.data.dataset import Dataset
from pincal.export.calibrated_robot import CalibratedRobot, load_calibration, robot_from_urdf
from pincal.export.urdf_writer import corrected_files, corrected_urdf
from pincal.identify.calibration import Calibration
from pincal.identify.evaluation import ErrorStats, evaluate
from pincal.identify.identifiability import Identifiability, natural_scale
from pincal.identify.lm import OptimizeResult
from pincal.identify.measurement import Measurement
from pincal.identify.measurements import Problem
from pincal.identify.solver import Setup, assess, register, solve
from pincal.kinematics.effects import AnyEffect
from pincal.kinematics.mdh import make_model
from pincal.robot.robots import Robot


def corrected_robot(cal: Calibration) -> Robot:
    """The chain of ``cal``'s own geometry (the full model's, whatever its URDF alone holds)
    written as a URDF and loaded as a consumer loads it: what its effects' gravity torques use."""
    return robot_from_urdf(corrected_urdf(replace(cal, urdf_fit=None)), cal.robot)


def on_robot(extension: AnyEffect, robot: Robot) -> AnyEffect:
    """The same effects with their gravity torques computed on ``robot``."""
    return extension.on(robot)


def effect_on_top(
    geometry: Calibration, extension: AnyEffect, data: Dataset, test: Dataset | None
) -> Calibration:
    """The effect fitted on top of a geometric calibration, which stays as it is.

    Args:
        geometry: the geometric fit (no extension): its geometry, registration and tool are held.
        extension: the effect (its robot is replaced by the corrected URDF's chain).
        data, test: the fitted and held-out poses.
    """
    n_geo, n_ext = geometry.model.n_params, extension.n_params
    theta = np.concatenate([geometry.theta[:n_geo], np.zeros(n_ext), geometry.theta[n_geo:]])
    mask = np.insert(geometry.identifiability.identifiable, n_geo, np.ones(n_ext, dtype=bool))
    ident = replace(geometry.identifiability, identifiable=mask)
    return _effect_refitted(geometry, extension, theta, ident, data, test)


def settled(cal: Calibration, data: Dataset, test: Dataset | None) -> Calibration:
    """A fit of geometry and effect assessed again with the effect's gravity torques computed on
    its own corrected URDF (which its sidecar will be evaluated on); nothing is refitted."""
    if cal.extension is None:
        return cal
    ext = on_robot(cal.extension, corrected_robot(cal))
    problem = Problem(cal.model, cal.measurement, data, ext)
    setup = Setup(problem, natural_scale(problem), cal.urdf_measurement.tool)
    result = OptimizeResult(
        njev=cal.n_evaluations, nfev=cal.n_evaluations, message=cal.message, success=cal.converged
    )
    settled_cal = assess(
        setup, cal.theta, register(setup, with_extension=False), cal.identifiability, result, test
    )
    return carried(settled_cal, cal)


def _effect_refitted(
    geometry: Calibration,
    extension: AnyEffect,
    theta: np.ndarray,
    ident: Identifiability,
    data: Dataset,
    test: Dataset | None,
) -> Calibration:
    """Fit the effect's parameters (and fixed points' positions) from ``theta`` with every other
    unknown held, the effect's gravity torques computed on ``geometry``'s corrected URDF."""
    ext = on_robot(extension, corrected_robot(geometry))
    problem = Problem(geometry.model, geometry.measurement, data, ext)
    setup = Setup(problem, natural_scale(problem), geometry.urdf_measurement.tool)
    n_geo = geometry.model.n_params
    free = np.zeros(problem.n_params, dtype=bool)
    free[n_geo : problem.n_model] = True
    k = problem.n_model + problem.measurement.n_instrument
    free[k : k + problem.measurement.n_points] = True  # fixed points: where the sockets are
    theta, result = solve(setup, theta, free)
    cal = assess(setup, theta, register(setup, with_extension=False), ident, result, test)
    return carried(cal, geometry)


def carried(cal: Calibration, source: Calibration) -> Calibration:
    """``cal`` with what ``source`` recorded of how it was made (outliers, choice, balance, pull, guard)."""
    return replace(
        cal,
        excluded=source.excluded,
        choice=source.choice,
        balance=source.balance,
        prior=source.prior,
        guard=source.guard,
    )


@dataclass(frozen=True)
class Exported:
    """What was exported, scored as loaded back.

    Attributes:
        train, test: the URDF alone (with the sidecar's registration and tool) on the fitted and
            held-out poses (test None without held-out poses).
        full_train, full_test: the URDF with the whole sidecar.
    """

    train: ErrorStats
    test: ErrorStats | None
    full_train: ErrorStats
    full_test: ErrorStats | None


def _score(loaded: CalibratedRobot, cal: Calibration, data: Dataset | None, full: bool) -> ErrorStats | None:
    """Errors of a loaded calibration on ``data``: its registration and tool held, the
    extension applied only when ``full``."""
    if data is None:
        return None
    loaded = loaded if full else loaded.alone
    model = make_model("placements", loaded.robot)
    reg = loaded.instrument_T_base
    meas: Measurement = replace(
        cal.measurement,
        instrument_T_base=reg if reg is not None else cal.measurement.instrument_T_base,
        fit_instrument=False,
        tool=loaded.tool,
        fit_tool=False,
        pairs=None,
        marker_points=None if loaded.markers is None else np.array([p for _, p in loaded.markers.values()]),
    )
    ext = loaded.extension
    problem = Problem(model, meas, data, ext)
    theta = problem.initial_theta()
    theta[model.n_params : problem.n_model] = loaded.effect if ext is not None else []
    return evaluate(model, meas, theta, data, ext)


def exported_errors(cal: Calibration, data: Dataset, test: Dataset | None = None) -> Exported:
    """Write the corrected URDF and its sidecar, load them back, score them (see :class:`Exported`)."""
    with tempfile.TemporaryDirectory(prefix="pincal-") as folder:
        files = corrected_files(cal, Path(folder) / "calibrated.urdf")
        for path, text in files:  # a private folder: no other reader, nothing to make atomic
            Path(path).write_text(text, encoding="utf-8")
        loaded = load_calibration(files[0][0])
        return Exported(
            train=_score(loaded, cal, data, False) or ErrorStats.of(np.zeros(1)),
            test=_score(loaded, cal, test, False),
            full_train=_score(loaded, cal, data, True) or ErrorStats.of(np.zeros(1)),
            full_test=_score(loaded, cal, test, True),
        )
