"""Pictures of a diagnosis: the baseline's residual against the named cause's regressor.

Each pose's position residual is turned into the joint error that would explain it best
(``-J_j · r / |J_j|²`` with ``J_j`` the motion of the measured point per unit of the joint), and
plotted against the cause's regressor (gravity torque for compliance and backlash, the joint
angle for gear harmonics and scale errors), with the identified effect drawn over it; beside it,
the same after the model is extended.
"""

from __future__ import annotations

import io
import textwrap
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from pincal.auto.diagnose import Diagnosis
from pincal.auto.residual import ResidualVerdict
from pincal.data.dataset import Dataset
from pincal.errors import DataError
from pincal.files import atomic_write
from pincal.identify.calibration import Calibration
from pincal.kinematics.gravity import gravity_torques


def _implied_joint_error(cal: Calibration, data: Dataset, joint: int) -> np.ndarray:
    problem = cal.problem(data)
    res = problem.residuals(cal.theta).reshape(len(data), -1)[:, :3]
    sens = problem.joint_sensitivity(cal.theta, joint)
    return -np.sum(sens * res, axis=1) / np.sum(sens * sens, axis=1)


def plot_diagnosis(
    diagnosis: Diagnosis,
    data: Dataset,
    path: str | Path,
    residual: ResidualVerdict | None = None,
    words: Callable[[str], str] = str,
) -> Path:
    """Write the PNG of a diagnosis: the named cause's evidence, or (without a cause, given the
    ``residual`` verdict) the held-out errors against the joint they depend on most; returns its path.
    ``words`` rewrites its titles (the command line names arguments as its flags).

    Raises:
        DataError: nothing to plot, or the data are distances (no per-pose residual).
    """
    if diagnosis.baseline.measurement.measure.by_pairs:
        raise DataError("the diagnosis plots need position or pose data: distances have no per-pose residual")
    if diagnosis.cause is None:
        if residual is None or residual.errors is None:
            raise DataError("nothing to plot: the diagnosis named no cause")
        best = diagnosis.candidates[0].extension.joint if diagnosis.candidates else None
        return plot_residual(residual, data, path, best, words)
    return _plot_cause(diagnosis, data, path, residual)


def residual_joint(residual: ResidualVerdict, data: Dataset, candidate: str | None = None) -> tuple[int, str]:
    """The joint to plot the residual against, and why: the one the residual verdict found the
    errors depend on, else the best candidate's (the one the diagnosis names), else the first."""
    names = list(data.joint_names)
    if residual.variable in names:
        return names.index(residual.variable), "the joint the errors depend on most"
    if candidate in names:
        return names.index(candidate), "the best candidate's joint (not significant)"
    return 0, "no joint the errors depend on"


def plot_residual(
    residual: ResidualVerdict,
    data: Dataset,
    path: str | Path,
    candidate: str | None = None,
    words: Callable[[str], str] = str,
) -> Path:
    """The final model's held-out errors against the joint angle they depend on most (else the
    joint of ``candidate``, the diagnosis' best candidate), with the noise floor: what a model
    without a named cause still gets wrong."""
    from matplotlib.figure import Figure

    assert residual.errors is not None
    norms = np.linalg.norm(residual.errors, axis=1) * 1e3
    j, why = residual_joint(residual, data, candidate)
    fig = Figure(figsize=(6, 4))
    ax = fig.subplots()
    ax.plot(data.q[:, j], norms, ".", label="held-out error of the final model")
    if np.isfinite(residual.floor_mm):
        ax.axhspan(0, residual.floor_mm, color="C2", alpha=0.2, label="noise floor (RMS)")
    ax.set_xlabel(f"{data.joint_names[j]} angle [rad] ({why})")
    ax.set_ylabel("held-out position error [mm]")
    ax.set_title(textwrap.fill(words(residual.sentence()), 70), fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def _save(fig: Any, path: str | Path) -> Path:
    fig.tight_layout()
    out, png = Path(path), io.BytesIO()
    fig.savefig(png, format="png", dpi=110)
    atomic_write(out, png.getvalue())  # whole or not at all, like every output
    return out


def _plot_cause(
    diagnosis: Diagnosis, data: Dataset, path: str | Path, residual: ResidualVerdict | None
) -> Path:
    """The residual as a joint error against the cause's variable, before and after."""
    from matplotlib.figure import Figure  # no pyplot: the caller's backend and figures stay as they are

    assert diagnosis.cause is not None
    ext = diagnosis.cause.extension
    robot, j = ext.robot, ext.index
    if ext.effect in ("joint_compliance", "backlash"):
        x, xlabel = gravity_torques(robot, data.q, ext.payload)[:, j], f"gravity torque on {ext.joint} [N·m]"
    elif ext.effect == "lost_motion":  # ±1, spread a little so that the points can be told apart
        spread = np.random.default_rng(0).uniform(-0.15, 0.15, len(data))
        x, xlabel = data.moves()[:, j] + spread, f"direction {ext.joint} last moved in (−1, 0 unknown, +1)"
    else:
        x, xlabel = data.q[:, j], f"{ext.joint} angle [rad]"
    order = np.argsort(x)
    effect = ext.regressors(data.q, data.moves()) @ diagnosis.cause.params
    fig = Figure(figsize=(10, 4))
    axes = fig.subplots(1, 2, sharey=True)
    for ax, cal, title in (
        (axes[0], diagnosis.baseline, f"rigid model (CV RMS {diagnosis.baseline_cv_rms_mm:.3f} mm)"),
        (
            axes[1],
            diagnosis.extended,
            f"with {ext.label} (CV RMS {diagnosis.extended_cv_rms_mm:.3f} mm)",
        ),
    ):
        ax.plot(x, _implied_joint_error(cal, data, j) * 1e3, ".", label="residual as a joint error")
        ax.set_title(title, fontsize=10)
        ax.set_xlabel(xlabel)
        ax.grid(alpha=0.3)
    axes[0].plot(x[order], effect[order] * 1e3, "-", color="C3", label=f"identified {ext.effect}")
    if residual is not None and np.isfinite(residual.noise_mm):
        base = diagnosis.baseline
        lever = np.median(np.linalg.norm(base.problem(data).joint_sensitivity(base.theta, j), axis=1))
        band = residual.noise_mm / max(float(lever), 1e-9)  # mm / (m/rad) = mrad
        for ax in axes:
            ax.axhspan(-band, band, color="C2", alpha=0.15, label="instrument noise (as a joint error)")
    axes[0].set_ylabel(f"{ext.joint} error [mrad]")
    axes[0].legend(fontsize=8)
    fig.suptitle(textwrap.fill(diagnosis.summary(), 130), fontsize=9)
    return _save(fig, path)
