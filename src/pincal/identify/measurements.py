"""Measurement models: residuals and analytic Jacobians for position, pose and distance data.

The unknowns are stacked as ``θ = [model parameters | instrument (6) | tool (3 or 6)]``:

- *instrument*: the registration ``instrument_T_base = instrument_T_base⁰ · exp(ρ)`` (a twist
  ρ, order (v, ω)), estimated unless the instrument frame is given (``--instrument-frame base``);
- *tool*: the measured point on the tip frame (3, [m]) for position and distance data, or the
  target frame ``tip_T_target = tip_T_target⁰ · exp(τ)`` (6) for pose data.

Residuals (model minus measurement):

- ``position``: the point in the instrument frame, 3 per pose [m];
- ``pose``: the position (3 [m]) and ``w · log3(R_measuredᵀ R_model)`` (3), with
  ``w = rotation_weight`` [m/rad] so that 1 mrad weighs as much as ``w`` mm;
- ``distance`` (Gao et al. 2013, eqs. 13-18): ``|p_i - p_j|`` (model, base frame) minus the
  measured distance, one per pair [m]; it needs no registration;
- ``points``: the tip (base frame) minus the position of the fixed point the row names, 3 per
  row [m], then one per known distance between points (:mod:`pincal.identify.fixed_points`); the points'
  positions (3 each, [m]) take the registration's place in θ.

Position and pose data of many poses are evaluated block by block (:mod:`pincal.identify.chunked`). Each
kind's rows are its class's (:mod:`pincal.identify.kinds`).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pinocchio as pin

from pincal.data.dataset import Dataset, every_marker
from pincal.data.pairs import all_pairs
from pincal.identify import chunked
from pincal.identify.fixed_points import point_index, point_means
from pincal.identify.measurement import Measurement, check_markers, marker_points, unpack
from pincal.identify.registration import quaternions
from pincal.kinematics.chain import Frames, forward, summed_columns, twist_columns
from pincal.kinematics.effects import AnyEffect
from pincal.kinematics.models import Model
from pincal.kinematics.turns import stacked_dot


def marker_arms(rotations: np.ndarray, points: np.ndarray, marker: np.ndarray) -> np.ndarray:
    """Each row's marker point in base axes (N, 3) [m]: ``R_tip · point[marker]``."""
    return np.einsum("nij,nj->ni", rotations, points[marker])


def marker_columns(rotations: np.ndarray, marker: np.ndarray, cols: np.ndarray, n_markers: int) -> np.ndarray:
    """The target's velocity (N, 3, c) for the markers' point columns ``cols`` (0-based among
    their 3K): a marker's point moves only its own rows, along the tip frame's axes."""
    out = np.zeros((len(marker), 3, len(cols)))
    for c, col in enumerate(cols):
        k, axis = divmod(int(col), 3)
        if k < n_markers:
            out[:, :, c] = rotations[:, :, axis] * (marker == k)[:, None]
    return out


def branch_only(frames: Frames, k: int, v: np.ndarray, w: np.ndarray | None) -> tuple[np.ndarray, Any]:
    """Columns of position ``k`` kept only on the rows whose tip it moves (a tree), else as given."""
    mask = frames.acting(k)
    if mask is None:
        return v, w
    return v * mask, None if w is None else w * mask


def as_slice(where: np.ndarray) -> slice | np.ndarray:
    """Sorted column indices as a slice when they are consecutive: writing through a slice costs
    a seventh of writing through an index array (20,000 poses)."""
    if where[-1] - where[0] == len(where) - 1:
        return slice(int(where[0]), int(where[-1]) + 1)
    return where


def base_tip(frames: Frames, registration: pin.SE3 | None) -> tuple[np.ndarray, np.ndarray]:
    """``base_R_tip`` (N, 3, 3) and ``base_p_tip`` (N, 3) [m] of chain frames in base axes, or of
    frames in the instrument's axes (``registration``: ``instrument_T_base``)."""
    rot, pos = frames.tip_rotation, frames.tip_translation
    if registration is None:
        return rot.copy(), pos.copy()  # a copy: a view would keep every chain frame
    back = registration.rotation.T
    return back @ rot, (pos - registration.translation) @ back.T


def tip_frames(rot: np.ndarray, pos: np.ndarray, registration: pin.SE3 | None) -> Frames:
    """Frames holding only the tip frame ``rot`` (N, 3, 3), ``pos`` (N, 3) [m] given in base axes,
    in the instrument's axes when ``registration`` (``instrument_T_base``) is given."""
    if registration is not None:
        turn = registration.rotation
        rot, pos = turn @ rot, pos @ turn.T + registration.translation
    return Frames(rot[None], pos[None])


class Problem:
    """The residual function of a model, a measurement model and a dataset."""

    def __init__(
        self, model: Model, measurement: Measurement, data: Dataset, extension: AnyEffect | None = None
    ) -> None:
        measurement.measure.check(data)
        check_markers(measurement, data)
        self.model = model
        self.measurement = measurement
        self.data = data
        self.extension = extension
        names, units = measurement.names()
        ext_names = extension.names if extension else ()
        ext_units = extension.units if extension else ()
        self.names = (*model.names, *ext_names, *names)
        self.units = (*model.units, *ext_units, *units)
        self.n_model = model.n_params + len(ext_names)
        none = np.empty((len(data), 0))
        self.regressors = extension.regressors(data.q, data.moves()) if extension else none
        self.param_joints = extension.param_joints if extension else np.zeros(0, dtype=int)
        self.onto_joints = np.zeros((len(self.param_joints), data.q.shape[1]))  # each parameter's joint
        self.onto_joints[np.arange(len(self.param_joints)), self.param_joints] = 1.0
        self.pairs = np.empty((0, 2), dtype=int)
        self.measured_distances = np.empty(0)
        if measurement.measure.by_pairs:
            self.pairs = measurement.pairs if measurement.pairs is not None else all_pairs(len(data))
            self.measured_distances = np.linalg.norm(
                data.points[self.pairs[:, 0]] - data.points[self.pairs[:, 1]], axis=1
            )
        self.measured_rotations = data.rotations() if measurement.measure.orientation else np.empty((0, 3, 3))
        self.point_index = point_index(data, measurement.points) if measurement.measure.fixed_points else None
        self._frames: tuple[Any, Any] = (None, None)  # the last θ's frames
        self._tips: tuple[Any, Any] = (None, None)  # the last geometry's tip frame, in base axes

    def on(self, data: Dataset) -> Problem:
        """The same problem on other poses (a block, a sample)."""
        return Problem(self.model, self.measurement, data, self.extension)

    def measuring(self, theta: np.ndarray, q: np.ndarray) -> Problem:
        """The same problem at the configurations ``q`` (N, n) [rad or m], measuring exactly what
        ``theta`` predicts there (each marker; for distance data, between every two of them): its
        residuals at another θ are that θ's rows less ``theta``'s."""
        quats = np.tile([1.0, 0.0, 0.0, 0.0], (len(q), 1)) if self.data.has_orientation else None
        blank = every_marker(self.data, q, quats)
        at_q = Problem(self.model, replace(self.measurement, pairs=None), blank, self.extension)
        _, rot, pos = self.measurement.measure.frames(at_q, theta, None)
        return at_q.on(replace(blank, points=pos, quaternions=None if quats is None else quaternions(rot)))

    def forget_frames(self) -> None:
        """Drop the frames kept for the last θ (a block's, once used)."""
        self._frames = (None, None)

    @property
    def n_params(self) -> int:
        """Number of unknowns in θ."""
        return len(self.names)

    def split(self, theta: np.ndarray) -> tuple[np.ndarray, pin.SE3, pin.SE3]:
        """Model parameters, ``instrument_T_base`` and ``tip_T_target`` for the unknowns θ."""
        return unpack(self.n_model, self.measurement, theta)

    def initial_theta(self) -> np.ndarray:
        """θ for the nominal model and the measurement model's initial registration and tool."""
        m, theta = self.measurement, np.zeros(self.n_params)
        k = self.n_model + m.n_instrument + m.n_points
        if m.markers and m.n_tool:
            theta[k : k + m.n_tool] = m.points_on_tip().reshape(-1)
        elif m.n_tool == 3:
            theta[k : k + 3] = m.tool.translation
        if m.n_points and self.point_index is not None:  # each point at its rows' mean tip
            means = point_means(self.target_frames(theta)[2], self.point_index, len(m.points))
            theta[self.n_model : self.n_model + m.n_points] = means.reshape(-1)
        return theta

    def point_positions(self, theta: np.ndarray) -> np.ndarray:
        """The fixed points' positions (K, 3) [m] in the base frame (fixed-point data)."""
        return theta[self.n_model : self.n_model + self.measurement.n_points].reshape(-1, 3)

    def row_poses(self) -> np.ndarray:
        """The pose each residual row belongs to (-1: none, as a known distance's row); for
        every measure but ``distance``, whose rows are pairs (:attr:`pairs`)."""
        rows = np.repeat(np.arange(len(self.data)), self.measurement.measure.width)
        return np.concatenate([rows, np.full(len(self.measurement.point_distances), -1)])

    def reached(self, theta: np.ndarray) -> np.ndarray:
        """The joint values the robot reaches (N, n): the commands plus the extension's error."""
        if self.extension is None:
            return self.data.q
        moved = self.regressors * theta[self.model.n_params : self.n_model]
        return self.data.q + moved @ self.onto_joints

    def target_frames(
        self, theta: np.ndarray, in_instrument: bool = False, tip_only: bool = False
    ) -> tuple[Frames, np.ndarray, np.ndarray]:
        """Chain frames, ``R_target`` (N, 3, 3) and ``p_target`` (N, 3) [m], in base axes (or in
        the instrument's, ``in_instrument``). With ``tip_only``, the frames may hold the tip alone
        (enough for the residuals and the registration's, tool's and markers' columns): at a
        geometry met before (θ's model part), the tip frame kept from then, without the chain."""
        key = (theta.tobytes(), in_instrument)
        if self._frames[0] == key:  # a solver asks for residuals and Jacobian at the same θ
            return self._frames[1]
        if chunked.is_large(self):  # block by block (issue 33): the tip frame only
            self._frames = (key, chunked.target_frames(self, theta, in_instrument))
            return self._frames[1]
        x, reg, tool = self.split(theta)
        geometry = theta[: self.n_model].tobytes()
        whole = not (tip_only and self._tips[0] == geometry)
        if not whole:  # a registration's fit moves no joint frame
            base_r, base_p = self._tips[1]
            frames = tip_frames(base_r, base_p, reg if in_instrument else None)
        else:
            chain = self.model.chain(x[: self.model.n_params])
            if in_instrument:
                chain = chain.registered(reg)
            frames = forward(chain, self.reached(theta), self.row_tips())
            self._tips = (geometry, base_tip(frames, reg if in_instrument else None))
        if self.measurement.markers and self.data.marker is not None:
            rot = frames.tip_rotation
            points = marker_points(self.n_model, self.measurement, theta)
            pos = frames.tip_translation + marker_arms(rot, points, self.data.marker)
        else:
            rot = stacked_dot(frames.tip_rotation, tool.rotation)
            pos = (
                frames.tip_translation + stacked_dot(frames.tip_rotation, tool.translation[:, None])[:, :, 0]
            )
        if whole:  # a tip-only answer serves no Jacobian of the chain
            self._frames = (key, (frames, rot, pos))
        return frames, rot, pos

    def row_tips(self) -> np.ndarray | None:
        """A tree's tip of each row (the frame its marker is on), else None."""
        tips = self.measurement.marker_tips
        if not tips or self.data.marker is None:
            return None
        return np.asarray(tips, dtype=int)[self.data.marker]

    def predict(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predicted target positions (N, 3) [m] and rotations (N, 3, 3) in the instrument frame."""
        _, rot, pos = self.target_frames(theta, in_instrument=True, tip_only=True)
        return pos, rot

    def joint_sensitivity(self, theta: np.ndarray, joint: int) -> np.ndarray:
        """How each pose's measured point moves per unit of joint ``joint`` (N, 3), instrument frame."""
        frames, _, pos = self.target_frames(theta, in_instrument=True)
        k = 2 * joint + 1
        zeta = self.model.chain(theta[: self.model.n_params]).axes[joint][:, None]
        moved = twist_columns(frames.rotations[k], frames.translations[k], zeta, pos)[0][:, :, 0]
        mask = frames.acting(k)
        return moved if mask is None else moved * mask[:, :, 0]

    def n_rows(self) -> int:
        """How many residual rows :meth:`residuals` gives (counted, not computed)."""
        return self.measurement.measure.n_rows(self)

    def residuals(self, theta: np.ndarray) -> np.ndarray:
        """Stacked residuals [m] (see the module docstring)."""
        return self.rows(theta, None)[0]

    def jacobian(self, theta: np.ndarray, free: np.ndarray | None = None) -> np.ndarray:
        """Analytic Jacobian of :meth:`residuals` with respect to θ (its columns ``free``, a mask
        or indices, if given: only those are computed)."""
        cols = np.arange(self.n_params) if free is None else np.arange(self.n_params)[free]
        return self.rows(theta, cols)[1]

    def target_jacobian(
        self,
        theta: np.ndarray,
        cols: np.ndarray,
        frames: Frames,
        target: tuple[np.ndarray, np.ndarray],
        to_log: np.ndarray | None = None,
    ) -> np.ndarray:
        """Jacobian of the target, for the unknowns ``cols``: each is a right-perturbation of a
        frame. Rows: the target's velocity (N, 3, c) in the axes of ``frames``, then, given
        ``to_log`` (N, 3, 3), that map of its angular velocity (N, 3, c)."""
        m, n_geo = self.measurement, self.model.n_params
        rot, pos = target
        rotation = to_log is not None
        out = np.zeros((len(self.data), 6 if rotation else 3, len(cols)))
        jac_v, jac_w = out[:, :3], out[:, 3:]

        def columns(k_rot: np.ndarray, k_pos: np.ndarray, zeta: np.ndarray) -> tuple[np.ndarray, Any]:
            v, _ = twist_columns(k_rot, k_pos, zeta, pos, rotation=False)
            if to_log is None:
                return v, None
            if k_rot.shape == (3, 3):  # one frame for every pose (the registration's)
                return v, stacked_dot(to_log, k_rot @ zeta[3:])
            return v, stacked_dot(to_log @ k_rot, zeta[3:])

        def add(k_rot: np.ndarray, k_pos: np.ndarray, zeta: np.ndarray, where: np.ndarray) -> None:
            v, w = columns(k_rot, k_pos, zeta)
            at = as_slice(where)
            jac_v[:, :, at] += v
            if w is not None:
                jac_w[:, :, at] += w

        geo = np.flatnonzero(cols < n_geo)
        if geo.size:
            twists = self.model.twists(theta[:n_geo])[:, :, cols[geo]]
            v, w = summed_columns(frames, twists, pos, to_log=to_log)
            jac_v[:, :, as_slice(geo)] = v
            if w is not None:
                jac_w[:, :, as_slice(geo)] = w
        ext = np.flatnonzero((cols >= n_geo) & (cols < self.n_model))
        joints = self.param_joints[cols[ext] - n_geo]
        axes = self.model.chain(theta[:n_geo]).axes if ext.size else np.zeros((0, 6))  # model's joint frames
        for index in np.unique(joints):  # each moved joint's column, times each pose's regressor
            here = ext[joints == index]
            k = 2 * int(index) + 1
            v, w = columns(
                frames.rotations[k], frames.translations[k], axes[index][:, None] * np.ones(here.size)
            )
            v, w = branch_only(frames, k, v, w)
            regressors = self.regressors[:, cols[here] - n_geo][:, None, :]
            jac_v[:, :, as_slice(here)] = v * regressors
            if w is not None:
                jac_w[:, :, as_slice(here)] = w * regressors
        k = self.n_model
        if m.n_instrument:  # instrument_T_base · exp(ρ): a perturbation before the chain
            here = np.flatnonzero((cols >= k) & (cols < k + 6))
            _, reg, _ = self.split(theta)
            if here.size:
                zeta = pin.Jexp6(pin.Motion(theta[k : k + 6]))[:, cols[here] - k]
                add(reg.rotation, reg.translation, zeta, here)
            k += 6
        k += m.n_points  # a point's columns are not the target's: see fixed_points.points_rows
        here = np.flatnonzero(cols >= k)
        if here.size and m.markers and self.data.marker is not None:
            rotations = frames.tip_rotation
            jac_v[:, :, as_slice(here)] = marker_columns(
                rotations, self.data.marker, cols[here] - k, len(m.markers)
            )
        elif here.size and m.n_tool == 3:
            jac_v[:, :, as_slice(here)] = frames.tip_rotation[:, :, cols[here] - k]
        elif here.size and m.n_tool == 6:
            add(rot, pos, pin.Jexp6(pin.Motion(theta[k : k + 6]))[:, cols[here] - k], here)
        return out

    def rows(self, theta: np.ndarray, cols: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """Residuals and, if columns ``cols`` are asked for, their Jacobian (else an empty array)."""
        if chunked.is_large(self):
            return chunked.evaluate(self, theta, cols)
        return self.measurement.measure.rows(self, theta, cols)
