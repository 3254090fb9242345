"""The residual function as the modules below :mod:`pincal.identify.measurements` see it.

A measurement kind (:mod:`pincal.identify.kinds`), the fixed points' rows
(:mod:`pincal.identify.fixed_points`)
and the block-wise evaluation of large data (:mod:`pincal.identify.chunked`) work on a
:class:`~pincal.identify.measurements.Problem`, whose methods call them in turn. They take it as this
protocol, so that none of them imports the module above it: the layers point only down.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from pincal.data.dataset import Dataset
from pincal.kinematics.chain import Frames
from pincal.kinematics.effects import AnyEffect
from pincal.kinematics.models import Model


class ProblemRows(Protocol):
    """What a :class:`~pincal.identify.measurements.Problem` offers the kinds, fixed points and blocks.

    Attributes:
        data: the poses.
        model: the geometric error model.
        measurement: the :class:`~pincal.identify.measurement.Measurement` (kind, registration, tool).
        extension: the non-geometric effect, if any.
        n_params: the number of unknowns θ; n_model: of the model's and the effect's.
        pairs: (m, 2) pose pairs of distance data; measured_distances: their distances [m].
        measured_rotations: (N, 3, 3) measured rotations of pose data.
        point_index: each row's fixed point (fixed-point data), else None.
    """

    data: Dataset
    model: Model
    measurement: Any
    extension: AnyEffect | None
    n_model: int
    pairs: np.ndarray
    measured_distances: np.ndarray
    measured_rotations: np.ndarray
    point_index: np.ndarray | None

    @property
    def n_params(self) -> int:
        """Number of unknowns in θ."""

    def on(self, data: Dataset) -> ProblemRows:
        """The same problem on other poses."""

    def forget_frames(self) -> None:
        """Drop the frames kept for the last θ."""

    def row_poses(self) -> np.ndarray:
        """The pose each residual row belongs to."""

    def target_frames(
        self, theta: np.ndarray, in_instrument: bool = False, tip_only: bool = False
    ) -> tuple[Frames, np.ndarray, np.ndarray]:
        """Chain frames (with ``tip_only``, perhaps the tip's alone), target rotations (N, 3, 3)
        and positions (N, 3) [m]."""

    def target_jacobian(
        self,
        theta: np.ndarray,
        cols: np.ndarray,
        frames: Frames,
        target: tuple[np.ndarray, np.ndarray],
        to_log: np.ndarray | None = None,
    ) -> np.ndarray:
        """Jacobian of the target for the unknowns ``cols``."""

    def point_positions(self, theta: np.ndarray) -> np.ndarray:
        """The fixed points' positions (K, 3) [m]."""

    def rows(self, theta: np.ndarray, cols: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """Residuals [m] and, for the unknowns ``cols``, their Jacobian rows."""

    def residuals(self, theta: np.ndarray) -> np.ndarray:
        """Stacked residuals [m]."""

    def jacobian(self, theta: np.ndarray, free: np.ndarray | None = None) -> np.ndarray:
        """Jacobian of the residuals (its columns ``free``, if given)."""
