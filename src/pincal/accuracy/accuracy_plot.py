"""A picture of ISO 9283 figures: the attained positions around each commanded pose."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np

from pincal.accuracy.iso9283 import AccuracyResult
from pincal.errors import DataError
from pincal.files import atomic_write


def _panel(ax: Any, offsets: np.ndarray, to_command: np.ndarray, rp: float, axis: str) -> None:
    """One plane: attained positions around their barycentre [mm], RP's circle, and the commanded
    position (drawn where it is, or as an arrow toward it when it lies far outside the circle)."""
    circle = np.linspace(0.0, 2 * np.pi, 100)
    ax.plot(offsets[:, 0], offsets[:, 1], ".", color="C0", label="attained")
    ax.plot(rp * np.cos(circle), rp * np.sin(circle), "-", color="C2", lw=0.8, label="RP")
    ax.plot([0.0], [0.0], "x", color="k", label="barycentre")
    far = np.linalg.norm(to_command) > 2 * rp
    shown = to_command / max(np.linalg.norm(to_command), 1e-12) * 1.6 * rp if far else to_command
    if far:
        ax.annotate("", shown, (0.0, 0.0), arrowprops={"arrowstyle": "->", "color": "C3"})
        ax.text(*shown, f"commanded {np.linalg.norm(to_command):.3g} mm away", color="C3", fontsize=7)
    else:
        ax.plot(*shown, "+", color="C3", markersize=12, label="commanded")
    ax.set_xlabel("X − barycentre [mm]")
    ax.set_ylabel(f"{axis} − barycentre [mm]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)


def accuracy_png(result: AccuracyResult) -> bytes:
    """A PNG with one column per pose: the attained positions around their barycentre in the
    base X-Y and X-Z planes [mm], RP's circle, and where the commanded position lies.

    Raises:
        DataError: matplotlib is not installed (the ``plot`` extra).
    """
    try:
        from matplotlib.figure import Figure  # no pyplot: the caller's backend stays as it is
    except ImportError:
        raise DataError("plotting needs matplotlib: pip install 'pincal[plot]'") from None
    n = len(result.poses)
    fig = Figure(figsize=(3.2 * n, 6.2))
    axes = fig.subplots(2, n, squeeze=False)
    for k, pose in enumerate(result.poses):
        offsets = (pose.attained - pose.barycentre) * 1e3
        to_command = (pose.commanded - pose.barycentre) * 1e3
        for row, (j, name) in enumerate(((1, "Y"), (2, "Z"))):
            _panel(axes[row, k], offsets[:, [0, j]], to_command[[0, j]], pose.rp_mm, name)
        axes[0, k].set_title(f"{pose.pose}: AP {pose.ap_mm:.3f} mm, RP {pose.rp_mm:.3f} mm", fontsize=9)
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(f"ISO 9283, commanded by the {result.command.replace('_', ' ')} (circle: RP)", fontsize=10)
    fig.tight_layout()
    png = io.BytesIO()
    fig.savefig(png, format="png", dpi=100)
    return png.getvalue()


def plot_accuracy(result: AccuracyResult, path: str | Path) -> Path:
    """Write :func:`accuracy_png` to ``path`` (whole or not at all); returns the path."""
    atomic_write(path, accuracy_png(result))
    return Path(path)
