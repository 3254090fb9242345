"""How identification time grows with the number of poses and of joints.

For each robot, simulates a seeded laser-tracker experiment (:func:`pincal.simulate`: 0.5 mm /
0.5 mrad joint-origin errors, 1 mrad joint offsets, unknown tracker pose and reflector, 0.03 mm
noise) with 100 to 10,000 poses and times ``pincal.calibrate(robot, data, "placements")`` on
position data: the median of ``--repeat`` runs, wall clock by :func:`time.perf_counter`. Writes a
log-log plot. :mod:`real_data` calls :func:`scaling` and :func:`plot` for the README.

Usage::

    OPENBLAS_NUM_THREADS=1 python benchmarks/identification_scaling.py [--tiago-urdf PATH]
        [--out benchmarks/figures/identification_scaling.png] [--repeat 3]
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path
from typing import Any

import pincal

#: Numbers of simulated poses.
POSES = (100, 300, 1000, 3000, 10000)
#: Default output of the plot.
FIGURE = Path(__file__).resolve().parent / "figures" / "identification_scaling.png"
#: TIAGo's measured chain: the torso's prismatic joint and the seven arm joints.
TIAGO_JOINTS = ("torso_lift_joint", *(f"arm_{k}_joint" for k in range(1, 8)))
TIAGO_TIP = "wrist_ft_tool_link"


def load_tiago(urdf: str | Path) -> pincal.Robot:
    """TIAGo from base_footprint to the wrist force-torque tool frame (8 joints)."""
    return pincal.load_robot(str(urdf), tip=TIAGO_TIP, joints=TIAGO_JOINTS)


def median_time(robot: pincal.Robot, data: pincal.Dataset, repeat: int, model: str = "placements") -> float:
    """Median wall-clock time [s] of ``repeat`` calls of :func:`pincal.calibrate`."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        pincal.calibrate(robot, data, model)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def scaling(
    robots: dict[str, pincal.Robot], poses: tuple[int, ...] = POSES, repeat: int = 3, seed: int = 0
) -> list[dict[str, Any]]:
    """Median identification time [s] for each robot and number of poses.

    Returns:
        One record per (robot, poses): ``robot``, ``joints``, ``poses``, ``seconds``.
    """
    out = []
    for name, robot in robots.items():
        _, data, _ = pincal.simulate(robot, n_fit=max(poses), n_test=0, seed=seed)
        pincal.calibrate(robot, data.subset(range(50)), "placements")  # warm-up
        for n in poses:
            seconds = median_time(robot, data.subset(range(n)), repeat)
            out.append({"robot": name, "joints": robot.n_joints, "poses": n, "seconds": seconds})
    return out


def plot(records: list[dict[str, Any]], path: str | Path, marks: list[dict[str, Any]] | None = None) -> Path:
    """Log-log plot of identification time against poses, one line per robot.

    Args:
        records: the output of :func:`scaling`.
        path: the PNG to write.
        marks: single points to add (``label``, ``poses``, ``seconds``, ``marker``).
    """
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.4, 4.2))
    ax = fig.add_subplot()
    for name in dict.fromkeys(r["robot"] for r in records):
        rows = [r for r in records if r["robot"] == name]
        ax.plot(
            [r["poses"] for r in rows],
            [r["seconds"] for r in rows],
            "o-",
            label=f"pincal, {name} ({rows[0]['joints']} joints), simulated",
        )
    for mark in marks or []:
        ax.plot(mark["poses"], mark["seconds"], mark.get("marker", "s"), ms=8, label=mark["label"])
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("measured poses (position data)")
    ax.set_ylabel("identification time [s] (median)")
    ax.set_title("pincal.calibrate(..., 'placements'): time vs poses and joints")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path


def main() -> None:
    """Time, print the table and write the plot."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tiago-urdf", type=Path, help="tiago_48_schunk.urdf, to add TIAGo's 8-joint chain")
    parser.add_argument("--out", type=Path, default=FIGURE, help="the PNG to write")
    parser.add_argument("--repeat", type=int, default=3, help="timed runs per point (median)")
    args = parser.parse_args()
    robots = {"ur5": pincal.load_robot("ur5"), "panda": pincal.load_robot("panda")}
    if args.tiago_urdf:
        robots["tiago"] = load_tiago(args.tiago_urdf)
    records = scaling(robots, repeat=args.repeat)
    for r in records:
        print(f"{r['robot']:6s} {r['joints']} joints {r['poses']:6d} poses {r['seconds']:8.3f} s")
    print(f"plot written to {plot(records, args.out)}")


if __name__ == "__main__":
    main()
