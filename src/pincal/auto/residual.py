"""What the final model still gets wrong: structure above the instrument's noise, or noise alone.

The verdict is decided on the fitted poses, so that a user with one data set gets it:

1. The final model's K-fold cross-validated errors, linearised at its fit (as
   :mod:`pincal.auto.screening`): each fold's poses predicted by the fit of the other folds.
2. The instrument's noise ``σ`` (RMS per axis): given (``noise_mm``), else estimated from
   repeated poses (the same commanded joints measured more than once, at least
   :data:`MIN_NOISE_DOF` degrees of freedom), else unknown.
3. With ``σ``: the same cross-validation run on pure noise of that size (Monte Carlo through the
   same linear operator, so the loss of degrees of freedom to the fit and the registration is
   counted exactly) gives what the errors would be if the model were right. An estimated ``σ`` is
   itself uncertain: each draw's ``σ²`` is drawn from its posterior ``ν s² / χ²_ν`` (``ν`` its
   degrees of freedom), so that a few repeated poses do not pass for an exact noise figure. For
   pose data, the orientation rows get noise too, of the size the fit's own orientation residuals
   give. The observed mean square above the 99th percentile of those draws, by more than
   (:data:`MIN_SHARE` × the noise floor)², is ``unexplained``; what it exceeds the draws' mean by
   is the structure's mean square. Otherwise ``explained``.
4. Without ``σ``: a model-free test of whether the held-out errors still depend on the joint
   angles (the K nearest poses in joint space predict a pose's error better than a random
   permutation of the errors does, p < 0.01): ``unexplained`` if they do, the noise then
   estimated from what the neighbours cannot predict; else ``undetermined`` (the data cannot
   tell structure from noise), never ``explained``.

Errors are per pose the norm of the 3-D position error (for distance data, per pair the distance
error), as in the report's ``ERR``; the noise floor is the RMS of those norms under noise alone.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from pincal.auto.balance import Delivered
from pincal.data.dataset import Dataset
from pincal.identify.calibration import Calibration
from pincal.identify.folds import pose_folds

#: Structure smaller than this share of the noise floor is not called unexplained (a noise
#: figure a few per cent off must not turn a right model into a finding).
MIN_SHARE = 0.3
#: Monte Carlo draws of pure noise.
DRAWS = 200
#: Neighbours of the model-free test, and its permutations.
NEIGHBOURS, PERMUTATIONS = 5, 200
#: Joint values closer than this [rad or m] are the same commanded pose.
SAME_POSE = 1e-6
#: Repeated poses giving fewer degrees of freedom than this give no noise figure (the verdict is
#: then the model-free test's: ``undetermined`` unless the errors depend on the joints).
MIN_NOISE_DOF = 9
#: What ``unexplained_mm`` is, for the report.
UNEXPLAINED_MEANS = (
    "RMS over the fitted poses of the norm of the 3-D error above the noise (per pair, of the "
    "distance error), from the cross-validated errors [mm]; noise_mm is per axis: noise alone "
    "gives a norm of about sqrt(3) x noise_mm"
)


@dataclass(frozen=True)
class ResidualVerdict:
    """Whether the final model leaves structure above the noise.

    Attributes:
        noise_mm: the instrument's noise, RMS per axis [mm] (given or estimated; NaN if unknown).
        noise_source: ``given`` or ``estimated``.
        unexplained_mm: RMS of the structure above the noise, per pose (or pair) [mm]; 0 when none.
        verdict: ``explained``, ``unexplained`` or ``undetermined``.
        cv_rms_mm: the final model's cross-validated RMS (linearised) [mm].
        floor_mm: what that RMS would be with noise alone [mm] (NaN without a noise figure).
        how: how the noise was known and the verdict reached, in words.
        errors: the held-out error vectors per pose (N, 3) [m] (None for distance data).
        variable: without a noise figure, the variable the errors were found to depend on (a
            joint's name, ``pose order`` or ``all joints``; None when none was found).
    """

    noise_mm: float
    noise_source: str
    unexplained_mm: float
    verdict: str
    cv_rms_mm: float
    floor_mm: float
    how: str
    errors: np.ndarray | None = None
    variable: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """The report's ``residual`` object (no NaN: an unknown figure is None)."""

        def finite(x: float) -> float | None:
            return float(x) if np.isfinite(x) else None

        return {
            "noise_mm": finite(self.noise_mm),
            "noise_source": self.noise_source,
            "unexplained_mm": float(self.unexplained_mm),
            "unexplained_means": UNEXPLAINED_MEANS,
            "verdict": self.verdict,
            "cv_rms_mm": finite(self.cv_rms_mm),
            "noise_floor_mm": finite(self.floor_mm),
            "how": self.how,
        }

    def sentence(self) -> str:
        """What remains, in one clause."""
        if self.verdict == "explained":
            return f"explained: what remains is the instrument's noise ({self.noise_mm:.3g} mm per axis)"
        if self.verdict == "unexplained":
            return (
                f"{self.unexplained_mm:.3g} mm unexplained above the noise "
                f"({self.noise_source} {self.noise_mm:.3g} mm per axis)"
            )
        return (
            "undetermined: the data cannot tell structure from noise; give the instrument's noise "
            "(noise_mm=MM, RMS per axis) or measure a few poses twice to judge what remains"
        )


class HeldOut:
    """The linearised K-fold cross-validation of a fit, for any residual vector: each fold refits
    what the delivered fit fitted, as it fitted it (:class:`pincal.auto.balance.Delivered`)."""

    def __init__(self, cal: Calibration, data: Dataset, folds: int, seed: int) -> None:
        self.problem = cal.problem(data)
        self.kind = cal.measurement.measure
        weight = 0.0 if cal.balance is None else cal.balance.weight
        self.fit = Delivered(self.problem, cal.theta, cal.identifiability.identifiable, weight)
        self.residuals, self.alone_residuals = self.fit.full, self.fit.alone
        poses = self.kind.owners(self.problem)
        self.rotation_noise = _rotation_noise(self.problem, self.residuals, cal)
        self.parts: list[np.ndarray] = [
            np.asarray(np.isin(poses, held).any(axis=1))
            for held in pose_folds(data, min(folds, len(data)), seed)
        ]

    def errors(self, residuals: np.ndarray, alone: np.ndarray | None = None) -> np.ndarray:
        """Held-out error rows (held-out rows, M) [m] for residual columns (rows, M) of the model
        with its effect, and ``alone`` those of the model without it (default: the same)."""
        alone = residuals if alone is None else alone
        return np.concatenate([self.fit.errors(test, residuals, alone)[0] for test in self.parts])

    def per_pose(self, rows: np.ndarray) -> np.ndarray:
        """Held-out rows (R, M) -> per pose the 3-D position error vectors (N, 3, M), or per pair
        the distance errors (P, 1, M)."""
        order = np.concatenate([np.flatnonzero(t) for t in self.parts])
        return self.kind.per_pose(rows, self.kind.owners(self.problem)[order, 0])

    def noise_rows(self, sigma: float, draws: int, rng: np.random.Generator) -> np.ndarray:
        """Residual rows (rows, draws) [m] that noise of ``sigma`` per axis on each measured
        point makes."""
        noise = rng.normal(scale=sigma, size=(len(self.problem.data), 3, draws))
        rows = self.kind.noise_rows(self.problem, len(self.residuals), noise)
        if self.rotation_noise > 0:  # pose data: the orientation rows are noisy too
            n, width = len(self.problem.data), self.kind.width
            turned = rng.normal(scale=self.rotation_noise, size=(n, width - 3, draws))
            rows[: n * width].reshape(n, width, draws)[:, 3:, :] += turned
        return rows


def _rotation_noise(problem: Any, residuals: np.ndarray, cal: Calibration) -> float:
    """RMS per orientation row [m: radians times the rotation weight] of the fit's orientation
    residuals, counted for the degrees of freedom the fit took; 0 without orientation rows."""
    kind = cal.measurement.measure
    if not kind.orientation:
        return 0.0
    n, width = len(problem.data), kind.width
    turned = residuals[: n * width].reshape(n, width)[:, 3:]
    kept = 1.0 - int(cal.identifiability.identifiable.sum()) / max(len(residuals), 1)
    return float(np.sqrt(np.mean(turned**2) / max(kept, 0.1)))


def mean_square(per_pose: np.ndarray) -> np.ndarray:
    """Mean over poses of the squared error norms, per column (M,) [m²]."""
    return np.mean(np.sum(per_pose**2, axis=1), axis=0)


def repeated_noise(data: Dataset) -> float | None:
    """Noise per axis [m] from poses measured more than once (None: no repeated pose)."""
    found = noise_estimate(data)
    return None if found is None else found[0]


def noise_estimate(data: Dataset) -> tuple[float, int] | None:
    """Noise per axis [m] from poses measured more than once and its degrees of freedom (one per
    coordinate of each measurement beyond a pose's first); None: fewer than :data:`MIN_NOISE_DOF`."""
    if data.points is None or len(data) < 2:
        return None
    key = np.round(data.q / SAME_POSE).astype(np.int64)
    if data.marker is not None:  # several markers of one pose are not repeats
        key = np.column_stack([key, data.marker])
    _, group, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    group = group.reshape(-1)
    dof = int(np.sum(counts - 1))
    if 3 * dof < MIN_NOISE_DOF:
        return None
    means = np.zeros((len(counts), 3))
    np.add.at(means, group, data.points)
    means /= counts[:, None]
    scatter = float(np.sum((data.points - means[group]) ** 2))
    return float(np.sqrt(scatter / (3 * dof))), 3 * dof


def _with_noise(
    held: HeldOut, observed: np.ndarray, sigma: float, source: str, seed: int, dof: int | None = None
) -> ResidualVerdict:
    """The verdict against noise ``sigma`` per axis [m]; estimated with ``dof`` degrees of
    freedom, each draw's noise from its posterior (``σ² = dof s² / χ²_dof``)."""
    rng = np.random.default_rng(seed)
    rows = held.noise_rows(sigma, DRAWS, rng)
    if dof is not None:
        rows = rows * np.sqrt(dof / rng.chisquare(dof, DRAWS))
    null = mean_square(held.per_pose(held.errors(rows)))
    ms = float(mean_square(observed[:, :, None])[0])
    excess = ms - float(np.mean(null))
    floor = float(np.sqrt(np.mean(null)))
    structured = ms > float(np.quantile(null, 0.99)) and excess > (MIN_SHARE * floor) ** 2
    verdict = "unexplained" if structured else "explained"
    drawn = "" if dof is None else f", its uncertainty from {dof} degrees of freedom drawn in each"
    how = (
        f"cross-validated RMS {np.sqrt(ms) * 1e3:.3g} mm against {floor * 1e3:.3g} mm for noise "
        f"alone ({source} noise, {DRAWS} draws through the same cross-validation{drawn})"
    )
    unexplained = float(np.sqrt(excess)) * 1e3 if structured else 0.0
    rms_mm = np.sqrt(ms) * 1e3
    return ResidualVerdict(sigma * 1e3, source, unexplained, verdict, rms_mm, floor * 1e3, how, observed)


def _neighbour_errors(errors: np.ndarray, neighbours: np.ndarray) -> np.ndarray:
    """Mean square of what the mean of each pose's neighbours leaves of its error [m²], for each
    of the error sets ``errors`` (N, 3, S): (S,)."""
    predicted = errors[neighbours].mean(axis=1)
    return np.mean(np.sum((errors - predicted) ** 2, axis=1), axis=0)


def _nearest(values: np.ndarray, k: int) -> np.ndarray:
    """Each row's ``k`` nearest other rows (N, k) of ``values`` (N, d), each column scaled (in no
    particular order: a mean over them is taken)."""
    scale = values.std(axis=0)
    z = values / np.where(scale > 0, scale, 1.0)
    dist = np.sum((z[:, None, :] - z[None, :, :]) ** 2, axis=2)
    np.fill_diagonal(dist, np.inf)
    return np.argpartition(dist, k - 1, axis=1)[:, :k]


def dependence(data: Dataset, errors: np.ndarray, seed: int = 0) -> tuple[float, str, float]:
    """A model-free test of whether the errors (N, 3) [m] depend on the poses: the K nearest
    poses along one variable (the pose order, one joint, or all joints) predict each pose's error.

    Returns:
        The p-value of the best variable's prediction against permutations of the errors (the
        same best-of choice made on each), that variable's name, and the noise per axis [m]
        that its prediction leaves.
    """
    k = min(NEIGHBOURS, len(errors) - 1)
    variables = {"pose order": np.arange(len(errors), dtype=float)[:, None], "all joints": data.q}
    variables.update({name: data.q[:, [j]] for j, name in enumerate(data.joint_names)})
    rng = np.random.default_rng(seed)
    orders = [np.arange(len(errors))] + [rng.permutation(len(errors)) for _ in range(PERMUTATIONS)]
    every = np.stack([errors[order] for order in orders], axis=2)  # the errors, then each permutation
    scores = {name: _neighbour_errors(every, _nearest(v, k)) for name, v in variables.items()}
    observed, name = min((float(s[0]), name) for name, s in scores.items())
    null = np.min(np.array(list(scores.values()))[:, 1:], axis=0)  # the same best-of choice
    p_value = (1 + np.sum(null <= observed)) / (1 + PERMUTATIONS)
    return float(p_value), name, float(np.sqrt(observed / (3 * (1 + 1 / k))))


#: Above this many poses (position or pose data) the verdict is decided on a random subset.
VERDICT_POSES = 1_500


def _sampled(cal: Calibration, data: Dataset, seed: int) -> tuple[Dataset, str]:
    """``data``, or :data:`VERDICT_POSES` random poses of it when large, and what was done."""
    if len(data) <= VERDICT_POSES or not cal.measurement.measure.registered:
        return data, ""
    keep = np.sort(np.random.default_rng(seed).choice(len(data), VERDICT_POSES, replace=False))
    return data.subset(keep), f"; on {VERDICT_POSES} random poses of the {len(data)}"


def residual_verdict(
    cal: Calibration,
    data: Dataset,
    noise_mm: float | None = None,
    folds: int = 5,
    seed: int = 0,
) -> ResidualVerdict:
    """Whether ``cal`` leaves structure above the noise on its fitted poses ``data``.

    Args:
        cal: the final calibration.
        data: the poses it fitted.
        noise_mm: the instrument's noise, RMS per axis [mm], if known.
        folds, seed: the cross-validation's K and seed.
    """
    data, note = _sampled(cal, data, seed)
    verdict = _decided(cal, data, noise_mm, folds, seed)
    return replace(verdict, how=verdict.how + note)


def _decided(
    cal: Calibration, data: Dataset, noise_mm: float | None, folds: int, seed: int
) -> ResidualVerdict:
    """:func:`residual_verdict` on the poses ``data``."""
    held = HeldOut(cal, data, folds, seed)
    rows = held.errors(held.residuals[:, None], held.alone_residuals[:, None])
    observed = held.per_pose(rows)[:, :, 0]
    if noise_mm is not None:
        return _with_noise(held, observed, noise_mm * 1e-3, "given", seed)
    repeated = noise_estimate(data) if not held.kind.fixed_points else None
    if repeated is not None:
        return _with_noise(held, observed, repeated[0], "estimated", seed, repeated[1])
    rms = float(np.sqrt(mean_square(observed[:, :, None])[0]))
    if held.kind.by_pairs or len(data) < 3 * NEIGHBOURS:
        why = "no noise figure, no repeated pose, and no per-pose errors to test"
        return ResidualVerdict(np.nan, "estimated", 0.0, "undetermined", rms * 1e3, np.nan, why)
    p_value, variable, noise = dependence(data, observed, seed)
    if p_value >= 0.01:
        why = "no noise figure, no repeated pose; the errors show no dependence on the joints"
        return ResidualVerdict(
            noise * 1e3, "estimated", 0.0, "undetermined", rms * 1e3, np.nan, why, observed
        )
    unexplained = np.sqrt(max(rms**2 - 3 * noise**2, 0.0)) * 1e3
    why = f"no noise figure, no repeated pose; the errors depend on the {variable} (p = {p_value:.2g})"
    floor = np.sqrt(3) * noise * 1e3
    return ResidualVerdict(
        noise * 1e3, "estimated", unexplained, "unexplained", rms * 1e3, floor, why, observed, variable
    )
