"""ISO 9283 pose accuracy (AP) and pose repeatability (RP) from repeated visits of commanded poses.

For each commanded pose, visited n times (ISO 9283's protocol: 30 cycles to 5 poses P1-P5 on a
diagonal plane of a cube in the workspace), with attained positions P_j:

- the barycentre G = mean of P_j;
- AP = |G - C|, C the commanded position; APx, APy, APz the components of G - C in base axes;
- RP = l̄ + 3 S_l, l_j = |P_j - G|, S_l their sample standard deviation (n - 1 in the denominator).

With orientations, each attained orientation is written relative to the commanded one in base axes,
R_j R_c^T = Rz(c_j) Ry(b_j) Rx(a_j) (fixed axes X, then Y, then Z): APa = mean of a_j (likewise
b, c) and RPa = 3 S_a, S_a the sample standard deviation of a_j. For the small deviations of a robot
these are ISO's differences of attained and commanded angles, without their singularities.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from pincal.errors import DataError

#: Visits per pose ISO 9283 asks for.
ISO_CYCLES = 30
#: What the commanded position is: the program's Cartesian position, or a model's forward kinematics.
COMMANDS = ("programmed", "nominal_model", "calibrated_model")
ANGLE_CONVENTION = (
    "a, b, c [deg]: R_attained R_commanded^T = Rz(c) Ry(b) Rx(a), rotations about the base X, Y, Z axes"
)


def repeatability(attained: np.ndarray) -> float:
    """RP = l̄ + 3 S_l of positions (n, 3), in their unit."""
    distances = np.linalg.norm(attained - attained.mean(axis=0), axis=1)
    return float(distances.mean() + 3.0 * distances.std(ddof=1))


@dataclass(frozen=True)
class PoseFigures:
    """ISO 9283 figures of one commanded pose.

    Attributes:
        pose: its name.
        commanded: (3,) commanded position [m]; attained: (n, 3) attained positions [m].
        angles: (n, 3) attained orientation relative to the commanded one, a, b, c [rad], or None.
    """

    pose: str
    commanded: np.ndarray
    attained: np.ndarray
    angles: np.ndarray | None = None

    @property
    def n(self) -> int:
        """Visits."""
        return len(self.attained)

    @property
    def barycentre(self) -> np.ndarray:
        """Mean attained position [m]."""
        return self.attained.mean(axis=0)

    @property
    def ap_mm(self) -> float:
        """Pose accuracy AP [mm]."""
        return float(np.linalg.norm(self.barycentre - self.commanded)) * 1e3

    @property
    def rp_mm(self) -> float:
        """Pose repeatability RP [mm]."""
        return repeatability(self.attained) * 1e3

    def to_dict(self) -> dict[str, Any]:
        """The figures as the report's JSON holds them (mm and degrees)."""
        dx, dy, dz = (self.barycentre - self.commanded) * 1e3
        out: dict[str, Any] = {"pose": self.pose, "n": self.n, "AP_mm": self.ap_mm}
        out.update(APx_mm=float(dx), APy_mm=float(dy), APz_mm=float(dz), RP_mm=self.rp_mm)
        if self.angles is not None:
            deg = np.rad2deg(self.angles)
            for k, axis in enumerate("abc"):
                out[f"AP{axis}_deg"] = float(deg[:, k].mean())
            for k, axis in enumerate("abc"):
                out[f"RP{axis}_deg"] = float(3.0 * deg[:, k].std(ddof=1))
        return out


@dataclass(frozen=True)
class AccuracyResult:
    """ISO 9283 figures of every commanded pose.

    Attributes:
        command: what the commanded position is (one of :data:`COMMANDS`).
        poses: the figures of each pose, in order of first visit.
    """

    command: str
    poses: tuple[PoseFigures, ...]

    @property
    def has_orientation(self) -> bool:
        """Whether orientation figures were computed."""
        return self.poses[0].angles is not None

    @property
    def iso_conformant(self) -> bool:
        """Whether every pose was visited at least :data:`ISO_CYCLES` times."""
        return all(p.n >= ISO_CYCLES for p in self.poses)

    def to_dict(self) -> dict[str, Any]:
        """The report's ``iso9283`` object."""
        out: dict[str, Any] = {"command": self.command, "poses": [p.to_dict() for p in self.poses]}
        out["AP_mm_max"] = max(p.ap_mm for p in self.poses)
        out["RP_mm_max"] = max(p.rp_mm for p in self.poses)
        out["iso_conformant"] = self.iso_conformant
        out["angle_convention"] = ANGLE_CONVENTION if self.has_orientation else None
        return out

    def table(self) -> str:
        """The figures as a text table (mm, and degrees with orientations)."""
        head = f"{'pose':>8} {'n':>4} {'AP':>9} {'APx':>9} {'APy':>9} {'APz':>9} {'RP':>9}  [mm]"
        lines = [
            f"ISO 9283 pose accuracy and repeatability, commanded by the {self.command.replace('_', ' ')}",
            head,
        ]
        for p in self.poses:
            d = p.to_dict()
            values = " ".join(f"{d[k]:9.4f}" for k in ("AP_mm", "APx_mm", "APy_mm", "APz_mm", "RP_mm"))
            angles = ""
            if p.angles is not None:
                angles = "  RPa,b,c " + ", ".join(f"{d[f'RP{a}_deg']:.4f}" for a in "abc") + " deg"
            lines.append(f"{p.pose:>8} {p.n:>4} {values}{angles}")
        return "\n".join(lines)


def relative_angles(attained: np.ndarray, commanded: np.ndarray) -> np.ndarray:
    """a, b, c (n, 3) [rad] of rotations (n, 3, 3) relative to ``commanded`` (3, 3), in base axes."""
    return Rotation.from_matrix(attained @ commanded.T).as_euler("xyz")


def iso9283(
    labels: Sequence[str],
    commanded: np.ndarray,
    attained: np.ndarray,
    command: str,
    commanded_rotations: np.ndarray | None = None,
    attained_rotations: np.ndarray | None = None,
) -> AccuracyResult:
    """ISO 9283 AP and RP of each pose (see the module docstring).

    Args:
        labels: (N,) the commanded pose each visit was to.
        commanded: (N, 3) the commanded position of each visit, base frame [m] (averaged per pose).
        attained: (N, 3) the attained position of each visit, base frame [m].
        command: what ``commanded`` is (one of :data:`COMMANDS`).
        commanded_rotations, attained_rotations: (N, 3, 3) orientations for the angle figures, or None.

    Raises:
        DataError: a pose visited fewer than 2 times, or no visit at all.
    """
    if command not in COMMANDS:
        raise ValueError(f"command must be one of {COMMANDS}, got {command!r}")
    names = list(dict.fromkeys(str(label) for label in labels))
    if not names:
        raise DataError("no visits: the data has no rows")
    labels_arr = np.array([str(label) for label in labels])
    once = [name for name in names if np.count_nonzero(labels_arr == name) < 2]
    if once:
        raise DataError(
            f"pose(s) {', '.join(once)} visited once: ISO 9283's repeatability needs 2 visits or more of each"
        )
    poses = []
    for name in names:
        visits = np.flatnonzero(labels_arr == name)
        angles = None
        if commanded_rotations is not None and attained_rotations is not None:
            mean_command = Rotation.from_matrix(commanded_rotations[visits]).mean().as_matrix()
            angles = relative_angles(attained_rotations[visits], mean_command)
        poses.append(PoseFigures(name, commanded[visits].mean(axis=0), attained[visits], angles))
    return AccuracyResult(command, tuple(poses))


def too_few_cycles(result: AccuracyResult) -> str | None:
    """A warning when a pose has fewer visits than ISO 9283's 30 cycles, else None."""
    few = [f"{p.pose} ({p.n})" for p in result.poses if p.n < ISO_CYCLES]
    if not few:
        return None
    return (
        f"poses visited fewer than {ISO_CYCLES} times: {', '.join(few)}: the figures are computed as "
        "ISO 9283 defines them but are not ISO-conformant"
    )
