"""Real-data benchmarks: pincal on every real dataset we hold, against the published figure.

For each dataset (layouts in ``DATASETS_DIR/SOURCES.md``; nothing is copied from it) this fits on
the training part, judges on the held-out part and prints one table: dataset, model, identified
parameters (model, registration and tool), RMS on the fitted poses, held-out RMS, the anchor's
published figure and the median wall time of the identification step (:func:`pincal.calibrate`,
plus :func:`pincal.identify.forward_selection.select_parameters` for the selected models). Then what
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

"Selected" models fit only the parameters
:func:`pincal.identify.forward_selection.select_parameters` chooses by
leave-one-out cross-validation on the fitted poses alone. Their held-out figure for the
cross-validated datasets is *nested*: the selection is re-run inside every fold.

Timings are medians of ``--repeat`` runs with one BLAS thread (set below, before numpy loads:
on a shared 2-core machine multithreaded BLAS makes these small solves up to 10x slower).

Usage::

    python benchmarks/real_data.py DATASETS_DIR [--json FILE] [--gao-data CSV] [--repeat 15]
        [--scaling-plot PNG | --no-scaling] [--markdown docs/results/generated/real_data.md]
"""

from __future__ import annotations

import os

import pincal.auto.selection

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from dataclasses import asdict, dataclass  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any, TypeVar  # noqa: E402

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
from identification_scaling import FIGURE, TIAGO_TIP, load_tiago, plot, scaling  # noqa: E402
from markdown_page import command_line, table, text_block, write_page  # noqa: E402

import pincal  # noqa: E402
from pincal.auto.choice import choice_of  # noqa: E402
from pincal.data.csv_writer import write_csv  # noqa: E402
from pincal.data.dataset import Dataset, read_table  # noqa: E402
from pincal.files import atomic_write  # noqa: E402
from pincal.identify.outliers import THRESHOLD  # noqa: E402
from pincal.identify.registration import quaternions  # noqa: E402
from pincal.report.summary_table import choice_lines  # noqa: E402

T = TypeVar("T")
#: FIGAROH on TIAGo (train / validation RMS [mm]) and its identification step [s], this machine kind.
FIGAROH = {"registration": (3.37, 4.87), "offsets": (2.88, 4.23), "full": (1.68, 3.22)}
FIGAROH_SECONDS = {"offsets": 0.19, "full": 0.37}
#: The fit exported whatever pincal's guard says: FIGAROH's models compared as FIGAROH fits them.
FORCED = pincal.Pull(force_fit=True)
#: Timed runs per point of the scaling plot.
SCALING_REPEAT = 5
#: UR10e minus UR10 nominal DH lengths [m] (Universal Robots' published tables: d4 0.17415 vs 0.163941,
#: d5 0.11985 vs 0.1157).
UR10E_MINUS_UR10 = {"d4": 0.17415 - 0.163941, "d5": 0.11985 - 0.1157}


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
    command: str = ""


def timed(repeat: int, fn: Callable[..., T], *args: Any, **kwargs: Any) -> tuple[T, float]:
    """The result of ``fn(*args, **kwargs)`` and the median wall time [s] of ``repeat`` calls."""
    times, result = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        result = fn(*args, **kwargs)
        times.append(time.perf_counter() - start)
    assert result is not None
    return result, statistics.median(times)


def urdf_alone_row(full: Row, cal: pincal.Calibration) -> Row:
    """The row of the URDF alone that the default also writes, beside the full model's ``full``
    (its figures: the URDF with the sidecar's effects and the geometry fitted with them)."""
    alone = cal.written
    assert alone.test_after is not None
    return Row(
        full.dataset,
        f"{full.model}: the URDF alone",
        alone.identifiability.n_identifiable,
        alone.train_after.rms_mm,
        alone.test_after.rms_mm,
        full.held_by,
        full.anchor,
        full.seconds,
        full.command,
    )


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
    return robot, Dataset(robot.joint_names, values[:, :6], values[:, 6:9], quaternions(np.array(rotations)))


def load_panda(folder: Path) -> tuple[pincal.Robot, Dataset]:
    """The Panda to its flange ``panda_link8`` and the camera's poses in the board's frame."""
    robot = pincal.load_robot("panda", tip="panda_link8")
    joints = [f"q{k}" for k in range(1, 8)]
    cols = [*joints, *(f"X_C_B_{i}{j}" for i in range(3) for j in range(4))]
    values = read_table(folder / "calib_data_converted.csv", cols, "q1..q7 and X_C_B_ij")
    poses = values[:, 7:].reshape(-1, 3, 4)
    return robot, Dataset(
        robot.joint_names, values[:, :7], poses[:, :, 3].copy(), quaternions(poses[:, :, :3])
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


def choice_notes(cal: pincal.Calibration, data: Dataset, out: list[str], label: str) -> None:
    """What ``pincal calibrate`` printed about its choice, indented (the same lines)."""
    out.append(f"  {label}:")
    out.extend(f"    {line}" for line in choice_lines(cal, data))
    if cal.choice is not None and cal.choice.params is not None:
        out.append(f"    values: {values(cal, cal.choice.params)}")


def bench_tiago(folder: Path, repeat: int, out: list[str]) -> tuple[list[Row], dict[str, Any]]:
    """TIAGo: train on one day, judge on another; FIGAROH's figures as anchors."""
    robot, train, val = load_tiago_data(folder)
    name = "tiago_qualisys"
    rows: list[Row] = []
    details: dict[str, Any] = {}
    fig = {k: f"FIGAROH {a:.2f} / {b:.2f}" for k, (a, b) in FIGAROH.items()}
    base = f"pincal calibrate {folder}/tiago_48_schunk.urdf train.csv --tip {TIAGO_TIP} --test validation.csv"
    runs: list[tuple[str, dict[str, Any], str, str]] = [
        ("registration only", dict(params=[]), "registration", "(API: params=[])"),
        (  # FIGAROH's own models, fitted as FIGAROH fits them: no guard (pincal's refuses both)
            "offsets, forced",
            dict(model="offsets", params="all", pull=FORCED),
            "offsets",
            "--model offsets --params all --extend none --force-fit",
        ),
        (
            "placements, all, forced",
            dict(params="all", pull=FORCED),
            "full",
            "--params all --extend none --force-fit",
        ),
        ("placements, all", dict(params="all"), "full", "--params all --extend none"),
        ("placements, auto", {}, "full", "--extend none"),
        ("poe, auto", dict(model="poe"), "full", "--model poe --extend none"),
        ("mdh, auto", dict(model="mdh"), "full", "--model mdh --extend none"),
        ("placements, auto + extend auto *", dict(extension="auto"), "-", ""),
    ]
    timing: dict[str, float] = {}
    for label, options, anchor, flags in runs:
        options = {"params": "auto", "outliers": THRESHOLD, "extension": None, **options}
        n = 1 if options.get("extension") == "auto" else repeat
        cal, seconds = timed(n, pincal.calibrate, robot, train, test=val, **options)
        timing[label] = seconds
        assert cal.test_after is not None
        rows.append(
            Row(
                name,
                label,
                cal.identifiability.n_identifiable,
                cal.train_after.rms_mm,
                cal.test_after.rms_mm,
                "validation",
                fig.get(anchor, "-"),
                seconds,
                f"{base} {flags}".strip(),
            )
        )
        if label.startswith("placements, auto"):
            choice_notes(cal, train, out, label)
            details[label] = pincal.report_dict(cal, train)
        if cal.urdf_fit is not None:  # the default delivers two models: the URDF alone is the other
            rows.append(urdf_alone_row(rows[-1], cal))
    out[:0] = [f"{name}: {len(train)} training poses, {len(val)} validation poses (another day), point 1"]
    bare = {  # the identification alone: no outlier screen (it leaves no TIAGo pose out)
        "offsets": timed(repeat, pincal.calibrate, robot, train, "offsets")[1],
        "placements, all": timed(repeat, pincal.calibrate, robot, train, "placements")[1],
    }
    ratio_off = FIGAROH_SECONDS["offsets"] / bare["offsets"]
    ratio_full = FIGAROH_SECONDS["full"] / bare["placements, all"]
    out.append(
        f"  identification alone (calibrate without the outlier screen, a robust refit that the rows' "
        f"times include), median of {repeat}: offsets {bare['offsets']:.3f} s, {ratio_off:.1f}x faster than "
        f"FIGAROH's {FIGAROH_SECONDS['offsets']} s; placements, all {bare['placements, all']:.3f} s, "
        f"{ratio_full:.1f}x faster than FIGAROH's {FIGAROH_SECONDS['full']} s"
    )
    timing |= {f"{k}, no outlier screen": v for k, v in bare.items()}
    details["timing"] = timing | {"figaroh_s": FIGAROH_SECONDS}
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
    command: str,
    models: tuple[str, ...] = ("offsets",),
) -> tuple[list[Row], dict[str, Any]]:
    """A dataset judged by K-fold cross-validation over its poses: every row is ``pincal
    calibrate`` with ``--nested yes --folds K`` (the choice re-run on each fold), except the
    ``--extend auto`` row, judged by its diagnosis' cross-validation of the chosen model."""
    by = "leave-one-out" if folds == len(data) else f"{folds}-fold"
    rows: list[Row] = []
    details: dict[str, Any] = {}
    base = f"{command} --model {model}" + (f" --measure {measure}" if measure else "")
    runs: list[tuple[str, str, dict[str, Any], str]]
    runs = [(f"{m}, all", m, dict(params="all"), "--params all --extend none") for m in models]
    runs = [("registration only", model, dict(params=[]), "(API: params=[])"), *runs]
    runs += [
        (f"{model}, all", model, dict(params="all"), "--params all --extend none"),
        (f"{model}, auto", model, {}, "--extend none"),
        (f"{model}, auto + extend auto *", model, dict(extension="auto"), ""),
    ]
    for label, mdl, options, flags in runs:
        options = {"params": "auto", "outliers": THRESHOLD, "folds": folds, "extension": None, **options}
        cal, seconds = timed(repeat, pincal.calibrate, robot, data, mdl, measure, **options)
        judged = pincal.calibrate(robot, data, mdl, measure, **options, nested=True)
        choice = choice_of(judged)
        assert choice is not None and choice.nested is not None
        flags = f"{base.replace(f'--model {model}', f'--model {mdl}')} --nested yes --folds {folds} {flags}"
        held = choice.nested.after
        rows.append(
            Row(
                name,
                label,
                cal.identifiability.n_identifiable,
                cal.train_after.rms_mm,
                held.rms_mm,
                f"{by}, nested",
                anchor,
                seconds,
                flags.strip(),
            )
        )
        details[label] = {"held_out": held.to_dict(), "train": cal.train_after.to_dict()}
        guard = cal.guard
        if guard is not None and not guard.kept_fit and options["params"] != []:  # a fit it could refuse
            out.append(
                f"  {label}: the guard refuses the fit on all {len(data)} poses (z = {guard.z:.2f} "
                f"against the threshold {guard.z_min:.2f}) and exports the nominal geometry "
                f"({cal.train_after.rms_mm:.2f} mm fitted)"
            )
        if label.endswith("auto *"):
            choice_notes(cal, data, out, label)
    diag_folds = 7 if measure == "distance" else 5
    ext, seconds = timed(
        1,
        pincal.calibrate,
        robot,
        data,
        model,
        measure,
        params="auto",
        extension="auto",
        outliers=THRESHOLD,
        folds=diag_folds,
    )
    assert ext.choice is not None  # its choice is printed with the default row's (the same call)
    if ext.extension is not None:
        chosen = pincal.auto.crossval.cross_validate(
            robot,
            data,
            model,
            measure,
            diag_folds,
            params=ext.choice.params,
            extension=ext.extension,
            partial=True,
        )
        held_by = f"{diag_folds}-fold, chosen model"
        rows.append(
            Row(
                name,
                f"{model}, auto + {ext.extension.label}",
                ext.identifiability.n_identifiable,
                ext.train_after.rms_mm,
                chosen.after.rms_mm,
                held_by,
                anchor,
                seconds,
                f"{base} --extend auto --folds {diag_folds}",
            )
        )
        details["extended"] = {
            "cause": ext.extension.label,
            "cv": chosen.after.to_dict(),
            "cv_urdf": chosen.urdf.to_dict(),
        }
        if measure == "distance":
            urdf, after = chosen.urdf.mean_mm, chosen.after.mean_mm
            out.append(
                f"  held-out mean |distance error| ({diag_folds}-fold, the chosen model): URDF as is "
                f"{urdf:.3f} mm -> {after:.3f} mm ({urdf / after:.2f}x; the paper: 3.5x, 2.96 -> 0.62 mm "
                "on its 16 test pairs)"
            )
    details["report_auto_extend"] = pincal.report_dict(ext, data)
    kind = measure or ("pose" if data.has_orientation else "position")
    out[:0] = [f"{name}: {len(data)} poses, {kind} data, judged by {by} cross-validation"]
    return rows, details


def export(folder: Path | None, name: str, data: Dataset) -> None:
    """Write ``data`` as a pincal CSV into ``folder`` (nothing when None)."""
    if folder is not None:
        folder.mkdir(parents=True, exist_ok=True)
        write_csv(folder / name, data)


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
    parser.add_argument(
        "--export",
        type=Path,
        metavar="DIR",
        help="also write the UR10, Panda and Gao data as pincal CSVs here, for the printed commands",
    )
    parser.add_argument(
        "--markdown", type=Path, metavar="MD", help="also write the table, commands and notes in Markdown"
    )
    args = parser.parse_args(argv)
    if not args.datasets.is_dir():
        parser.error(f"{args.datasets} is not a folder")
    if args.repeat < 1:
        parser.error("--repeat must be at least 1")
    gao_path = args.gao_data or args.datasets.parent / "data" / "gao2013_calibration_poses.csv"
    start = time.perf_counter()

    notes: list[str] = []
    sections: list[list[str]] = [[] for _ in range(4)]
    rows, details = bench_tiago(args.datasets / "tiago_qualisys", args.repeat, sections[0])
    results: dict[str, Any] = {"tiago_qualisys": details}
    exported = args.export or Path("EXPORT")
    robot, data = load_ur10(args.datasets / "ur10_camera")
    new, results["ur10_camera"] = bench_cv(
        "ur10_camera",
        robot,
        data,
        "placements",
        None,
        len(data),
        args.repeat,
        "none published",
        sections[1],
        f"pincal calibrate ur10 {exported}/ur10_camera.csv --tip wrist_3_link",
    )
    rows += new
    sections[1].append(
        "  a UR10e's nominal d4 and d5 exceed the UR10's by "
        f"{UR10E_MINUS_UR10['d4'] * 1e3:.2f} and {UR10E_MINUS_UR10['d5'] * 1e3:.2f} mm "
        "(shoulder_lift_joint.ty and wrist_2_joint.tz move those lengths)"
    )
    export(args.export, "ur10_camera.csv", data)
    robot, data = load_panda(args.datasets / "panda_eye_in_hand")
    new, results["panda_eye_in_hand"] = bench_cv(
        "panda_eye_in_hand",
        robot,
        data,
        "placements",
        None,
        10,
        args.repeat,
        "none published",
        sections[2],
        f"pincal calibrate panda {exported}/panda_eye_in_hand.csv --tip panda_link8",
    )
    rows += new
    export(args.export, "panda_eye_in_hand.csv", data)
    robot, data, source = load_gao(gao_path)
    new, results["gao2013"] = bench_cv(
        "gao2013",
        robot,
        data,
        "poe",
        "distance",
        7,
        args.repeat,
        "paper: 3.5x on URDF",
        sections[3],
        f"pincal calibrate mrres5 {exported}/gao2013.csv",
        models=(),
    )
    rows += new
    export(args.export, "gao2013.csv", data)
    notes = [line for section in sections for line in section]
    results["gao2013"]["source"] = source

    print(
        f"pincal {pincal.__version__}: real-data benchmarks, {os.environ['OPENBLAS_NUM_THREADS']} BLAS "
        f"thread, times are medians of {args.repeat}"
    )
    print(format_table(rows))
    print("commands (the pincal command line that produces each row's model and held-out figure):")
    for r in rows:
        print(f"  {r.dataset} / {r.model}: {r.command}")
    print(
        "params: identified parameters, registration and tool included. RMS of the 3-D position error, "
        "distances for gao2013."
    )
    print("* the command's defaults: --params auto --extend auto (--model placements; gao2013: poe)")
    print()
    print("\n".join(notes))

    scaling_records: list[dict[str, Any]] = []
    if not args.no_scaling:
        tiago = load_tiago(args.datasets / "tiago_qualisys" / "tiago_48_schunk.urdf")
        robots = {"ur5": pincal.load_robot("ur5"), "panda": pincal.load_robot("panda"), "tiago": tiago}
        scaling_records = scaling(robots, repeat=SCALING_REPEAT)
        t_full = results["tiago_qualisys"]["timing"]["placements, auto"]
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

    if args.markdown:
        names = {str(args.datasets).rstrip("/"): "DATASETS_DIR", str(args.export): "EXPORT"}
        markdown(args.markdown, rows, notes, scaling_records, argv, names)
        print(f"Markdown written to {args.markdown}")
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


def markdown(
    path: Path,
    rows: list[Row],
    notes: list[str],
    scaling_records: list[dict[str, Any]],
    argv: list[str] | None,
    names: dict[str, str],
) -> None:
    """The results page's generated part: the table, each row's command, the notes, the scaling."""
    header = ["dataset", "model", "params", "train RMS [mm]", "held-out RMS [mm]", "held out by", "anchor"]
    header.append("time [s]")
    body = [[r.dataset, r.model, r.params, f"{r.train_mm:.2f}", f"{r.held_mm:.2f}"] for r in rows]
    for line, r in zip(body, rows):
        line += [r.held_by, r.anchor, f"{r.seconds:.3f}"]
    commands = [f"- {r.dataset} / {r.model}: `{_named(r.command, names)}`" for r in rows]
    sections = [
        table(header, body),
        "",
        "params: identified parameters, registration and tool included. RMS of the 3-D position "
        "error, distances for gao2013. `*` the command's defaults: `--params auto --extend auto`, "
        "whose URDF + sidecar is the full model; where it names a cause, the next row is the URDF "
        "alone it also writes (the geometry fitted without the cause).",
        "",
        "The `pincal calibrate` command that produces each row's model and held-out figure "
        "(`EXPORT`: the folder given to `--export`):",
        "",
        *commands,
        "",
        "What was chosen, per dataset:",
        "",
        text_block(_named("\n".join(notes), names)),
    ]
    if scaling_records:
        poses = sorted({r["poses"] for r in scaling_records})
        robots = dict.fromkeys(r["robot"] for r in scaling_records)
        grid = [
            [f"{name} ({recs[poses[0]]['joints']} joints)", *(f"{recs[n]['seconds']:.3f}" for n in poses)]
            for name in robots
            for recs in [{r["poses"]: r for r in scaling_records if r["robot"] == name}]
        ]
        sections += ["", "Identification time [s], placements, simulated position data:", ""]
        sections.append(table(["robot", *(f"{n} poses" for n in poses)], grid))
    argv = sys.argv[1:] if argv is None else argv
    write_page(path, command_line("real_data.py", argv, names), sections)


def _named(text: str, names: dict[str, str]) -> str:
    """``text`` with each path of ``names`` written as its name."""
    for path, name in names.items():
        text = text.replace(path, name)
    return text


if __name__ == "__main__":
    main()
