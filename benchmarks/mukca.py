"""MUKCa's socket data: calibration without an instrument, judged on other placements.

For each robot in ``DATASETS_DIR/mukca/data`` (layout in ``DATASETS_DIR/SOURCES.md``; nothing is
copied from it) and each placement of the socket fixture, this calibrates on that placement
alone, as ``pincal calibrate URDF PLACEMENT_DIR --tip ball_link --point-distance 0,1=50
--units mm`` does (the same :func:`pincal.calibrate` call: parameters chosen by cross-validation,
outlier screening), and judges the model on every other placement of the same robot with MUKCa's
protocol: the sockets' positions are the means of that placement's own rows, the robot model is
the calibrated one. It prints, per robot, the held-out mean absolute error (each row's distance
from its socket's mean tip position) of the URDF as it is and calibrated (median and worst over
train/test combinations), the distance error ``|distance between the socket means - 50 mm|``,
what ``diagnose`` names on each placement, and the time per calibration. Then, leaving one
placement out, it calibrates on all the others at once (a folder of the placement folders, as
``pincal calibrate URDF ROBOT_DIR`` reads it) and judges the one left out; and it prints the
floor: one model fitted on every placement, judged on each (what a model can reach at best on
the data it was fitted to). It saves a plot of every placement's held-out error before and after.

It prints first the protocol's summary per robot beside MUKCa's own figures (median and worst
held-out MAE, pairs worse than the URDF as is, the pull's weight chosen, the guard's refusals:
:mod:`mukca_results`), and ``--markdown`` writes it with the other tables as the results page.

Usage::

    python benchmarks/mukca.py DATASETS_DIR [--plot PNG] [--json FILE] [--model placements]
        [--protocol-only] [--oracle] [--markdown docs/results/mukca.md]
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections import Counter  # noqa: E402
from dataclasses import dataclass, replace  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402
from mukca_oracle import oracle, oracle_table  # noqa: E402
from mukca_results import Pair, plot, protocol_rows, worse_pairs, write_json, write_page  # noqa: E402

import pincal  # noqa: E402
from pincal.auto.diagnose import diagnose  # noqa: E402
from pincal.data.point_files import read_socket_folder  # noqa: E402
from pincal.identify.evaluation import ErrorStats, evaluate  # noqa: E402
from pincal.identify.fixed_points import point_means  # noqa: E402
from pincal.identify.measurements import Problem  # noqa: E402
from pincal.report.report import placements  # noqa: E402

URDFS = {"panda": "panda.urdf", "kuka": "iiwa14.urdf", "dinova": "gen3lite.urdf"}
DISTANCE = (("0", "1", 0.05),)  # [m] between the sockets
OPTIONS: dict[str, Any] = dict(params="auto", outliers=6.0, point_distances=DISTANCE)  # the command's
FIGURE = Path(__file__).parent / "figures" / "mukca.png"


@dataclass(frozen=True)
class Judged:
    """One calibration, judged on another placement: held-out figures [mm]."""

    robot: str
    train: str
    test: str
    urdf: ErrorStats
    after: ErrorStats
    seconds: float
    weight: float
    kept_fit: bool

    def pair(self) -> Pair:
        """The protocol's record of this pair."""
        urdf, after = float(self.urdf.point_mae_mm or 0.0), float(self.after.point_mae_mm or 0.0)
        return Pair(self.robot, self.train, self.test, urdf, after, self.weight, self.kept_fit, self.seconds)


@dataclass(frozen=True)
class Pooled:
    """A placement judged with the model calibrated on all the robot's other placements together
    (``held``), and with the one calibrated on every placement, itself included (``floor``: what
    a rigid model can reach on this placement at best) [mm]."""

    robot: str
    test: str
    held: ErrorStats
    floor: ErrorStats
    seconds: float


def placements_folder(places: list[Path], folder: Path) -> Path:
    """A folder of links to ``places``: the data set ``pincal calibrate FOLDER`` reads as every
    placement at once."""
    folder.mkdir(parents=True)
    for place in places:
        (folder / place.name).symlink_to(place.resolve(), target_is_directory=True)
    return folder


def pooled(
    robot_dir: Path, urdf: Path, model: str, folder: Path
) -> tuple[list[Pooled], list[str], pincal.Calibration]:
    """Leave one placement out: calibrate on all the others at once (the robot's folder of
    placements, as ``pincal calibrate URDF ROBOT_DIR`` reads it), judge on the one left out; the
    placements the calibration on every placement names as suspect (its warnings); and that
    calibration (the floor model)."""
    robot = pincal.load_robot(urdf, tip="ball_link")
    places = sorted(p for p in robot_dir.iterdir() if p.is_dir())
    all_rows = read_socket_folder(robot_dir, robot.joint_names)
    every = pincal.calibrate(robot, all_rows, model, **OPTIONS)
    suspects = [
        f"{robot_dir.name}/{p.name} ({p.after.point_mae_mm:.3f} mm, the others' median "
        f"{p.others_mae_mm:.3f} mm; {p.left_out} of {p.rows} rows left out)"
        for p in placements(every, all_rows)
        if p.suspect
    ]
    out = []
    for place in places:
        others = placements_folder([p for p in places if p != place], folder / robot_dir.name / place.name)
        start = time.perf_counter()
        cal = pincal.calibrate(robot, read_socket_folder(others, robot.joint_names), model, **OPTIONS)
        seconds = time.perf_counter() - start
        held = read_socket_folder(place, robot.joint_names)
        held_err, floor = (evaluate(c.model, c.measurement, c.theta, held, c.extension) for c in (cal, every))
        out.append(Pooled(robot_dir.name, place.name, held_err, floor, seconds))
    return out, suspects, every


def judge(
    robot_dir: Path, urdf: Path, model: str, extend: str = "none", named: bool = True
) -> tuple[list[Judged], Counter[str]]:
    """Calibrate on each placement, judge on the others; what diagnose names per placement (for
    the Pandas, whose URDF has no masses, with the bundled Panda's: ``--inertias panda``), unless
    not ``named``."""
    robot = pincal.load_robot(urdf, tip="ball_link")
    panda = robot_dir.name.startswith("panda")
    masses = pincal.load_robot(urdf, tip="ball_link", inertias="panda") if panda else None
    places = {
        p.name: read_socket_folder(p, robot.joint_names) for p in sorted(robot_dir.iterdir()) if p.is_dir()
    }
    out, causes = [], Counter[str]()
    for train, data in places.items():
        start = time.perf_counter()
        cal = pincal.calibrate(
            robot if extend == "none" else masses or robot, data, model, extension=extend, **OPTIONS
        )
        seconds = time.perf_counter() - start
        if named:
            found = diagnose(masses or robot, data, model, point_distances=DISTANCE)
            causes[found.cause.extension.label if found.cause is not None else "none"] += 1
        weight = cal.prior.weight if cal.prior is not None else float("nan")
        kept = cal.guard is None or cal.guard.kept_fit
        for test, held in places.items():
            if test != train:
                urdf_err = evaluate(cal.model, cal.urdf_measurement, cal.urdf_theta, held, cal.extension)
                after = evaluate(cal.model, cal.measurement, cal.theta, held, cal.extension)
                out.append(Judged(robot_dir.name, train, test, urdf_err, after, seconds, weight, kept))
    return out, causes


def synthetic(every: pincal.Calibration, robot_dir: Path, model: str, seed: int = 0) -> list[float]:
    """The one-placement held-out MAEs [mm] (every train/test combination) on rows made again
    from the floor model ``every`` (the calibration on every placement, :func:`pooled`): each
    configuration moved until the model's ball is at its socket's mean, plus independent scatter
    as large as that placement's own error."""
    robot = every.model.robot
    rng = np.random.default_rng(seed)
    made = {}
    for place in sorted(p for p in robot_dir.iterdir() if p.is_dir()):
        data = read_socket_folder(place, robot.joint_names)
        tips = Problem(every.model, every.measurement, data, every.extension).target_frames(every.theta)[2]
        labels = data.labels
        assert labels is not None  # read_socket_folder names each row's socket
        goal = point_means(tips, labels, len(data.point_names))[labels]
        mae = float(np.mean(np.linalg.norm(tips - goal, axis=1)))  # [m] that placement's own error
        goal = goal + rng.normal(0.0, mae / np.sqrt(8.0 / np.pi), goal.shape)  # a 3-D Gaussian's mean norm
        q = data.q.copy()
        for _ in range(5):  # Gauss-Newton on the joints: the ball to the goal
            moved = replace(data, q=q)
            problem = Problem(every.model, every.measurement, moved, every.extension)
            jac = np.stack([problem.joint_sensitivity(every.theta, j) for j in range(q.shape[1])], axis=2)
            miss = goal - problem.target_frames(every.theta)[2]
            q = q + np.einsum("nij,nj->ni", np.linalg.pinv(jac), miss)
        made[place.name] = replace(data, q=q)
    held = []
    for train, data in made.items():
        cal = pincal.calibrate(robot, data, model, **OPTIONS)
        held += [
            float(evaluate(cal.model, cal.measurement, cal.theta, other, cal.extension).point_mae_mm or 0.0)
            for test, other in made.items()
            if test != train
        ]
    return held


def rigid_table(root: Path, rows: list[Judged], floors: dict[str, pincal.Calibration], model: str) -> str:
    """Per robot and for all Pandas: one placement's held-out MAE median [mm] on the real rows
    and on the rows made again from each robot's floor model (:func:`synthetic`)."""
    made = {name: synthetic(every, root / "data" / name, model) for name, every in floors.items()}
    made["all Pandas"] = [v for name, held in made.items() if name.startswith("panda") for v in held]
    lines = ["\none placement's held-out MAE median [mm], real rows / rows made again from the floor model"]
    for name, held in made.items():
        group = [r for r in rows if r.robot == name or (name == "all Pandas" and r.robot.startswith("panda"))]
        real = np.median([float(r.after.point_mae_mm or 0.0) for r in group])
        lines.append(f"  {name}: {real:.3f} / {np.median(held):.3f}")
    return "\n".join(lines)


def table(rows: list[Judged], causes: dict[str, Counter[str]], pools: list[Pooled]) -> str:
    """Per robot: held-out mean absolute error and distance error, URDF as is and calibrated on
    one placement; calibrated on all other placements; the floor (every placement fitted)."""

    def fig(values: list[float]) -> str:
        return f"{np.median(values):6.3f} ({max(values):6.3f})"

    lines = [
        "| robot | placements | URDF as is: MAE, median (worst) [mm] | calibrated: MAE, median (worst) [mm]"
        " | distance error, URDF / calibrated, median [mm] | diagnose names | time per calibration [s]"
        " | calibrated on all other placements: MAE, median (worst) [mm] | floor: every placement"
        " fitted, MAE median [mm] |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name in sorted({r.robot for r in rows}):
        mine = [r for r in rows if r.robot == name]
        n_places = len({r.train for r in mine})

        def each(attr: str, key: str, group: list[Judged] = mine) -> list[float]:
            return [float(getattr(getattr(r, attr), key) or 0.0) for r in group]

        named = ", ".join(f"{c} ({k})" for c, k in causes[name].most_common())
        lines.append(
            f"| {name} | {n_places} | {fig(each('urdf', 'point_mae_mm'))} "
            f"| {fig(each('after', 'point_mae_mm'))} "
            f"| {np.median(each('urdf', 'point_distance_error_mm')):.3f} / "
            f"{np.median(each('after', 'point_distance_error_mm')):.3f} | {named} "
            f"| {np.median([r.seconds for r in mine]):.3f} "
            f"| {fig([float(p.held.point_mae_mm or 0.0) for p in pools if p.robot == name])} "
            f"| {np.median([float(p.floor.point_mae_mm or 0.0) for p in pools if p.robot == name]):.3f} |"
        )
    pandas = [r for r in rows if r.robot.startswith("panda")]
    if pandas:
        mae = [float(r.after.point_mae_mm or 0.0) for r in pandas]
        off = [float(r.after.point_distance_error_mm or 0.0) for r in pandas]
        lines.append(
            f"\nAll Pandas together ({len(pandas)} train/test combinations): held-out MAE median "
            f"{np.median(mae):.3f} mm, distance error median {np.median(off):.3f} mm; "
            f"each calibrated on all other placements: {pooled_median(pools):.3f} mm; the floor (every "
            f"placement fitted, the judged one included): {pooled_median(pools, floor=True):.3f} mm"
        )
    return "\n".join(lines)


def pooled_median(pools: list[Pooled], floor: bool = False) -> float:
    """The Pandas' held-out MAE median [mm] of the models calibrated on all other placements (or
    on every placement: ``floor``), each placement weighted as in the one-placement protocol
    (judged once per other placement)."""
    pandas = [p for p in pools if p.robot.startswith("panda")]
    weights = [sum(q.robot == p.robot for q in pandas) - 1 for p in pandas]
    values = np.repeat([float((p.floor if floor else p.held).point_mae_mm or 0.0) for p in pandas], weights)
    return float(np.median(values))


def arguments() -> argparse.Namespace:
    """The command line."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("datasets", type=Path, help="the shared datasets folder (holding mukca/)")
    parser.add_argument("--model", default="placements", choices=pincal.MODELS)
    parser.add_argument("--plot", type=Path, default=FIGURE)
    parser.add_argument("--extend", choices=["none", "auto"], default="none", help="(Pandas: with masses)")
    parser.add_argument("--json", type=Path, help="write every judged combination here")
    parser.add_argument(
        "--synthetic", action="store_true", help="also on rows made again from the floor model"
    )
    parser.add_argument(
        "--protocol-only", action="store_true", help="the protocol alone (no diagnosis, pooling, plot)"
    )
    parser.add_argument("--markdown", type=Path, help="write the results page here (docs/results/mukca.md)")
    parser.add_argument(
        "--oracle", action="store_true", help="also what the pull reaches at best (mukca_oracle)"
    )
    return parser.parse_args()


def main() -> None:
    args = arguments()
    root = args.datasets / "mukca"
    start = time.perf_counter()
    rows: list[Judged] = []
    pools: list[Pooled] = []
    causes: dict[str, Counter[str]] = {}
    suspects: list[str] = []
    floors: dict[str, pincal.Calibration] = {}
    with tempfile.TemporaryDirectory() as folder:
        for robot_dir in sorted((root / "data").iterdir()):
            urdf = root / "urdf" / URDFS[robot_dir.name.split("_")[0]]
            judged, causes[robot_dir.name] = judge(
                robot_dir, urdf, args.model, args.extend, not args.protocol_only
            )
            rows += judged
            if not args.protocol_only:
                pool, named, floors[robot_dir.name] = pooled(robot_dir, urdf, args.model, Path(folder))
                pools += pool
                suspects += named
    pairs = [r.pair() for r in rows]
    print("\n".join(protocol_rows(pairs)))
    print("\npairs worse than the URDF as is: " + ("; ".join(worse_pairs(pairs)) or "none"))
    more = "(run without --protocol-only for the other tables)"
    if not args.protocol_only:
        more = table(rows, causes, pools)
        listed = "; ".join(suspects) or "none"
        more += f"\n\nplacements a robot's calibration on every placement names as suspect: {listed}"
        if args.synthetic:
            more += "\n" + rigid_table(root, rows, floors, args.model)
        print("\n" + more)
        plot(rows, args.plot)
        print(f"\nplot: {args.plot}")
    if args.oracle:
        robots = sorted((root / "data").iterdir())
        more += "\n" + oracle_table([oracle(d, root / "urdf" / URDFS[d.name.split("_")[0]]) for d in robots])
        print(more[more.index("\nwhat the pull") :])
    print(f"whole benchmark {time.perf_counter() - start:.0f} s")
    if args.markdown is not None:
        flags = (" --protocol-only" if args.protocol_only else "") + (" --oracle" if args.oracle else "")
        write_page(
            args.markdown,
            pairs,
            more,
            f"python benchmarks/mukca.py ../shared/datasets{flags} --markdown PAGE",
        )
    if args.json is not None:
        write_json(args.json, rows, pools)


if __name__ == "__main__":
    main()
