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
import scipy.linalg

from .errors import IdentifiabilityError

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
    """

    identifiable: np.ndarray
    singular_values: np.ndarray
    condition_number: float
    reasons: dict[str, str]

    @property
    def n_identifiable(self) -> int:
        """Number of identifiable parameters."""
        return int(self.identifiable.sum())


def parameter_scale(units: tuple[str, ...] | list[str], length: float) -> np.ndarray:
    """Natural size of each parameter: 1 for metres, ``1 / length`` for radians [rad/m]."""
    return np.array([1.0 / length if u == "rad" else 1.0 for u in units])


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
    if js.shape[0] > js.shape[1]:  # same Gram matrix, far fewer rows: R of a QR
        js = np.linalg.qr(js, mode="r")
    norms = np.linalg.norm(js, axis=0)
    if cand.size == 0 or not np.any(norms > 0):
        raise IdentifiabilityError(
            "no parameter has any effect on these measurements: the poses are too few or all alike"
        )
    sv = np.linalg.svd(js, compute_uv=False)
    tol = rcond * sv[0]
    rank = int(np.sum(sv > tol))
    _, piv = scipy.linalg.qr(js * preference[cand], mode="r", pivoting=True)
    keep_local = np.sort(piv[:rank])
    keep = cand[keep_local]
    mask = np.zeros(len(names), dtype=bool)
    mask[keep] = True
    kept = js[:, keep_local]
    sk = np.linalg.svd(kept, compute_uv=False)
    cond = float(sk[0] / sk[-1]) if sk[-1] > 0 else float("inf")
    for local, idx in enumerate(cand):
        if mask[idx]:
            continue
        col = js[:, local]
        if np.linalg.norm(col) <= tol:
            reasons[names[idx]] = "has no effect on these measurements"
            continue
        coef, *_ = np.linalg.lstsq(kept, col, rcond=None)
        weight = np.abs(coef) * np.linalg.norm(kept, axis=0)
        top = [names[keep[k]] for k in np.argsort(-weight)[:3] if weight[k] > 1e-3 * np.linalg.norm(col)]
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
        ref = np.linalg.qr(ref, mode="r")
    sv_ref = np.linalg.svd(ref, compute_uv=False)
    rank_ref = int(np.sum(sv_ref > rcond * sv_ref[0])) if sv_ref.size else 0
    _, piv = scipy.linalg.qr(ref, mode="r", pivoting=True)
    keep = np.sort(piv[:rank_ref])  # a set the varied poses identify
    js = jacobian[:, cand[keep]] * scale[cand[keep]]
    if js.shape[0] > js.shape[1]:
        js = np.linalg.qr(js, mode="r")
    _, sv, vt = np.linalg.svd(js, full_matrices=True)
    sv_full = np.zeros(len(keep))
    sv_full[: len(sv)] = sv
    blind = vt[sv_full <= rcond * max(float(sv_full[0]), 1e-300)]
    if blind.size == 0:
        return rank_ref, []
    share = np.sqrt(np.sum(blind**2, axis=0))
    order = np.argsort(-share)
    return rank_ref, [names[cand[keep[k]]] for k in order if share[k] > 0.2 * share[order[0]]]
