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
from pathlib import Path

import numpy as np

from .calibration import Calibration
from .data import Dataset, atomic_write
from .diagnose import Diagnosis
from .effects import gravity_torques
from .errors import DataError


def _implied_joint_error(cal: Calibration, data: Dataset, joint: int) -> np.ndarray:
    problem = cal.problem(data)
    res = problem.residuals(cal.theta).reshape(len(data), -1)[:, :3]
    sens = problem.joint_sensitivity(cal.theta, joint)
    return -np.sum(sens * res, axis=1) / np.sum(sens * sens, axis=1)


def plot_diagnosis(diagnosis: Diagnosis, data: Dataset, path: str | Path) -> Path:
    """Write the PNG of a diagnosis with a named cause; returns its path.

    Raises:
        DataError: no cause was named, or the data are distances (no per-pose residual).
    """
    from matplotlib.figure import Figure  # no pyplot: the caller's backend and figures stay as they are

    if diagnosis.cause is None:
        raise DataError("nothing to plot: the diagnosis named no cause")
    if diagnosis.baseline.measurement.kind == "distance":
        raise DataError("--plots needs position or pose data: distances have no per-pose residual")
    ext = diagnosis.cause.extension
    robot, j = ext.robot, ext.index
    if ext.effect in ("joint_compliance", "backlash"):
        x, xlabel = gravity_torques(robot, data.q, ext.payload)[:, j], f"gravity torque on {ext.joint} [N·m]"
    else:
        x, xlabel = data.q[:, j], f"{ext.joint} angle [rad]"
    order = np.argsort(x)
    effect = ext.regressors(data.q) @ diagnosis.cause.params
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
    axes[0].set_ylabel(f"{ext.joint} error [mrad]")
    axes[0].legend(fontsize=8)
    fig.suptitle(textwrap.fill(diagnosis.summary(), 130), fontsize=9)
    fig.tight_layout()
    out, png = Path(path), io.BytesIO()
    fig.savefig(png, format="png", dpi=110)
    atomic_write(out, png.getvalue())  # whole or not at all, like every output
    return out
