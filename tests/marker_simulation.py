"""Several markers simulated without pincal's model code: Pinocchio's own kinematics of a URDF whose
joint origins are perturbed, seen by an instrument at a random pose, with Gaussian noise.

Used by ``tests/test_markers.py`` (issue 41): the truth is written as a perturbed URDF model, each
marker a point on its frame, and the CSV has ``xK,yK,zK`` columns with some cells left empty.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin


def chain_model(urdf: str | Path, frames: Sequence[str]) -> tuple[pin.Model, list[str]]:
    """Pinocchio's model of ``urdf`` reduced to the joints between the base and any of ``frames``
    (the others locked at neutral), and those joints' names (actuated, in model order)."""
    full = pin.buildModelFromUrdf(str(urdf))
    keep: set[int] = set()
    for name in frames:
        j = full.frames[full.getFrameId(name)].parentJoint
        while j > 0:
            keep.add(j)
            j = full.parents[j]
    lock = [j for j in range(1, full.njoints) if j not in keep]
    model = pin.buildReducedModel(full, lock, pin.neutral(full)) if lock else full
    return model, list(model.names[1:])


def configuration(model: pin.Model, q: np.ndarray) -> np.ndarray:
    """Pinocchio's configuration for one value per joint."""
    out = pin.neutral(model)
    for k in range(1, model.njoints):
        joint = model.joints[k]
        if joint.nq == 2:
            out[joint.idx_q : joint.idx_q + 2] = (math.cos(q[k - 1]), math.sin(q[k - 1]))
        else:
            out[joint.idx_q] = q[k - 1]
    return out


def simulate(
    urdf: str | Path,
    markers: dict[str, tuple[str, Sequence[float]]],
    n_poses: int,
    noise_m: float = 3e-5,
    hidden: float = 0.05,
    seed: int = 0,
    error_m: float = 1e-3,
) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Joint names, joint values (N, n) [rad] and measured points (N, K, 3) [m] (NaN: hidden) of
    markers ``{label: (frame, point_m)}`` on a robot whose joint origins are off by about
    ``error_m`` (and ``error_m`` / 0.3 m in angle); ``hidden``: the share of rows with one
    marker hidden."""
    rng = np.random.default_rng(seed)
    nominal, names = chain_model(urdf, [f for f, _ in markers.values()])
    true = nominal.copy()
    for j in range(1, true.njoints):
        twist = np.concatenate([rng.normal(0, error_m, 3), rng.normal(0, error_m / 0.3, 3)])
        true.jointPlacements[j] = true.jointPlacements[j] * pin.exp6(pin.Motion(twist))
    lo, hi = nominal.lowerPositionLimit, nominal.upperPositionLimit
    lo = np.where(np.isfinite(lo) & (lo > -math.pi), lo, -math.pi)
    hi = np.where(np.isfinite(hi) & (hi < math.pi), hi, math.pi)
    q = np.array(
        [
            [
                rng.uniform(lo[true.joints[k].idx_q], hi[true.joints[k].idx_q]) * 0.9
                for k in range(1, true.njoints)
            ]
            for _ in range(n_poses)
        ]
    )
    reg = pin.SE3(pin.rpy.rpyToMatrix(*rng.uniform(-math.pi, math.pi, 3)), rng.uniform(-2, 2, 3))
    data = true.createData()
    points = np.empty((n_poses, len(markers), 3))
    for i in range(n_poses):
        pin.framesForwardKinematics(true, data, configuration(true, q[i]))
        for k, (frame, point) in enumerate(markers.values()):
            points[i, k] = reg.act(data.oMf[true.getFrameId(frame)].act(np.asarray(point, float)))
    points += rng.normal(0, noise_m, points.shape)
    rows = rng.choice(n_poses, size=int(round(hidden * n_poses)), replace=False)
    for r in rows:
        points[r, rng.integers(len(markers))] = np.nan
    return names, q, points


def write(
    path: str | Path, names: Sequence[str], q: np.ndarray, labels: Sequence[str], points: np.ndarray
) -> None:
    """A CSV with a column per joint and ``xK,yK,zK`` per marker (empty cells: hidden), in metres."""
    with open(path, "w", newline="") as f:
        out = csv.writer(f)
        out.writerow([*names, *(f"{a}{k}" for k in labels for a in "xyz")])
        for qi, pi in zip(q, points):
            out.writerow(
                [
                    *(repr(float(v)) for v in qi),
                    *("" if np.isnan(v) else repr(float(v)) for v in pi.reshape(-1)),
                ]
            )
