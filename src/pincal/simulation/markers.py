"""Several markers per pose simulated with pincal's own kinematics (issue 41).

:func:`simulate_markers` measures markers fixed on the true robot's frames (on a tree,
``robot.marker_frames`` puts each label on its frame), through the truth's instrument, with
Gaussian noise, and hides one marker in a share of the rows: the data a ``xK,yK,zK`` CSV holds
(:mod:`pincal.data.markers`), one row per marker seen.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from pincal.data.dataset import Dataset
from pincal.kinematics.chain import forward
from pincal.simulation.truth import TrueRobot


def simulate_markers(
    truth: TrueRobot,
    q: np.ndarray,
    points: np.ndarray,
    labels: Sequence[str] | None = None,
    noise: float = 3e-5,
    hidden: float = 0.0,
    seed: int = 0,
) -> Dataset:
    """The markers ``labels`` at ``points`` (K, 3) [m] on their frames, measured at joint values
    ``q`` (N, n) [rad or m].

    Args:
        truth: the true robot and instrument, and its hidden effect if any (its tool is not used:
            each marker is its own point).
        q: joint values.
        points: each marker's point on its frame [m].
        labels: the markers' labels (default 1..K); on a tree, the robot's ``marker_frames`` keys.
        noise: 1σ of each coordinate [m].
        hidden: the share of the poses with one marker (drawn at random) not seen.
        seed: seed of the noise and of what is hidden.
    """
    rng = np.random.default_rng(seed)
    robot = truth.robot
    names = tuple(labels) if labels is not None else tuple(str(k + 1) for k in range(len(points)))
    n_poses, k = len(q), len(names)
    seen = np.ones((n_poses, k), dtype=bool)
    for pose in rng.choice(n_poses, size=int(round(hidden * n_poses)), replace=False):
        seen[pose, rng.integers(k)] = False
    pose, marker = np.nonzero(seen)
    tips = np.array([robot.marker_tip(label) for label in names])[marker] if robot.is_tree else None
    reached = np.asarray(q, dtype=float)[pose]
    if truth.extension is not None and truth.effect is not None:  # a hidden effect, as TrueRobot.target
        reached = reached + truth.extension.joint_error(reached, truth.effect)
    frames = forward(truth.model.chain(truth.x), reached, tips)
    base = frames.tip_translation + np.einsum("nij,nj->ni", frames.tip_rotation, np.asarray(points)[marker])
    reg = truth.instrument_T_base
    measured = base @ reg.rotation.T + reg.translation + rng.normal(0.0, noise, base.shape)
    return Dataset(
        robot.joint_names,
        np.asarray(q, dtype=float)[pose],
        measured,
        rows=pose + 1,
        marker=marker,
        marker_names=names,
    )
