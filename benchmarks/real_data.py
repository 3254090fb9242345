"""Real-data benchmarks: pincal on every real dataset we hold, against the published figure.

For each dataset (layouts in ``DATASETS_DIR/SOURCES.md``; nothing is copied from it) this fits on
the training part, judges on the held-out part and prints one table: dataset, model, identified
parameters (model, registration and tool), RMS on the fitted poses, held-out RMS, the anchor's
published figure and the median wall time of the identification step (:func:`pincal.calibrate`,
plus :func:`pincal.selection.select_parameters` for the selected models). Then what
``diagnose`` names on each, the selections, and a scaling run of identification time against
the number of poses and of joints, saved as a PNG.

- ``tiago_qualisys``: fit on ``train_2021-11-30.csv`` (37 poses), judge on
  ``validation_2021-11-26.csv`` (62 poses, another day), point 1, chain ``base_footprint`` →
  torso and arm → ``wrist_ft_tool_link``, mocap registration and point on the tool unknown.
  Anchor: FIGAROH's held-out protocol on the same split.
- ``ur10_camera``: the camera's pose in the checkerboard's frame (``x1,y1,z1`` [m];
  ``phix1,phiy1,phiz1`` roll, pitch, yaw [rad] with ``R = Rz(yaw) Ry(pitch) Rx(roll)``, as
  ``pinocchio.rpy`` writes them), camera on ``wrist_3_link``: pose data, the board's pose and the
  camera's mounting (6-DoF) unknown; leave-one-out cross-validation over the 23 poses.
- ``panda_eye_in_hand``: ``X_C_B`` is the camera's pose in the board's frame (the rigid motion
  ``board_T_camera``: only this reading fits the kinematics), camera on ``panda_link8``, board
  pose and camera mounting unknown (hand-eye and kinematics together); 10-fold cross-validation.
- ``gao2013``: Table 2 of Gao et al. 2013 (``--gao-data``), distances between the 28 tracker
  points, POE (the paper's model), 7-fold cross-validation over poses.

"Selected" models fit only the parameters :func:`pincal.selection.select_parameters` chooses by
leave-one-out cross-validation on the fitted poses alone. Their held-out figure for the
cross-validated datasets is *nested*: the selection is re-run inside every fold.

Timings are medians of ``--repeat`` runs with one BLAS thread (set below, before numpy loads:
on a shared 2-core machine multithreaded BLAS makes these small solves up to 10x slower).

Usage::

    python benchmarks/real_data.py DATASETS_DIR [--json FILE] [--gao-data CSV] [--repeat 15]
        [--scaling-plot PNG | --no-scaling]
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from dataclasses import asdict, dataclass  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any, TypeVar  # noqa: E402

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
from identification_scaling import FIGURE, load_tiago, plot, scaling  # noqa: E402

import pincal  # noqa: E402
from pincal.data import Dataset, atomic_write, read_table  # noqa: E402
from pincal.diagnose import Diagnosis, diagnose  # noqa: E402
from pincal.selection import cross_validate_selection, select_parameters  # noqa: E402

T = TypeVar("T")
#: FIGAROH on TIAGo (train / validation RMS [mm]) and its identification step [s], this machine kind.
FIGAROH = {"registration": (3.37, 4.87), "offsets": (2.88, 4.23), "full": (1.68, 3.22)}
FIGAROH_SECONDS = {"offsets": 0.19, "full": 0.37}
#: Timed runs per point of the scaling plot.
SCALING_REPEAT = 5
#: UR10e minus UR10 nominal DH lengths [m] (Universal Robots' published tables: d4 0.17415 vs 0.163941,
#: d5 0.11985 vs 0.1157).
UR10E_MINUS_UR10 = {"d4": 0.17415 - 0.163941, "d5": 0.11985 - 0.1157}
#: For cross-validation and diagnose: each fold fits what its poses identify.
CV_OPTIONS: dict[str, Any] = {"partial": True}


@dataclass
class Row:
    """One line of the table (RMS of the 3-D position error [mm]; distance data: over pairs)."""

    dataset: str
    model: str
    params: int
    train_mm: float
    held_mm: float
    held_by: str
    anchor: str
    seconds: float


#: Median CPU time [s] of the last call of :func:`timed` (this process only: robust to other load).
LAST_CPU: list[float] = [0.0]


def timed(repeat: int, fn: Callable[..., T], *args: Any, **kwargs: Any) -> tuple[T, float]:
    """The result of ``fn(*args, **kwargs)`` and the median wall time [s] of ``repeat`` calls."""
    times, cpu, result = [], [], None
    for _ in range(repeat):
        start, start_cpu = time.perf_counter(), time.process_time()
        result = fn(*args, **kwargs)
        times.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
    assert result is not None
    LAST_CPU[0] = statistics.median(cpu)
    return result, statistics.median(times)


def _quaternions(rotations: list[np.ndarray]) -> np.ndarray:
    return np.array([pin.Quaternion(r).coeffs()[[3, 0, 1, 2]] for r in rotations])


def load_tiago_data(folder: Path) -> tuple[pincal.Robot, Dataset, Dataset]:
    """TIAGo's chain and its training and validation sessions (point 1 only)."""
    robot = load_tiago(folder / "tiago_48_schunk.urdf")
    point = {"x": "x1", "y": "y1", "z": "z1"}

    def read(name: str) -> Dataset:
        values = read_table(folder / name, [*robot.joint_names, "x", "y", "z"], "joints and x1,y1,z1", point)
        return Dataset(robot.joint_names, values[:, :-3], values[:, -3:])

    return robot, read("train_2021-11-30.csv"), read("validation_2021-11-26.csv")


def load_ur10(folder: Path) -> tuple[pincal.Robot, Dataset]:
    """The UR10 to ``wrist_3_link`` and the camera's poses in the board's frame."""
    robot = pincal.load_robot("ur10", tip="wrist_3_link")
    cols = [*robot.joint_names, "x1", "y1", "z1", "phix1", "phiy1", "phiz1"]
    values = read_table(folder / "calibration.csv", cols, "the joints, x1,y1,z1 and phix1,phiy1,phiz1")
    rotations = [pin.rpy.rpyToMatrix(*rpy) for rpy in values[:, -3:]]
    return robot, Dataset(robot.joint_names, values[:, :6], values[:, 6:9], _quaternions(rotations))


def load_panda(folder: Path) -> tuple[pincal.Robot, Dataset]:
    """The Panda to its flange ``panda_link8`` and the camera's poses in the board's frame."""
    robot = pincal.load_robot("panda", tip="panda_link8")
    joints = [f"q{k}" for k in range(1, 8)]
    cols = [*joints, *(f"X_C_B_{i}{j}" for i in range(3) for j in range(4))]
    values = read_table(folder / "calib_data_converted.csv", cols, "q1..q7 and X_C_B_ij")
    poses = values[:, 7:].reshape(-1, 3, 4)
    return robot, Dataset(
        robot.joint_names, values[:, :7], poses[:, :, 3].copy(), _quaternions(list(poses[:, :, :3]))
    )


def load_gao(path: Path | None) -> tuple[pincal.Robot, Dataset, str]:
    """Gao et al. 2013's 28 poses (degrees, mm) from ``path``, or the table pincal ships."""
    robot = pincal.load_robot("mrres5")
    if path is None or not path.is_file():
        return robot, pincal.gao2013_data()[0], "pincal.gao2013_data() (the same Table 2)"
    cols = [*(f"theta{k}_deg" for k in range(1, 6)), "x_meas_mm", "y_meas_mm", "z_meas_mm"]
    values = read_table(path, cols, "theta1_deg..theta5_deg and x_meas_mm,y_meas_mm,z_meas_mm")
    return robot, Dataset(robot.joint_names, np.deg2rad(values[:, :5]), values[:, 5:] * 1e-3), str(path)


def values(cal: pincal.Calibration, names: tuple[str, ...]) -> str:
    """``name value ± std`` of identified parameters, in mm and mrad."""
    parts = []
    for name in names:
        k = cal.names.index(name)
        unit = "mrad" if cal.units[k] == "rad" else "mm"
        parts.append(f"{name} {cal.theta[k] * 1e3:+.2f} ± {cal.std[k] * 1e3:.2f} {unit}")
    return ", ".join(parts)


def diagnosis_line(diag: Diagnosis) -> str:
    """What ``diagnose`` named, with its cross-validated gain."""
    return f"{diag.summary()} [gain {diag.gain:.2f}]"


def bench_tiago(folder: Path, repeat: int, out: list[str]) -> tuple[list[Row], dict[str, Any]]:
    """TIAGo: train on one day, judge on another; FIGAROH's figures as anchors."""
    robot, train, val = load_tiago_data(folder)
    name = "tiago_qualisys"
    rows: list[Row] = []
    details: dict[str, Any] = {}

    def fit(model: str, **options: Any) -> tuple[pincal.Calibration, float]:
        return timed(repeat, pincal.calibrate, robot, train, model, test=val, **options)

    def row(label: str, cal: pincal.Calibration, seconds: float, anchor: str) -> Row:
        assert cal.test_after is not None
        return Row(
            name,
            label,
            cal.identifiability.n_identifiable,
            cal.train_after.rms_mm,
            cal.test_after.rms_mm,
            "validation",
            anchor,
            seconds,
        )

    fig = {k: f"FIGAROH {a:.2f} / {b:.2f}" for k, (a, b) in FIGAROH.items()}
    reg, t = fit("placements", params=[])
    rows.append(row("registration only", reg, t, fig["registration"]))
    off, t_off = fit("offsets")
    cpu_off = LAST_CPU[0]
    rows.append(row("offsets", off, t_off, fig["offsets"]))
    full, t_full = fit("placements")
    cpu_full = LAST_CPU[0]
    rows.append(row("placements, all", full, t_full, fig["full"]))
    selections = {}
    for model in ("placements", "poe", "mdh"):
        sel, t_sel = timed(repeat, select_parameters, robot, train, model)
        cal, t_cal = fit(model, params=list(sel.chosen))
        selections[model] = sel
        if model == "placements":
            cal_sel = cal
        mark = " *" if model == "placements" else ""
        rows.append(row(f"{model}, selected{mark}", cal, t_sel + t_cal, fig["full"]))
        details[f"selection_{model}"] = sel.to_dict() | {"train_rms_mm": cal.train_after.rms_mm}
    chosen = list(selections["placements"].chosen)
    diag = diagnose(robot, train, "placements", params=chosen, **CV_OPTIONS)
    details["diagnose"] = diag.to_dict()
    if diag.cause is not None:
        ext, t_ext = fit("placements", params=chosen, extension=diag.cause.extension)
        rows.append(row(f"placements, selected * + {diag.cause.extension.label}", ext, t_ext, "-"))

    n = len(train)
    loo = {
        "registration only": pincal.cross_validate(
            robot, train, "placements", folds=n, params=[], **CV_OPTIONS
        ),
        "offsets": pincal.cross_validate(robot, train, "offsets", folds=n, **CV_OPTIONS),
        "placements, all": pincal.cross_validate(robot, train, "placements", folds=n, **CV_OPTIONS),
    }
    nested = cross_validate_selection(robot, train, "placements", folds=n, **CV_OPTIONS)
    details["training_loo_rms_mm"] = {k: v.after.rms_mm for k, v in loo.items()} | {
        "placements, selected (nested)": nested.after.rms_mm
    }

    out.append(f"{name}: {n} training poses, {len(val)} validation poses (another day), point 1")
    sel = selections["placements"]
    out.append(
        f"  selection on the training poses only (leave-one-out, linearised): {len(sel.chosen)} of "
        f"{len(sel.path) - 1} placement parameters, CV RMS {sel.path[0].cv_rms_mm:.2f} -> "
        f"{sel.cv_rms_mm:.2f} mm (all {len(sel.path) - 1}: {sel.path[-1].cv_rms_mm:.2f} mm; the shortest "
        f"path prefix within {sel.min_gain:.0%} of the lowest)"
    )
    out.append(f"    chosen: {values(cal_sel, sel.chosen)}")
    for model in ("poe", "mdh"):
        s = selections[model]
        out.append(f"    {model}: {len(s.chosen)} parameters, CV RMS {s.cv_rms_mm:.2f} mm")
    lowest = min(selections, key=lambda m: selections[m].cv_rms_mm)
    out.append(f"    lowest training CV: {lowest}; * is placements, pincal's default, chosen before any fit")
    out.append(
        "  leave-one-out on the training poses: "
        + ", ".join(f"{k} {v:.2f}" for k, v in details["training_loo_rms_mm"].items())
        + " mm"
    )
    out.append(f"  diagnose (baseline: placements, selected; 5-fold CV): {diagnosis_line(diag)}")
    ratio_off, ratio_full = FIGAROH_SECONDS["offsets"] / t_off, FIGAROH_SECONDS["full"] / t_full
    out.append(
        f"  identification (calibrate), median of {repeat}: offsets {t_off:.3f} s wall / {cpu_off:.3f} s "
        f"CPU, {ratio_off:.1f}x faster than FIGAROH's {FIGAROH_SECONDS['offsets']} s"
    )
    out.append(
        f"    placements ({full.identifiability.n_identifiable} identified; FIGAROH's full model: 30) "
        f"{t_full:.3f} s wall / {cpu_full:.3f} s CPU, {ratio_full:.1f}x faster than FIGAROH's "
        f"{FIGAROH_SECONDS['full']} s"
    )
    details["timing"] = {
        "offsets_s": t_off,
        "placements_s": t_full,
        "offsets_cpu_s": cpu_off,
        "placements_cpu_s": cpu_full,
        "figaroh_s": FIGAROH_SECONDS,
        "speedup_offsets": ratio_off,
        "speedup_placements": ratio_full,
    }
    return rows, details


def bench_cv(
    name: str,
    robot: pincal.Robot,
    data: Dataset,
    model: str,
    measure: str | None,
    folds: int,
    repeat: int,
    anchor: str,
    out: list[str],
    models: tuple[str, ...] = ("offsets",),
) -> tuple[list[Row], dict[str, Any]]:
    """A dataset judged by K-fold cross-validation over its poses."""
    by = "leave-one-out" if folds == len(data) else f"{folds}-fold"
    rows: list[Row] = []
    details: dict[str, Any] = {}

    def add(label: str, cal: pincal.Calibration, held: float, seconds: float, how: str = by) -> None:
        rows.append(
            Row(
                name,
                label,
                cal.identifiability.n_identifiable,
                cal.train_after.rms_mm,
                held,
                how,
                anchor,
                seconds,
            )
        )

    reg, t = timed(repeat, pincal.calibrate, robot, data, model, measure, params=[])
    cv_reg = pincal.cross_validate(robot, data, model, measure, folds=folds, params=[], **CV_OPTIONS)
    add(
        "registration only" if measure != "distance" else "nominal, tool point fitted",
        reg,
        cv_reg.after.rms_mm,
        t,
    )
    for other in models:
        cal, t = timed(repeat, pincal.calibrate, robot, data, other, measure)
        add(
            other,
            cal,
            pincal.cross_validate(robot, data, other, measure, folds=folds, **CV_OPTIONS).after.rms_mm,
            t,
        )
    full, t = timed(repeat, pincal.calibrate, robot, data, model, measure)
    cv_full = pincal.cross_validate(robot, data, model, measure, folds=folds, **CV_OPTIONS)
    add(f"{model}, all", full, cv_full.after.rms_mm, t)
    sel, t_sel = timed(repeat, select_parameters, robot, data, model, measure)
    cal, t_cal = timed(repeat, pincal.calibrate, robot, data, model, measure, params=list(sel.chosen))
    nested = cross_validate_selection(robot, data, model, measure, folds=folds, **CV_OPTIONS)
    add(f"{model}, selected", cal, nested.after.rms_mm, t_sel + t_cal, f"{by}, nested")
    diag = diagnose(
        robot,
        data,
        model,
        measure,
        folds=7 if measure == "distance" else 5,
        params=list(sel.chosen),
        **CV_OPTIONS,
    )
    if diag.cause is not None:
        ext, t_ext = timed(
            repeat,
            pincal.calibrate,
            robot,
            data,
            model,
            measure,
            params=list(sel.chosen),
            extension=diag.cause.extension,
            **CV_OPTIONS,
        )
        add(
            f"{model}, selected + {diag.cause.extension.label}",
            ext,
            diag.extended_cv_rms_mm,
            t_ext,
            f"{diag.folds}-fold (diagnose)",
        )

    out.append(
        f"{name}: {len(data)} poses, {measure or ('pose' if data.has_orientation else 'position')} data, "
        f"judged by {by} cross-validation"
    )
    if data.has_orientation:
        rot = [c.train_after.rot_rms_mrad for c in (reg, full, cal)]
        out.append(
            f"  orientation RMS on the fitted poses: registration only {rot[0]:.2f}, {model} all "
            f"{rot[1]:.2f}, selected {rot[2]:.2f} mrad"
        )
    out.append(
        f"  selection (leave-one-out, linearised): {len(sel.chosen)} of {len(sel.path) - 1} {model} "
        f"parameters, CV RMS {sel.path[0].cv_rms_mm:.2f} -> {sel.cv_rms_mm:.2f} mm"
    )
    out.append(f"    chosen: {values(cal, sel.chosen)}")
    if name == "ur10_camera":
        out.append(
            "    a UR10e's nominal d4 and d5 exceed the UR10's by "
            f"{UR10E_MINUS_UR10['d4'] * 1e3:.2f} and {UR10E_MINUS_UR10['d5'] * 1e3:.2f} mm "
            "(shoulder_lift_joint.ty and wrist_2_joint.tz move those lengths)"
        )
    out.append(f"  diagnose (baseline: {model}, selected): {diagnosis_line(diag)}")
    details.update(
        selection=sel.to_dict(), diagnose=diag.to_dict(), nested_chosen=[list(c) for c in nested.chosen]
    )
    if measure == "distance":
        urdf = cv_full.urdf.mean_mm
        details["mean_abs_distance_error_mm"] = {
            "urdf": urdf,
            "all": cv_full.after.mean_mm,
            "selected_nested": nested.after.mean_mm,
        }
        line = (
            f"  held-out mean |distance error|: URDF as is {urdf:.3f} mm -> {model} all "
            f"{cv_full.after.mean_mm:.3f} ({urdf / cv_full.after.mean_mm:.2f}x), selected (nested) "
            f"{nested.after.mean_mm:.3f} ({urdf / nested.after.mean_mm:.2f}x)"
        )
        if diag.cause is not None:
            ext_cv = pincal.cross_validate(
                robot,
                data,
                model,
                measure,
                folds=folds,
                params=list(sel.chosen),
                extension=diag.cause.extension,
                **CV_OPTIONS,
            )
            details["mean_abs_distance_error_mm"]["selected_extended"] = ext_cv.after.mean_mm
            line += (
                f", selected + {diag.cause.extension.label} {ext_cv.after.mean_mm:.3f} "
                f"({urdf / ext_cv.after.mean_mm:.2f}x)"
            )
        out.append(line + "; the paper: 3.5x (2.96 -> 0.62 mm on its 16 test pairs)")
    return rows, details


def format_table(rows: list[Row]) -> str:
    """The table as printed."""
    head = (
        "dataset",
        "model",
        "params",
        "train RMS",
        "held-out RMS",
        "held out by",
        "anchor (train / held-out)",
        "identify",
    )
    lines = [
        f"{head[0]:18s} {head[1]:52s} {head[2]:>6s} {head[3]:>9s} {head[4]:>12s}  {head[5]:24s} "
        f"{head[6]:26s} {head[7]:>8s}"
    ]
    lines.append(f"{'':18s} {'':52s} {'':>6s} {'[mm]':>9s} {'[mm]':>12s}  {'':24s} {'[mm]':26s} {'[s]':>8s}")
    for r in rows:
        lines.append(
            f"{r.dataset:18s} {r.model:52s} {r.params:6d} {r.train_mm:9.2f} {r.held_mm:12.2f}  "
            f"{r.held_by:24s} {r.anchor:26s} {r.seconds:8.3f}"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """Run every benchmark, print the table and the notes, write the JSON and the plot."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("datasets", type=Path, metavar="DATASETS_DIR", help="the folder ../shared/datasets")
    parser.add_argument("--json", type=Path, metavar="FILE", help="also write everything printed as JSON")
    parser.add_argument(
        "--gao-data",
        type=Path,
        metavar="CSV",
        help="Gao 2013 Table 2 (default: DATASETS_DIR/../data/gao2013_calibration_poses.csv, "
        "else the copy pincal ships)",
    )
    parser.add_argument("--repeat", type=int, default=15, help="timed runs per figure (median; default 15)")
    parser.add_argument(
        "--scaling-plot", type=Path, default=FIGURE, metavar="PNG", help="where to write the plot"
    )
    parser.add_argument("--no-scaling", action="store_true", help="skip the scaling run")
    args = parser.parse_args(argv)
    if not args.datasets.is_dir():
        parser.error(f"{args.datasets} is not a folder")
    if args.repeat < 1:
        parser.error("--repeat must be at least 1")
    gao_path = args.gao_data or args.datasets.parent / "data" / "gao2013_calibration_poses.csv"
    start = time.perf_counter()

    notes: list[str] = []
    rows, details = bench_tiago(args.datasets / "tiago_qualisys", args.repeat, notes)
    results: dict[str, Any] = {"tiago_qualisys": details}
    robot, data = load_ur10(args.datasets / "ur10_camera")
    new, results["ur10_camera"] = bench_cv(
        "ur10_camera", robot, data, "placements", None, len(data), args.repeat, "none published", notes
    )
    rows += new
    robot, data = load_panda(args.datasets / "panda_eye_in_hand")
    new, results["panda_eye_in_hand"] = bench_cv(
        "panda_eye_in_hand", robot, data, "placements", None, 10, args.repeat, "none published", notes
    )
    rows += new
    robot, data, source = load_gao(gao_path)
    new, results["gao2013"] = bench_cv(
        "gao2013", robot, data, "poe", "distance", 7, args.repeat, "paper: 3.5x on URDF", notes, models=()
    )
    results["gao2013"]["source"] = source
    rows += new

    print(
        f"pincal {pincal.__version__}: real-data benchmarks, {os.environ['OPENBLAS_NUM_THREADS']} BLAS "
        f"thread, times are medians of {args.repeat}"
    )
    print(format_table(rows))
    print(
        "params: identified parameters, registration and tool included. RMS of the 3-D position error, "
        "distances for gao2013."
    )
    print("* placements, pincal's default model (see the lowest training CV below).")
    print()
    print("\n".join(notes))

    scaling_records: list[dict[str, Any]] = []
    if not args.no_scaling:
        tiago = load_tiago(args.datasets / "tiago_qualisys" / "tiago_48_schunk.urdf")
        robots = {"ur5": pincal.load_robot("ur5"), "panda": pincal.load_robot("panda"), "tiago": tiago}
        scaling_records = scaling(robots, repeat=SCALING_REPEAT)
        t_full = results["tiago_qualisys"]["timing"]["placements_s"]
        marks = [
            {"label": "pincal, TIAGo real data (37 poses)", "poses": 37, "seconds": t_full, "marker": "s"},
            {
                "label": "FIGAROH, TIAGo real data (37 poses)",
                "poses": 37,
                "seconds": FIGAROH_SECONDS["full"],
                "marker": "X",
            },
        ]
        path = plot(scaling_records, args.scaling_plot, marks)
        print()
        print(f"identification time [s], placements, simulated position data, median of {SCALING_REPEAT}:")
        poses = sorted({r["poses"] for r in scaling_records})
        print(f"{'robot':17s}" + "".join(f"{n:>9d}" for n in poses))
        for rname in dict.fromkeys(r["robot"] for r in scaling_records):
            recs = {r["poses"]: r for r in scaling_records if r["robot"] == rname}
            label = f"{rname} ({recs[poses[0]]['joints']} joints)"
            print(f"{label:17s}" + "".join(f"{recs[n]['seconds']:9.3f}" for n in poses))
        print(f"plot: {path}")
    total = time.perf_counter() - start
    print(f"total wall time {total:.0f} s")

    if args.json:
        doc = {
            "table": [asdict(r) for r in rows],
            "datasets": results,
            "scaling": scaling_records,
            "notes": notes,
            "blas_threads": os.environ["OPENBLAS_NUM_THREADS"],
            "wall_time_s": total,
        }
        atomic_write(args.json, json.dumps(doc, indent=2, default=float) + "\n")
        print(f"JSON written to {args.json}")


if __name__ == "__main__":
    main()
