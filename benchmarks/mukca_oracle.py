"""What the pull toward the URDF can reach at best on MUKCa's protocol: an oracle that sees the
held-out placements (``benchmarks/mukca.py --oracle``).

For each training placement, the calibration is repeated at every weight of
:data:`pincal.identify.prior.WEIGHTS` (the guard off: ``force_fit``), and judged on every other placement
of the same robot. Two oracles then choose with the held-out figures, which no honest rule may:

- the best single weight for the robot (the same weight for every training placement): the
  smallest median held-out MAE, and the smallest one with no pair worse than the URDF as is;
- the best weight per training placement, or the nominal model (what a guard could export),
  chosen jointly over the robot's placements (exhaustively, for robots of at most
  :data:`EXHAUSTIVE` placements): the smallest median with no pair worse than the URDF.

When even the second oracle stays above MUKCa's median, no choice of the pull's strength (nor of
the guard's verdict) meets both of issue 31's bars on that robot: something else in the model has
to change.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mukca_results import MUKCA_MEDIAN_MM

import pincal
import pincal.identify.evaluation
import pincal.identify.prior
from pincal.data.point_files import read_socket_folder
from pincal.identify.evaluation import evaluate
from pincal.identify.prior import WEIGHTS

#: Per-placement oracle only for robots with at most this many placements (options ** placements).
EXHAUSTIVE = 4


@dataclass(frozen=True)
class Oracle:
    """One robot's oracles [mm]: ``after[t][w]`` the held-out MAEs of training placement ``t`` at
    weight ``WEIGHTS[w]``, ``urdf[t]`` the URDF's on the same held-out placements."""

    robot: str
    after: tuple[tuple[tuple[float, ...], ...], ...]
    urdf: tuple[tuple[float, ...], ...]

    def single(self, no_worse: bool) -> tuple[float, float] | None:
        """(weight, median) of the best single weight (with no pair worse than the URDF)."""
        best = None
        for w, weight in enumerate(WEIGHTS):
            after = np.concatenate([a[w] for a in self.after])
            if no_worse and np.any(after > np.concatenate(self.urdf)):
                continue
            if best is None or np.median(after) < best[1]:
                best = (weight, float(np.median(after)))
        return best

    def per_placement(self) -> float | None:
        """The smallest median over a weight (or the nominal model) per training placement with
        no pair worse than the URDF; None when there are too many placements to search."""
        if len(self.after) > EXHAUSTIVE:
            return None
        options = []
        for after, urdf in zip(self.after, self.urdf):
            fine = [np.array(a) for a in after if np.all(np.array(a) <= np.array(urdf))]
            options.append([*fine, np.array(urdf)])  # the nominal model is never worse than itself
        medians = (float(np.median(np.concatenate(c))) for c in itertools.product(*options))
        return min(medians)


def oracle(robot_dir: Path, urdf: Path) -> Oracle:
    """The calibrations of every training placement at every weight, judged on the others."""
    robot = pincal.load_robot(urdf, tip="ball_link")
    places = {
        p.name: read_socket_folder(p, robot.joint_names) for p in sorted(robot_dir.iterdir()) if p.is_dir()
    }
    after, base = [], []
    distance = (("0", "1", 0.05),)
    for train, data in places.items():
        held = [d for name, d in places.items() if name != train]
        row = []
        for weight in WEIGHTS:
            pull = pincal.Pull(weight, force_fit=True)
            cal = pincal.calibrate(
                robot, data, params="auto", outliers=6.0, point_distances=distance, pull=pull
            )
            row.append(
                tuple(_mae(evaluate(cal.model, cal.measurement, cal.theta, h, cal.extension)) for h in held)
            )
        base.append(
            tuple(
                _mae(evaluate(cal.model, cal.urdf_measurement, cal.urdf_theta, h, cal.extension))
                for h in held
            )
        )
        after.append(tuple(row))
    return Oracle(robot_dir.name, tuple(after), tuple(base))


def _mae(stats: object) -> float:
    """The held-out MAE [mm] of an :class:`pincal.identify.evaluation.ErrorStats`."""
    return float(getattr(stats, "point_mae_mm", 0.0) or 0.0)


def oracle_table(oracles: list[Oracle]) -> str:
    """Per robot: the oracles' medians beside MUKCa's."""
    lines = [
        "\nwhat the pull can reach at best (oracles choosing with the held-out placements, guard off;"
        " benchmarks/mukca_oracle.py)",
        "",
        "| robot | best single weight: median [mm] | best single weight with no pair worse than the URDF"
        " | best weight or nominal per training placement, no pair worse: median [mm] | MUKCa [mm] |",
        "|---|---|---|---|---|",
    ]
    for o in oracles:
        any_w, safe = o.single(False), o.single(True)
        per = o.per_placement()
        ref = MUKCA_MEDIAN_MM.get(o.robot)
        lines.append(
            f"| {o.robot} | {_fig(any_w)} | {_fig(safe)} | {'-' if per is None else f'{per:.3f}'} "
            f"| {'-' if ref is None else f'{ref:.3f}'} |"
        )
    return "\n".join(lines)


def _fig(best: tuple[float, float] | None) -> str:
    """``median (weight w)``, or none."""
    return "none" if best is None else f"{best[1]:.3f} (weight {best[0]:.3g})"
