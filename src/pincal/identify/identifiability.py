"""Which parameters the data can identify: SVD for the rank, QR with column pivoting for the set.

The identification Jacobian is scaled so that its columns are comparable (a rotation [rad] is
worth its lever arm [m]); its singular values give the numerical rank ``r``; QR with column
pivoting picks ``r`` well-conditioned columns. Ties between exactly redundant columns are broken
by a mild preference: the instrument and tool unknowns first, then joints nearer the tip, so a
redundant base placement is reported as absorbed by the registration, and a joint's translation
along its own axis as absorbed by the next joint's placement (or, along a run of parallel axes,
by the last placement of the run). Every parameter left out gets a
reason: no effect on the measurements, or the kept parameters that absorb it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pincal.data.checks import spread
from pincal.data.dataset import Dataset
from pincal.errors import IdentifiabilityError
from pincal.identify.lm import triangle_of
from pincal.identify.measurements import Problem
from pincal.kinematics.chain import Chain, forward
from pincal.robot.robots import Robot

#: Singular values below ``RCOND · σ_max`` count as zero.
RCOND = 1e-6


@dataclass(frozen=True)
class Identifiability:
    """The identifiable set of a problem.

    Attributes:
        identifiable: (P,) mask of the parameters the solver estimates.
        singular_values: singular values of the scaled Jacobian over the candidate parameters.
        condition_number: of the scaled Jacobian restricted to the identifiable set.
        reasons: parameter name -> why it is held at its current value.
        gauges: motions of the whole set-up no measurement sees (fixed-point data), each holding
            a parameter (:mod:`pincal.identify.fixed_points`).
    """

    identifiable: np.ndarray
    singular_values: np.ndarray
    condition_number: float
    reasons: dict[str, str]
    gauges: tuple[str, ...] = ()

    @property
    def n_identifiable(self) -> int:
        """Number of identifiable parameters."""
        return int(self.identifiable.sum())


def parameter_scale(units: tuple[str, ...] | list[str], length: float) -> np.ndarray:
    """Natural size of each parameter: 1 for metres, ``1 / length`` for radians [rad/m]."""
    return np.array([1.0 / length if u == "rad" else 1.0 for u in units])


def pivots(mat: np.ndarray, count: int) -> np.ndarray:
    """The first ``count`` column pivots of a QR with column pivoting (LAPACK's ``geqp3``, as
    ``scipy.linalg.qr(pivoting=True)`` gives them): at each step the column whose part outside
    the columns already chosen is longest (the first of equals). Written here so that a
    calibration does not load SciPy's linear algebra (a quarter of a second of start-up)."""
    rest = np.array(mat, dtype=float)
    chosen: list[int] = []
    for _ in range(min(count, rest.shape[1])):
        norms = np.einsum("ij,ij->j", rest, rest)
        norms[chosen] = -1.0
        k = int(np.argmax(norms))
        if norms[k] <= 0.0:
            break
        chosen.append(k)
        unit = rest[:, k] / np.sqrt(norms[k])
        for _ in range(2):  # twice: the columns left stay orthogonal to the chosen ones
            rest -= np.outer(unit, unit @ rest)
    return np.array(chosen, dtype=int)


def analyse(
    jacobian: np.ndarray,
    names: tuple[str, ...],
    scale: np.ndarray,
    candidates: np.ndarray,
    preference: np.ndarray,
    held: dict[str, str] | None = None,
    rcond: float = RCOND,
) -> Identifiability:
    """Find the identifiable set.

    Args:
        jacobian: (m, P) identification Jacobian at the current estimate.
        names: the P parameter names.
        scale: (P,) natural size of each parameter (see :func:`parameter_scale`).
        candidates: (P,) mask of the parameters that may be estimated.
        preference: (P,) weights > 0 that break ties between redundant columns (larger wins).
        held: reasons for parameters that are not candidates.
        rcond: relative singular-value threshold of the rank.
    """
    reasons = dict(held or {})
    cand = np.flatnonzero(candidates)
    js = jacobian[:, cand] * scale[cand]
    if js.shape[0] > js.shape[1]:  # same Gram matrix, far fewer rows: R of a QR, by pieces (memory)
        js = triangle_of(js)
    norms = np.linalg.norm(js, axis=0)
    if cand.size == 0 or not np.any(norms > 0):
        raise IdentifiabilityError(
            "no parameter has any effect on these measurements: the poses are too few or all alike"
        )
    sv = np.linalg.svd(js, compute_uv=False)
    tol = rcond * sv[0]
    rank = int(np.sum(sv > tol))
    keep_local = np.sort(pivots(js * preference[cand], rank))
    keep = cand[keep_local]
    mask = np.zeros(len(names), dtype=bool)
    mask[keep] = True
    kept = js[:, keep_local]
    sk = np.linalg.svd(kept, compute_uv=False)
    cond = float(sk[0] / sk[-1]) if sk[-1] > 0 else float("inf")
    rest = np.array([local for local, idx in enumerate(cand) if not mask[idx]], dtype=int)
    if rest.size:  # what each left-out column is made of, all in one least-squares solve
        coefs = np.linalg.lstsq(kept, js[:, rest], rcond=None)[0]  # (kept, left out)
        weights = np.abs(coefs) * np.linalg.norm(kept, axis=0)[:, None]
    for j, local in enumerate(rest):
        idx, size = cand[local], float(np.linalg.norm(js[:, local]))
        if size <= tol:
            reasons[names[idx]] = "has no effect on these measurements"
            continue
        weight = weights[:, j]
        top = [names[keep[k]] for k in np.argsort(-weight)[:3] if weight[k] > 1e-3 * size]
        reasons[names[idx]] = "absorbed by " + ", ".join(top) if top else "not identifiable from these poses"
    return Identifiability(mask, sv, cond, reasons)


def lost_parameters(
    jacobian: np.ndarray,
    reference: np.ndarray,
    names: tuple[str, ...],
    scale: np.ndarray,
    candidates: np.ndarray,
    rcond: float = RCOND,
) -> tuple[int, list[str]]:
    """Parameters that varied poses identify but these poses do not.

    Args:
        jacobian: (m, P) identification Jacobian on the data.
        reference: (m', P) the same on varied poses (random within the joint limits).
        names: the P parameter names.
        scale: (P,) natural size of each parameter.
        candidates: (P,) mask of the parameters that may be estimated.
        rcond: relative singular-value threshold of the rank.

    Returns:
        The number of parameters the varied poses identify, and the names that carry the
        directions the data cannot see (empty when the data's rank is the varied poses' rank),
        largest share first.
    """
    cand = np.flatnonzero(candidates)
    ref = reference[:, cand] * scale[cand]
    if ref.shape[0] > ref.shape[1]:
        ref = triangle_of(ref)
    sv_ref = np.linalg.svd(ref, compute_uv=False)
    rank_ref = int(np.sum(sv_ref > rcond * sv_ref[0])) if sv_ref.size else 0
    keep = np.sort(pivots(ref, rank_ref))  # a set the varied poses identify
    js = jacobian[:, cand[keep]] * scale[cand[keep]]
    if js.shape[0] > js.shape[1]:
        js = triangle_of(js)
    _, sv, vt = np.linalg.svd(js, full_matrices=True)
    sv_full = np.zeros(len(keep))
    sv_full[: len(sv)] = sv
    blind = vt[sv_full <= rcond * max(float(sv_full[0]), 1e-300)]
    if blind.size == 0:
        return rank_ref, []
    share = np.sqrt(np.sum(blind**2, axis=0))
    order = np.argsort(-share)
    return rank_ref, [names[cand[keep[k]]] for k in order if share[k] > 0.2 * share[order[0]]]


#: Fewer residual rows than this many times the unknowns varied poses identify: the data's
#: blind directions are put down to the count of poses, not to their spread.
FEW_ROWS = 2


def check_rank(
    problem: Problem,
    theta: np.ndarray,
    jacobian: np.ndarray,
    scale: np.ndarray,
    candidates: np.ndarray,
    rcond: float,
) -> int:
    """How many parameters varied poses identify; an error if these poses identify fewer.

    The reference is the same problem on random poses within the joint limits, measured exactly;
    ``jacobian`` is the data's, at ``theta``.

    Raises:
        IdentifiabilityError: naming the parameters the data cannot see, and the likely cause.
    """
    robot, data = problem.model.robot, problem.data
    n_ref = max(60, 2 * problem.n_params)
    q_ref = robot.random_configurations(n_ref, np.random.default_rng(0), margin=0.05)
    reference = problem.measuring(theta, q_ref)
    rank, lost = lost_parameters(jacobian, reference.jacobian(theta), problem.names, scale, candidates, rcond)
    if not lost or len(jacobian) <= rank:  # too few equations: the caller says so
        return rank
    span = np.ptp(data.q, axis=0)
    still = [j for j, s, p in zip(robot.joint_names, span, robot.prismatic) if s < (1e-4 if p else 1e-3)]
    if len(data) < 3 or len(still) == robot.n_joints:
        cause = "all the poses are alike (no joint moves)"
    elif still:
        cause = f"joint(s) {', '.join(still)} never move"
    elif len(jacobian) < FEW_ROWS * rank:
        cause = (
            f"{len(data)} poses give {len(jacobian)} equations, fewer than {FEW_ROWS} per unknown: too few "
            "to tell every correction apart (measure more poses; pincal plan ROBOT N chooses them)"
        )
    else:
        cause = f"{len(data)} poses do not vary the joints enough"
    names = ", ".join(lost[:8]) + (f" and {len(lost) - 8} more" if len(lost) > 8 else "")
    raise IdentifiabilityError(
        f"the data cannot identify {names}, which varied poses would: {cause}. Measure poses that "
        "move every joint over its range, fit fewer parameters (model=offsets), or pass "
        "partial=True to fit only what this data identifies"
    )


def workspace_length(data: Dataset, robot: Robot | None = None) -> float:
    """RMS distance of the measured points from their centroid [m] (at least 5 cm); for
    fixed-point data, whose points are few, the RMS distance of the nominal tip from the base."""
    if data.labels is not None and robot is not None:
        tips = forward(Chain.nominal(robot), data.q).tip_translation
        return max(0.05, float(np.sqrt(np.mean(np.sum(tips**2, axis=1)))))
    return max(0.05, spread(data.points))


def natural_scale(problem: Problem) -> np.ndarray:
    """Natural size of each unknown of a problem (see :class:`Setup`)."""
    robot, data, extension = problem.model.robot, problem.data, problem.extension
    length = workspace_length(data, robot)
    scale = parameter_scale(problem.units, length)
    if extension is not None:  # natural size of an effect: moving the joint by 1 mm at the lever arm
        rms = np.sqrt(np.mean(problem.regressors**2, axis=0))
        lever = np.where(np.asarray(robot.prismatic)[problem.param_joints], 1.0, length)
        scale[problem.model.n_params : problem.n_model] = 1.0 / (lever * np.where(rms > 0, rms, 1.0))
    return scale
