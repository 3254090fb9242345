"""The nominal model's registration-only fits, solved once per set of poses.

Every fit begins with the nominal geometry's registration, tool and points fitted alone
(:func:`pincal.identify.solver.register`), and its record holds the registration of the URDF as
it is (:func:`pincal.identify.solver.assess`). Neither depends on the parameters a fit frees nor
on the effects it holds (at their nominal zero): on one fold's poses, the diagnosis' baseline and
every candidate, in every round, ask for the same two answers. :data:`REGISTRATIONS` keeps the
last :data:`KEPT` of them by the problem's content (the robot, the parameterization, the poses,
the measurement set-up and the unknowns' natural sizes); a fit that asks again gets the answer
it would have computed (the URDF's registration: the same minimum, begun elsewhere).
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from collections.abc import Callable
from typing import Any

import numpy as np

from pincal.identify.measurements import Problem

#: Answers kept (a diagnosis on five folds asks for six sets of poses, two answers each).
KEPT = 64


def content_key(problem: Problem, scale: np.ndarray, what: str) -> tuple[Any, ...]:
    """What the registration-only fit ``what`` of ``problem`` depends on, as a hashable key:
    everything but the model's and the effects' unknowns, which it holds at zero."""
    m, data = problem.measurement, problem.data
    digest = hashlib.sha256()
    arrays = (data.q, data.points, data.quaternions, data.marker, m.pairs, m.marker_points)
    for array in (*arrays, m.instrument_T_base.homogeneous, m.tool.homogeneous, scale[problem.n_model :]):
        digest.update(b"none" if array is None else np.ascontiguousarray(array).tobytes() + b"|")
    setup = (m.kind, m.fit_instrument, m.fit_tool, m.rotation_weight, m.points, m.point_distances)
    model = (type(problem.model).__name__, problem.model.kind, problem.model.names)
    names = (tuple(problem.names[problem.n_model :]), tuple(getattr(data, "point_names", ()) or ()))
    return (what, setup, m.markers, m.marker_tips, model, names, digest.hexdigest())


class Registrations:
    """The last answers of registration-only fits, by content (:func:`content_key`)."""

    def __init__(self, kept: int = KEPT) -> None:
        self.kept = kept
        self._answers: OrderedDict[tuple[Any, ...], tuple[Any, np.ndarray]] = OrderedDict()

    def solved(
        self, problem: Problem, scale: np.ndarray, what: str, solve: Callable[[], np.ndarray]
    ) -> np.ndarray:
        """θ of ``problem`` from ``solve()``, or from the answer already found for the same
        content: the registration, points and tool of that answer, the rest at zero."""
        key = content_key(problem, scale, what)
        found = self._answers.get(key)
        if found is not None and found[0] is problem.model.robot:
            self._answers.move_to_end(key)
            theta = np.zeros(problem.n_params)
            theta[problem.n_model :] = found[1]
            return theta
        theta = solve()
        self._answers[key] = (problem.model.robot, theta[problem.n_model :].copy())
        if len(self._answers) > self.kept:
            self._answers.popitem(last=False)
        return theta

    def clear(self) -> None:
        """Forget every answer."""
        self._answers.clear()


#: The process's answers (each worker process has its own).
REGISTRATIONS = Registrations()
