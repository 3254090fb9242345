"""Identification rows of candidate poses, as a plan sees them: whitened, scaled, per tool guess.

:func:`pincal.planning.plan.plan_poses` judges a design by the information matrix of the fit it will
feed. :class:`Information` builds the rows of each candidate pose: the identification Jacobian
:func:`pincal.calibrate` uses (model, extension, registration or fixed points, tool columns),
taken at the nominal geometry, restricted to the parameters the candidates together identify,
with columns scaled by their natural size (a rotation is worth its lever arm, see
:func:`pincal.identify.identifiability.parameter_scale`) and rows whitened by the noise.

The measured point on the tip is rarely known exactly, and the rows depend on it (its lever
arm). Rows are therefore built for several *hypotheses* of where it is: the guess, and the
vertices of a regular tetrahedron of radius ``tolerance`` around it; a plan is judged on all of
them at once (:mod:`pincal.planning.design`), so that it does not depend on the guess being exact.

The task weights ``W_h = mean_t J_tᵀ J_t`` are the same Jacobian at the task poses (the tip's
position; a distance between two task poses for distance data; for fixed points, the tip's
position in the base frame, the sockets' columns left out), for I-optimality.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from pincal.data.dataset import Dataset
from pincal.identify.fixed_points import PointDistance
from pincal.identify.identifiability import analyse, parameter_scale
from pincal.identify.kinds import get_kind
from pincal.identify.measurement import Measurement
from pincal.identify.measurements import Problem
from pincal.kinematics.chain import Chain, forward
from pincal.kinematics.effects import Extension
from pincal.kinematics.mdh import make_model
from pincal.robot.robots import Robot

#: Unit vectors to the vertices of a regular tetrahedron: the tool hypotheses around the guess.
TETRAHEDRON = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]]) / np.sqrt(3.0)


def tool_hypotheses(tool: np.ndarray | None, tolerance: float) -> list[np.ndarray]:
    """Where the measured point on the tip may be (3,) [m]: the guess ``tool`` and 4 points
    ``tolerance`` [m] around it; without a guess, the 4 points around the tip's origin (a point
    on the last joint's axis would hide what any real, off-axis point shows)."""
    centre = np.zeros(3) if tool is None else np.asarray(tool, float)
    around = [centre + tolerance * d for d in TETRAHEDRON] if tolerance > 0.0 else []
    return around if tool is None and around else [centre, *around]


class Information:
    """Whitened, column-scaled identification rows of candidate poses, per tool hypothesis.

    Attributes:
        names, units: every unknown of the fit; ``free`` marks the identifiable ones (the most
            any hypothesis identifies); ``best`` is that hypothesis, ``guess`` its point [m].
        rows: per hypothesis, (M, r, P) rows of each candidate on the identifiable unknowns.
        tips: per hypothesis, (M, 3) the measured point at each candidate [m] (base frame).
        priors: per hypothesis, (P, P) the information before any pose (a ridge, known distances).
    """

    def __init__(
        self,
        robot: Robot,
        model: str,
        measure: str,
        q: np.ndarray,
        tools: list[np.ndarray],
        extension: Extension | None = None,
        noise: float = 3e-5,
        rot_noise: float = 1.5e-4,
        weight: float = 0.1,
        labels: np.ndarray | None = None,
        distances: tuple[PointDistance, ...] = (),
    ) -> None:
        self.robot, self.measure, self.extension, self.noise = robot, measure, extension, noise
        self.kind = get_kind(measure)
        self.mdl = make_model(model, robot)
        self.labels, self.distances, self.weight = labels, distances, weight
        n_points = 0 if labels is None else int(labels.max()) + 1
        self.point_names = tuple(str(k) for k in range(n_points))
        self.sigma = np.array([noise] * 3 + [weight * rot_noise] * (3 if self.kind.orientation else 0))
        raws = [self.raw(q, tool) for tool in tools]
        problem = raws[0][2]
        self.names, self.units, self.n_model = problem.names, problem.units, problem.n_model
        self.tips = [r[1] for r in raws]
        spread = np.sqrt(np.mean(np.sum((self.tips[0] - self.tips[0].mean(0)) ** 2, axis=1)))
        self.scale = parameter_scale(self.units, max(0.05, float(spread)))
        known = raws[0][3]
        preference = np.concatenate(
            [1.0 + 0.05 * np.linspace(0.0, 1.0, self.n_model), np.full(len(self.units) - self.n_model, 2.0)]
        )
        candidates = np.array([name not in self.mdl.held for name in self.names])
        held = dict(self.mdl.held)
        # the largest set a hypothesis identifies: a guess on the last joint's axis hides what
        # any real, off-axis point shows
        sets = [
            analyse(
                np.concatenate([self.for_analysis(r[0][:100], r[1][:100]), known]),
                self.names,
                self.scale,
                candidates,
                preference,
                held,
            ).identifiable
            for r in raws
        ]
        best = int(np.argmax([free.sum() for free in sets]))
        self.best = best
        self.free, self.guess = sets[best], tools[best]
        self.rows = [self.whiten(r[0]) for r in raws]
        ridge = 1e-8 * float(np.mean([np.einsum("mrp,mrp->", g, g) / len(g) for g in self.rows]))
        self.priors = [ridge * np.eye(int(self.free.sum())) + self.prior(r[3]) for r in raws]

    def extend(self, q: np.ndarray, tools: list[np.ndarray]) -> None:
        """Append candidates ``q`` (M, n) [rad or m], their rows and points per hypothesis ``tools``
        (the same as the constructor's); not for fixed points (each candidate is in a socket)."""
        for h, tool in enumerate(tools):
            rows, tips, _, _ = self.raw(q, tool)
            self.rows[h] = np.concatenate([self.rows[h], self.whiten(rows)])
            self.tips[h] = np.concatenate([self.tips[h], tips])

    def measurement(self, tool: np.ndarray, kind: str | None = None) -> Measurement:
        """The fit's measurement model with the measured point ``tool`` (3,) [m]."""
        kind = kind or ("position" if self.kind.by_pairs else self.measure)
        fixed_points = get_kind(kind).fixed_points
        return Measurement(
            kind,
            fit_instrument=get_kind(kind).registered and self.kind.registered,
            tool=pin.SE3(np.eye(3), tool),
            rotation_weight=self.weight,
            points=self.point_names if fixed_points else (),
            point_distances=self.distances if fixed_points else (),
        )

    def raw(
        self, q: np.ndarray, tool: np.ndarray, kind: str | None = None, labels: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, Problem, np.ndarray]:
        """Per-pose rows (N, r, P) at the nominal geometry, the measured points (N, 3) [m], the
        problem, and the rows of known distances (k, P); ``labels``: the socket of each pose
        (default: the candidates')."""
        frames = forward(Chain.nominal(self.robot), q)
        tips = frames.tip_translation + frames.tip_rotation @ tool
        meas = self.measurement(tool, kind)
        quats = None
        if meas.measure.orientation:
            quats = np.array([pin.Quaternion(r).coeffs()[[3, 0, 1, 2]] for r in frames.tip_rotation])
        labels = (self.labels if labels is None else labels) if meas.measure.fixed_points else None
        names = self.point_names if meas.measure.fixed_points else ()
        data = Dataset(self.robot.joint_names, q, tips, quats, labels=labels, point_names=names)
        problem = Problem(self.mdl, meas, data, self.extension)
        jac = problem.jacobian(problem.initial_theta())
        n_known = len(meas.point_distances)
        known = jac[len(jac) - n_known :] / np.sqrt(len(q))  # a known distance's row, unweighted
        per_pose = jac[: len(jac) - n_known].reshape(len(q), -1, problem.n_params)
        return per_pose, tips, problem, known

    def for_analysis(self, rows: np.ndarray, points: np.ndarray) -> np.ndarray:
        """The rows stacked as the fit sees them (pairs of poses for distance data)."""
        if not self.kind.by_pairs:
            return rows.reshape(-1, rows.shape[2])
        i, j = np.triu_indices(len(points), 1)
        return pair_rows(rows[i], rows[j], points[i] - points[j])

    def whiten(self, rows: np.ndarray) -> np.ndarray:
        """Rows on the identifiable unknowns, scaled, divided by their noise."""
        scaled = rows[:, :, self.free] * self.scale[self.free]
        sigma = self.sigma if not self.kind.by_pairs else np.full(3, self.noise * np.sqrt(2))
        return scaled / sigma[None, :, None]

    def prior(self, known: np.ndarray) -> np.ndarray:
        """Information of the known distances, as certain as the noise of one row."""
        rows = known[:, self.free] * self.scale[self.free] / self.noise
        return rows.T @ rows

    def candidate_rows(self, h: int, index: np.ndarray, chosen: Sequence[int]) -> np.ndarray:
        """Rows (len(index), r, P) each candidate would add to the ``chosen`` poses (hypothesis h)."""
        g = self.rows[h]
        if not self.kind.by_pairs:
            return g[index]
        chosen_ = np.asarray(chosen, dtype=int)
        tips = self.tips[h]
        return pair_rows(g[index][:, None], g[chosen_][None], tips[index][:, None] - tips[chosen_][None])

    def task_weights(self, q_task: np.ndarray, tools: list[np.ndarray]) -> list[np.ndarray]:
        """``W_h`` (P, P): ``mean_t J_tᵀ J_t`` over the task poses (or pairs of them, distance data),
        so that ``tr(W cov)`` is the mean squared error of the predicted point (distance) [m²]."""
        out = []
        for tool in tools:
            kind = "position" if not self.kind.registered else None
            rows, tips, problem, _ = self.raw(q_task, tool, kind)
            jt = np.zeros((len(q_task), 3, len(self.names)))
            where = [self.names.index(n) for n in problem.names if n in self.names]
            jt[:, :, where] = rows[:, :3, [problem.names.index(self.names[k]) for k in where]]
            jt = jt[:, :, self.free] * self.scale[self.free]
            if self.kind.by_pairs:
                i, j = np.triu_indices(len(q_task), 1)
                jt = pair_rows(jt[i], jt[j], tips[i] - tips[j])[:, None]
            out.append(np.einsum("trp,trq->pq", jt, jt) / len(jt))
        return out


def pair_rows(gi: np.ndarray, gj: np.ndarray, diff: np.ndarray) -> np.ndarray:
    """Rows of the distances between pairs of poses from their points' rows and separations."""
    with np.errstate(invalid="ignore", divide="ignore"):  # a pose paired with itself: no row
        u = np.nan_to_num(diff / np.linalg.norm(diff, axis=-1, keepdims=True))
    return np.einsum("...k,...kp->...p", u, gi - gj)
