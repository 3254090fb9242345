"""TIAGo's four markers (issue 41): one model for all four, against each marker calibrated alone.

FIGAROH's TIAGo files hold four points of the hand's motion-capture rigid body (``x1..z4``: BL,
BR, TR, TL); its protocol, and pincal's other benchmarks, use point 1 only. Here
:func:`pincal.calibrate` (as ``pincal calibrate`` calls it: ``--params auto``, ``--extend auto``,
``--outliers 6``) is fitted on the training day twice over:

- **four markers**: all four points at once, one registration, each point on the tool unknown;
- **one marker**: each point alone (the one-marker path), four calibrations;

and each marker is judged on the validation day (RMS of the 3-D error of that marker's points,
mm). Acceptance: each marker's held-out RMS of the four-marker fit within 2 % of its one-marker
calibration's, or better. What the other markers added is said beside: the equations per
unknown, the parameters identified, and the rigid body's own check (the distances between the
four points, constant on a rigid body, as the instrument measured them and as the fit placed the
points).

The four points are virtual points of one rigid body the mocap system tracks: its noise is one
pose error of that body, so the four points' errors are correlated (not four independent
measurements).

Usage::

    python benchmarks/tiago_markers.py DATASETS_DIR [--markdown docs/results/generated/tiago_markers.md]
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from itertools import combinations
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from identification_scaling import load_tiago  # noqa: E402
from markdown_page import command_line, table, text_block, write_page  # noqa: E402

import pincal  # noqa: E402
from pincal.data.dataset import Dataset, read_csv  # noqa: E402
from pincal.identify.outliers import THRESHOLD  # noqa: E402

TRAIN = "train_2021-11-30.csv"
VALIDATION = "validation_2021-11-26.csv"
#: Acceptance: a marker's held-out RMS of the four-marker fit over its one-marker calibration's.
WITHIN = 1.02


@dataclass(frozen=True)
class MarkerRow:
    """One marker: held-out RMS [mm] of the four-marker fit and of its one-marker calibration."""

    label: str
    four_mm: float
    one_mm: float
    one_params: int

    @property
    def ratio(self) -> float:
        """Four-marker over one-marker held-out RMS."""
        return self.four_mm / self.one_mm

    @property
    def holds(self) -> bool:
        """Within :data:`WITHIN` of the one-marker calibration, or better."""
        return self.ratio <= WITHIN


#: What ``pincal calibrate`` passes by default (the API's own defaults fit every parameter and no
#: effect).
DEFAULTS: dict[str, Any] = {"params": "auto", "extension": "auto", "outliers": THRESHOLD}


def one_marker(data: Dataset, k: int) -> Dataset:
    """Marker ``k``'s rows as a one-marker dataset (``x,y,z``)."""
    mine = np.flatnonzero(data.marker == k)
    return Dataset(data.joint_names, data.q[mine], data.points[mine], rows=data.row_numbers[mine])


def rigid_check(cal: pincal.Calibration, data: Dataset) -> list[tuple[str, float, float, float]]:
    """Per pair of markers: the measured distance's mean and spread over the poses [mm], and the
    fitted points' distance [mm] (a rigid body keeps it constant)."""
    points = cal.markers()
    out = []
    for a, b in combinations(range(len(data.marker_names)), 2):
        la, lb = data.marker_names[a], data.marker_names[b]
        rows = np.intersect1d(data.row_numbers[data.marker == a], data.row_numbers[data.marker == b])
        pa = data.points[(data.marker == a) & np.isin(data.row_numbers, rows)]
        pb = data.points[(data.marker == b) & np.isin(data.row_numbers, rows)]
        measured = np.linalg.norm(pa - pb, axis=1) * 1e3
        fitted = float(np.linalg.norm(points[la] - points[lb])) * 1e3
        out.append((f"{la}-{lb}", float(measured.mean()), float(measured.std()), fitted))
    return out


def held_mm(cal: pincal.Calibration) -> float:
    """The held-out RMS [mm] of a calibration fitted with held-out poses."""
    assert cal.test_after is not None
    return cal.test_after.rms_mm


def exported(cal: pincal.Calibration) -> str:
    """What the guard let the calibration export: ``fit``, or ``nominal`` (the URDF's geometry
    with the registration and tool fitted: the fit was not reliably better on its own poses)."""
    return "fit" if cal.guard is None or cal.guard.kept_fit else "nominal"


def run(datasets: Path) -> tuple[list[MarkerRow], list[str]]:
    """The table's rows and the lines of what the other markers added."""
    folder = datasets / "tiago_qualisys"
    robot = load_tiago(folder / "tiago_48_schunk.urdf")
    train = read_csv(folder / TRAIN, robot.joint_names, prismatic=robot.prismatic)
    val = read_csv(folder / VALIDATION, robot.joint_names, prismatic=robot.prismatic)
    four = pincal.calibrate(robot, train, test=val, **DEFAULTS)
    rows, ones = [], []
    for k, label in enumerate(train.marker_names):
        one = pincal.calibrate(robot, one_marker(train, k), test=one_marker(val, k), **DEFAULTS)
        ones.append(one)
        rows.append(
            MarkerRow(
                label,
                four.test_markers[label].rms_mm,
                held_mm(one),
                one.identifiability.n_identifiable,
            )
        )
    n_unknowns = four.identifiability.n_identifiable
    added = [
        f"four markers: {len(train)} points of {train.n_poses} poses ({3 * len(train)} equations) for "
        f"{n_unknowns} identified unknowns (one registration, {len(train.marker_names)} points on the tool); "
        f"one marker: {3 * train.n_poses} equations for {ones[0].identifiability.n_identifiable} "
        f"(marker 1)",
        f"held-out RMS over every marker's points: four-marker fit {held_mm(four):.3f} mm, "
        f"the four one-marker calibrations {np.sqrt(np.mean([held_mm(o) ** 2 for o in ones])):.3f} mm",
        f"cause kept: four markers {four.extension.label if four.extension else 'none'}; one marker "
        + ", ".join(o.extension.label if o.extension else "none" for o in ones),
        f"exported (the guard): four markers {exported(four)}; one marker "
        + ", ".join(exported(o) for o in ones),
        "rigid body check (training day): pair, measured distance mean ± std over the poses, the fitted "
        "points' distance [mm]",
    ]
    added += [f"  {p}: {m:.2f} ± {s:.2f}, fitted {f:.2f}" for p, m, s, f in rigid_check(four, train)]
    return rows, added


def main(argv: list[str] | None = None) -> None:
    """Print the table (and write it as Markdown with ``--markdown``)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("datasets", type=Path, metavar="DATASETS_DIR", help="the folder ../shared/datasets")
    parser.add_argument("--markdown", type=Path, help="write the results page's figures here")
    args = parser.parse_args(argv)
    rows, added = run(args.datasets)
    header = [
        "marker",
        "one-marker calibration [mm]",
        "four-marker fit [mm]",
        "ratio",
        f"within {WITHIN - 1:.0%}",
    ]
    body = [
        [r.label, f"{r.one_mm:.3f}", f"{r.four_mm:.3f}", f"{r.ratio:.4f}", "yes" if r.holds else "no"]
        for r in rows
    ]
    text = "held-out RMS on the validation day (fitted on the training day)\n"
    text += "\n".join(f"{' | '.join(row)}" for row in body) + "\n" + "\n".join(added)
    print(text)
    if args.markdown is not None:
        names = {str(args.datasets).rstrip("/"): "DATASETS_DIR"}
        command = command_line("tiago_markers.py", sys.argv[1:] if argv is None else argv, names)
        write_page(args.markdown, command, [table(header, body), "", text_block("\n".join(added))])


if __name__ == "__main__":
    main()
