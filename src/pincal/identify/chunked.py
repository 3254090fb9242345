"""Large data sets in blocks of poses: the fit's memory stays bounded whatever the number of poses.

Position and pose residuals are pose by pose, so a :class:`~pincal.identify.measurements.Problem` on N
poses is the stack of the problems on blocks of :data:`BLOCK_POSES` poses. Above
:data:`LARGE_POSES` poses (position or pose data), a problem works block by block:

- its residuals, Jacobian rows and target frames are computed one block at a time (the joint
  frames of one block are held, never those of all poses: 13 frames of a 6-joint arm are 1.2 GB
  at a million poses);
- the Levenberg-Marquardt step (:mod:`pincal.identify.lm`) uses the triangle R of the QR of ``[J r]``,
  built block by block as the QR of ``[R; next block]`` (the same triangle as one QR of the
  whole matrix, up to the signs of its rows), so the 3N × P Jacobian is never held; each of
  :data:`GROUPS` runs of blocks makes its own triangle, on a core of its own, and the triangles
  are merged by one more QR (the normal equations of the pull's evidence and of the check across
  the joint limits are summed the same way);
- the parameters' standard deviations use ``JᵀJ`` summed block by block;
- the identifiable set, and a fit with a robust loss (outlier screening), are found on a random
  subset of :data:`SAMPLE_POSES` poses (seed 0): which parameters the poses identify is a
  property of how the poses spread, which such a subset shares; the robust fit only scores the
  poses, and every pose is then scored.

Distance and fixed-point data (rows of pairs, points shared by rows) are not split.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any, ClassVar, Protocol, TypeVar

import numpy as np

from pincal.data.dataset import Dataset
from pincal.identify.lm import soft_l1_rows, soft_l1_slopes, triangle_of
from pincal.identify.rows import ProblemRows
from pincal.kinematics.chain import Frames
from pincal.workers import parallel_map


class _Posed(Protocol):
    """A set-up (:class:`pincal.identify.solver.Setup`): a dataclass with a problem."""

    __dataclass_fields__: ClassVar[dict[str, Any]]

    @property
    def problem(self) -> ProblemRows:
        """Its problem."""


_Setup = TypeVar("_Setup", bound=_Posed)
_T = TypeVar("_T")

#: Poses above which a problem works block by block.
LARGE_POSES = 50_000
#: Poses per block.
BLOCK_POSES = 20_000
#: Poses of the random subset the identifiable set and a robust fit are found on.
SAMPLE_POSES = 50_000
#: Runs of consecutive blocks whose triangles and normal equations are made apart and then merged
#: (side by side on two cores; one process makes the same groups, so the same answer).
GROUPS = 2


def is_large(problem: ProblemRows, above: int | None = None) -> bool:
    """Whether ``problem`` works block by block (see the module docstring): more than ``above``
    poses (default :data:`LARGE_POSES`) of a kind split by poses, and not solved whole."""
    if not getattr(problem, "blockwise", True):  # a problem that says it is solved whole
        return False
    return problem.measurement.measure.registered and len(problem.data) > (above or LARGE_POSES)


def blocks(problem: ProblemRows) -> list[ProblemRows]:
    """The problems on consecutive blocks of :data:`BLOCK_POSES` poses (made once per problem)."""
    made = problem.__dict__.get("_blocks")
    if made is None:
        made = [problem.on(part) for part in data_blocks(problem.data)]
        problem.__dict__["_blocks"] = made
    return made


def release(problem: ProblemRows) -> None:
    """Drop ``problem``'s blocks and what they keep (the tip frames of their last geometry, 96 B
    a pose), as a call that starts again on other poses does."""
    problem.__dict__.pop("_blocks", None)
    problem.__dict__.pop("_residuals", None)


def data_blocks(data: Dataset) -> list[Dataset]:
    """``data``'s consecutive blocks of :data:`BLOCK_POSES` poses, made once per data set: the
    problems on the same poses (the registration's, the fit's, the guard's) share them, and each
    holds views of ``data``'s arrays, not a copy of its poses."""
    made = data.__dict__.get("_blocks")
    if made is None:
        n = len(data)
        made = [data.subset(slice(a, min(a + BLOCK_POSES, n))) for a in range(0, n, BLOCK_POSES)]
        data.__dict__["_blocks"] = made
    return made


def _forget(block: ProblemRows) -> None:
    """Drop a block's kept frames once used (kept for every block, they would add up to all poses')."""
    block.forget_frames()


def evaluate(
    problem: ProblemRows, theta: np.ndarray, cols: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray]:
    """Residuals and (for ``cols``) Jacobian rows of a large problem, block by block."""
    if cols is None:
        return residuals(problem, theta), np.empty((0, 0))
    res, jac = [], []
    for block in blocks(problem):
        r, j = block.rows(theta, cols)
        _forget(block)
        res.append(r)
        jac.append(j)
    return np.concatenate(res), np.concatenate(jac)


def residuals(problem: ProblemRows, theta: np.ndarray) -> np.ndarray:
    """The residuals of a large problem at ``theta`` (read-only), block by block in this process
    (in two worker processes, which send them back, 10⁶ pose rows took longer); the last answer
    is kept: a fit often begins where a check just evaluated it (the warm start after the
    registration's minimum), 2 of 17 passes over every pose at 200,000 pose rows."""
    key = theta.tobytes()
    kept = problem.__dict__.get("_residuals")
    if kept is not None and kept[0] == key:
        return kept[1]
    parts = []
    for block in blocks(problem):
        parts.append(block.rows(theta, None)[0])
        _forget(block)
    res = np.concatenate(parts)
    res.flags.writeable = False
    problem.__dict__["_residuals"] = (key, res)
    return res


def target_frames(
    problem: ProblemRows, theta: np.ndarray, in_instrument: bool
) -> tuple[Frames, np.ndarray, np.ndarray]:
    """:meth:`ProblemRows.target_frames` of a large problem: its frames hold the tip frame only."""
    tips_r, tips_p, rots, poss = [], [], [], []
    for block in blocks(problem):
        frames, rot, pos = block.target_frames(theta, in_instrument, tip_only=True)
        _forget(block)
        tips_r.append(frames.tip_rotation.copy())  # a view would keep every frame of the block
        tips_p.append(frames.tip_translation.copy())
        rots.append(rot)
        poss.append(pos)
    tip = Frames(np.concatenate(tips_r)[None], np.concatenate(tips_p)[None])
    return tip, np.concatenate(rots), np.concatenate(poss)


def triangle(
    problem: ProblemRows,
    theta: np.ndarray,
    free: np.ndarray,
    x_scale: np.ndarray,
    extra: tuple[np.ndarray, np.ndarray],
    f_scale: float | None = None,
) -> np.ndarray:
    """The triangle R (P + 1, P + 1) of the QR of ``[J · x_scale, r]`` over the free columns,
    with the rows ``extra`` (their Jacobian and residuals) below the data's, block by block; with
    ``f_scale`` [m], of the soft-L1 loss's rooted rows (:func:`pincal.identify.lm.soft_l1_roots`)."""
    cols = np.arange(problem.n_params)[free]

    def group(parts: list[ProblemRows]) -> np.ndarray:
        tri = None
        for block in parts:
            r, j = block.rows(theta, cols)
            _forget(block)
            tri = triangle_of(_stacked(j, r, x_scale, f_scale), tri)
        assert tri is not None
        return tri

    tri = triangle_of(np.vstack(_grouped(problem, group)))  # the groups' triangles merged
    jac, res = extra
    return triangle_of(_stacked(jac, res, x_scale, f_scale), tri)


def _grouped(problem: ProblemRows, each: Callable[[list[ProblemRows]], _T]) -> list[_T]:
    """``each`` of the :data:`GROUPS` runs of consecutive blocks of ``problem``, side by side in
    worker processes (:func:`pincal.workers.parallel_map`: the same answers in one process)."""
    parts = blocks(problem)
    size = -(-len(parts) // GROUPS)
    groups = [parts[a : a + size] for a in range(0, len(parts), size)]
    return parallel_map(lambda k: each(groups[k]), len(groups))


def _stacked(jac: np.ndarray, res: np.ndarray, x_scale: np.ndarray, f_scale: float | None) -> np.ndarray:
    """``[J · x_scale, r]``, of the rooted rows when ``f_scale`` is given."""
    if f_scale is None:
        return np.column_stack([jac * x_scale, res])
    rooted = jac * soft_l1_slopes(res, f_scale)[:, None] * x_scale
    return np.column_stack([rooted, soft_l1_rows(res, f_scale)])


def normal_terms(
    problem: ProblemRows, theta: np.ndarray, free: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float, int]:
    """``JᵀJ`` (P, P), ``Jᵀr`` (P,), ``rᵀr`` and the number of rows, over the free columns, block
    by block for a large problem (the Jacobian of every pose is never held)."""
    cols = np.arange(problem.n_params)[free]
    gram, grad, rr, rows = block_sums(problem, theta, cols, _normal)
    return gram, grad, float(rr), int(rows)


def _normal(res: np.ndarray, jac: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, int]:
    """One block's terms of :func:`normal_terms`."""
    return jac.T @ jac, jac.T @ res, float(res @ res), len(res)


#: Terms of a block's rows summed over a problem's (:func:`block_sums`): arrays and numbers.
Terms = tuple[Any, ...]
Summand = Callable[[np.ndarray, np.ndarray], Terms]


def block_sums(problem: ProblemRows, theta: np.ndarray, cols: np.ndarray, summand: Summand) -> Terms:
    """The sum over ``problem``'s rows of ``summand(residuals, Jacobian rows)`` (a tuple of arrays
    and numbers; columns ``cols``): for a large problem, block by block (each block's rows are
    residual rows of whole poses, in order), the :data:`GROUPS` runs of blocks side by side."""
    if not is_large(problem):
        return summand(*problem.rows(theta, cols))

    def group(parts: list[ProblemRows]) -> Terms:
        total: Terms = ()
        for block in parts:
            terms = summand(*block.rows(theta, cols))
            _forget(block)
            total = _added(total, terms)
        return total

    total: Terms = ()
    for terms in _grouped(problem, group):
        total = _added(total, terms)
    return total


def _added(total: Terms, terms: Terms) -> Terms:
    """``terms`` added to ``total`` term by term (``()``: nothing yet)."""
    return terms if not total else tuple(a + b for a, b in zip(total, terms))


def lm_triangle(
    problem: ProblemRows,
    full: Callable[[np.ndarray], np.ndarray],
    free: np.ndarray,
    x_scale: np.ndarray,
    prior: tuple[np.ndarray, np.ndarray],
    f_scale: float | None = None,
) -> Callable[[np.ndarray], np.ndarray] | None:
    """For :func:`pincal.identify.lm.levenberg_marquardt` on a large problem (else None): ``sub`` (the free
    unknowns) -> the triangle of ``[J r]`` with the solver's prior rows ``w · (sub - nominal)`` on
    the first free unknowns below the data's (``prior``: their weights ``w`` and nominal values).
    With ``f_scale`` [m], of the soft-L1 loss's rooted rows, already above :data:`BLOCK_POSES`
    poses: the robust refit runs on a subset of :data:`SAMPLE_POSES`, whose Jacobian and its
    rooted, scaled and stacked copies took 0.6 GB at once."""
    if not is_large(problem, BLOCK_POSES if f_scale is not None else None):
        return None
    weights, nominal = prior
    held = np.eye(len(weights), len(x_scale)) * weights[:, None]

    def make(sub: np.ndarray) -> np.ndarray:
        extra = (held, weights * (sub[: len(weights)] - nominal))
        return triangle(problem, full(sub), free, x_scale, extra, f_scale)

    return make


def sampled(setup: _Setup) -> _Setup:
    """``setup`` on a random subset of :data:`SAMPLE_POSES` poses when its problem is large."""
    return replace(setup, problem=sample(setup.problem)) if is_large(setup.problem) else setup


def sample_poses(data: Dataset) -> Dataset:
    """``data``, or a random subset of :data:`SAMPLE_POSES` of its poses (seed 0, in row order)."""
    if len(data) <= SAMPLE_POSES:
        return data
    return data.subset(np.sort(np.random.default_rng(0).choice(len(data), SAMPLE_POSES, replace=False)))


def sample(problem: ProblemRows) -> ProblemRows:
    """The problem on a random subset of :data:`SAMPLE_POSES` poses (seed 0, in row order)."""
    return problem.on(sample_poses(problem.data))
