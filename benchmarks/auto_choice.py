"""Automatic model choice on simulated arms: ``params="auto"`` and ``extension="auto"`` of
:func:`pincal.calibrate` against fitting every parameter, in accuracy, false alarms and time.

Every experiment is :func:`pincal.simulate` with its defaults: random geometric errors (joint
placements and zero offsets), the tracker's registration and the measured point on the tip
unknown, 0.03 mm (3e-5 m) of Gaussian noise per coordinate, position data; model ``placements``.

1. **Accuracy** (``--fit-seeds`` seeds per robot, default 10; 150 fitted poses, held-out RMS on
   200 other simulated poses): ``params="auto"`` against ``params="all"``, the held-out RMS of
   each, whether auto kept every identifiable parameter (``cal.choice.params is None``) and the
   ratio auto / all. Acceptance: on every seed auto keeps every identifiable parameter, or its
   held-out RMS is at most 2 % above all's (ratio <= 1.02).
2. **False alarms** (``--seeds`` seeds per robot, default 20; 60 fitted poses, clean data: no
   hidden effect): ``params="auto", extension="auto"``. Acceptance: no cause named
   (``cal.choice.extension is None``) on any seed, i.e. 20 of 20.
4. **Hidden effects** (``--effect-seeds`` seeds per robot and effect, default 5; 60 fitted
   poses, 200 held-out): the truth of part 2 with a joint compliance, an encoder scale or a gear
   harmonic on the second joint, moving the tip by 0.3 mm RMS (:func:`pincal.simulation.truth.hide_effect`),
   calibrated as ``pincal calibrate`` does by default (``extension="auto"``, the balanced delivery
   that keeps the written URDF the best URDF alone), with ``--geometry joint`` (geometry and effect
   fitted together: what the sidecar can reach) and with ``--extend none``; the held-out RMS of each
   against the noise floor (0.03 mm × √3), and the default's URDF alone (its files written and
   loaded back). Acceptance on every seed: ``--geometry joint`` within 1.3 × the floor, and the
   default's URDF alone within 6 % of ``--extend none`` (the default with its sidecar lies between:
   it gives the sidecar only what the geometry could not absorb, :mod:`pincal.auto.balance`).
3. **Time** (100 fitted poses, seed 0): median wall time of ``--repeat`` (default 7) calls of
   ``calibrate(params="auto")`` and of ``calibrate(params="all")`` on the same data, run
   alternately in the same process after one untimed warm-up of each. Acceptance: auto <= 1.5 x
   all. ``calibrate(params="auto", nested=True)`` (the choice judged by 5-fold nested
   cross-validation) is timed too, for information only.

The process exits with status 1 when an acceptance fails. Timings use one BLAS thread (set
below, before numpy loads, as in ``real_data.py``).

Usage::

    python benchmarks/auto_choice.py [--seeds 20] [--fit-seeds 10] [--repeat 7]
        [--robots ur5 panda] [--parts 1 2 3 4] [--effect-seeds 5] [--quick] [--json FILE]
        [--markdown FILE]

``--markdown`` also writes what it prints as a page of ``docs/results/generated``.

``--quick`` runs 3 seeds in parts 1, 2 and 4 and 3 timed repeats.
"""

from __future__ import annotations

import os

import pincal.simulation.truth

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import contextlib  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402
from markdown_page import Tee, command_line, text_block, write_page  # noqa: E402

import pincal  # noqa: E402
from pincal.auto.choice import choice_of  # noqa: E402
from pincal.auto.delivery import exported_errors  # noqa: E402
from pincal.simulation.truth import hide_effect  # noqa: E402

#: Part 1: fitted and held-out poses.
FIT_POSES, TEST_POSES = 150, 200
#: Part 1: auto may lose at most this fraction of held-out RMS against all when it drops parameters.
MAX_LOSS = 0.02
#: Part 2: fitted poses (a diagnosis costs 5-20 s).
CLEAN_POSES = 60
#: Part 3: fitted poses, and the largest accepted time ratio auto / all.
TIMING_POSES, MAX_TIME_RATIO = 100, 1.5
NOISE = 3e-5
#: Part 4: the hidden effects (on the second joint, which gravity loads), their size at the tip
#: [m RMS], how far above the noise floor the joint fit may land, and how much worse than the
#: geometric fit the default's URDF alone may be (the held-out set's noise).
EFFECTS, EFFECT_RMS, FLOOR_FACTOR = ("joint_compliance", "encoder_scale", "gear_harmonic"), 3e-4, 1.3
ALONE_FACTOR = 1.06


def accuracy(robot_name: str, seeds: int) -> dict[str, Any]:
    """Part 1: auto against all on ``seeds`` simulations of ``robot_name``."""
    robot = pincal.load_robot(robot_name)
    rows = []
    for seed in range(seeds):
        _, fit, test = pincal.simulate(robot, n_fit=FIT_POSES, n_test=TEST_POSES, seed=seed, noise=NOISE)
        row: dict[str, Any] = {"seed": seed}
        try:
            auto = pincal.calibrate(robot, fit, params="auto", test=test)
            full = pincal.calibrate(robot, fit, params="all", test=test)
        except Exception as exc:  # a benchmark reports the seed rather than stopping
            row.update(error=f"{type(exc).__name__}: {exc}", ok=False)
            rows.append(row)
            continue
        assert auto.choice is not None and auto.test_after is not None and full.test_after is not None
        params = auto.choice.params
        row["auto_rms_mm"] = auto.test_after.rms_mm
        row["all_rms_mm"] = full.test_after.rms_mm
        row["keeps_all"] = params is None
        row["auto_n_params"] = None if params is None else len(params)
        row["auto_n_identifiable"] = auto.identifiability.n_identifiable
        row["all_n_identifiable"] = full.identifiability.n_identifiable
        row["ratio"] = row["auto_rms_mm"] / row["all_rms_mm"]
        row["ok"] = row["keeps_all"] or row["ratio"] <= 1.0 + MAX_LOSS
        rows.append(row)
    ratios = [r["ratio"] for r in rows if "ratio" in r]
    return {
        "robot": robot_name,
        "seeds": seeds,
        "keeps_all": sum(bool(r.get("keeps_all")) for r in rows),
        "median_ratio": statistics.median(ratios) if ratios else None,
        "worst_ratio": max(ratios) if ratios else None,
        "failures": [r["seed"] for r in rows if not r["ok"]],
        "rows": rows,
    }


def false_alarms(robot_name: str, seeds: int) -> dict[str, Any]:
    """Part 2: ``extension="auto"`` on clean simulations of ``robot_name``."""
    robot = pincal.load_robot(robot_name)
    rows = []
    for seed in range(seeds):
        _, fit, _ = pincal.simulate(robot, n_fit=CLEAN_POSES, n_test=1, seed=seed, noise=NOISE)
        row: dict[str, Any] = {"seed": seed}
        start = time.perf_counter()
        try:
            cal = pincal.calibrate(robot, fit, params="auto", extension="auto")
        except Exception as exc:
            row.update(error=f"{type(exc).__name__}: {exc}", cause=None, ok=False)
            rows.append(row)
            continue
        choice = choice_of(cal)
        assert choice is not None  # params="auto" records its choice
        ext = choice.extension
        row["seconds"] = time.perf_counter() - start
        row["cause"] = None if ext is None else ext.label
        row["keeps_all"] = choice.params is None
        row["rounds"] = len(choice.rounds)
        row["ok"] = ext is None
        rows.append(row)
    seconds = [r["seconds"] for r in rows if "seconds" in r]
    return {
        "robot": robot_name,
        "seeds": seeds,
        "no_cause": sum(r["ok"] for r in rows),
        "keeps_all": sum(bool(r.get("keeps_all")) for r in rows),
        "median_seconds": statistics.median(seconds) if seconds else None,
        "total_seconds": sum(seconds),
        "named": [{"seed": r["seed"], "cause": r["cause"]} for r in rows if r["cause"] is not None],
        "errors": [{"seed": r["seed"], "error": r["error"]} for r in rows if "error" in r],
    }


def hidden_effects(robot_name: str, seeds: int) -> dict[str, Any]:
    """Part 4: the command's default (``extension="auto"``), its joint fit and ``extension=None``
    on simulations with a hidden effect."""
    robot = pincal.load_robot(robot_name)
    floor = NOISE * 3**0.5 * 1e3  # [mm] RMS of a 3-D noise vector
    rows = []
    for effect in EFFECTS:
        ext = pincal.Extension.parse(robot, f"{effect}:{robot.joint_names[1]}")
        for seed in range(seeds):
            truth = pincal.random_truth(robot, seed)
            probe = robot.random_configurations(200, np.random.default_rng(seed + 7))
            hidden = hide_effect(truth, ext, probe, EFFECT_RMS, seed)
            _, fit, test = pincal.simulate(robot, CLEAN_POSES, TEST_POSES, seed, NOISE, truth=hidden)
            default = pincal.calibrate(robot, fit, params="auto", extension="auto", test=test)
            joint = pincal.calibrate(robot, fit, params="auto", extension="auto", test=test, deliver="joint")
            rigid = pincal.calibrate(robot, fit, params="auto", test=test)
            alone = exported_errors(default, fit, test).test
            assert default.test_after and joint.test_after and rigid.test_after and alone
            named = default.extension.label if default.extension is not None else None
            ratio = joint.test_after.rms_mm / floor
            rows.append(
                {
                    "effect": ext.label,
                    "seed": seed,
                    "default_mm": default.test_after.rms_mm,
                    "alone_mm": alone.rms_mm,
                    "joint_mm": joint.test_after.rms_mm,
                    "none_mm": rigid.test_after.rms_mm,
                    "named": named,
                    "ratio": ratio,
                    "ok": ratio <= FLOOR_FACTOR and alone.rms_mm <= ALONE_FACTOR * rigid.test_after.rms_mm,
                }
            )
    return {"robot": robot_name, "floor_mm": floor, "rows": rows}


def timing(robot_name: str, repeat: int) -> dict[str, Any]:
    """Part 3: median wall times of auto, all and auto with nested cross-validation [s]."""
    robot = pincal.load_robot(robot_name)
    _, fit, _ = pincal.simulate(robot, n_fit=TIMING_POSES, n_test=1, seed=0, noise=NOISE)
    calls: dict[str, dict[str, Any]] = {
        "auto": dict(params="auto"),
        "all": dict(params="all"),
        "auto_nested": dict(params="auto", nested=True),
    }
    times: dict[str, list[float]] = {name: [] for name in calls}
    for kwargs in calls.values():  # warm-up: imports, caches
        pincal.calibrate(robot, fit, **kwargs)
    for _ in range(repeat):
        for name, kwargs in calls.items():
            start = time.perf_counter()
            pincal.calibrate(robot, fit, **kwargs)
            times[name].append(time.perf_counter() - start)
    medians = {name: statistics.median(t) for name, t in times.items()}
    ratio = medians["auto"] / medians["all"]
    return {
        "robot": robot_name,
        "poses": TIMING_POSES,
        "repeat": repeat,
        **{f"{name}_s": m for name, m in medians.items()},
        "ratio": ratio,
        "ok": ratio <= MAX_TIME_RATIO,
        "times_s": times,
    }


def _fmt(x: float | None, spec: str) -> str:
    return "-" if x is None else format(x, spec)


def print_accuracy(results: list[dict[str, Any]]) -> None:
    print(f"\n1. params auto vs all: {FIT_POSES} fitted poses, held-out RMS on {TEST_POSES}, noise 0.03 mm")
    print(f"   {'robot':6s} {'seed':>4s} {'auto mm':>8s} {'all mm':>8s} {'ratio':>7s} {'kept':>7s}  ok")
    for res in results:
        for r in res["rows"]:
            if "error" in r:
                print(f"   {res['robot']:6s} {r['seed']:4d}  ERROR {r['error']}")
                continue
            kept = "all" if r["keeps_all"] else f"{r['auto_n_params']}"
            print(
                f"   {res['robot']:6s} {r['seed']:4d} {r['auto_rms_mm']:8.4f} {r['all_rms_mm']:8.4f} "
                f"{r['ratio']:7.4f} {kept:>7s}  {'yes' if r['ok'] else 'NO'}"
            )
    print(f"   {'robot':6s} {'kept all':>9s} {'median ratio':>13s} {'worst ratio':>12s}  failing seeds")
    for res in results:
        print(
            f"   {res['robot']:6s} {res['keeps_all']:>4d} of {res['seeds']:<2d} "
            f"{_fmt(res['median_ratio'], '13.4f')} {_fmt(res['worst_ratio'], '12.4f')}  "
            f"{', '.join(map(str, res['failures'])) or 'none'}"
        )


def print_false_alarms(results: list[dict[str, Any]]) -> None:
    print(f"\n2. extension auto on clean data: {CLEAN_POSES} fitted poses, params auto")
    head = f"{'no cause':>10s} {'kept all':>10s} {'median s':>9s} {'total s':>8s}"
    print(f"   {'robot':6s} {head}  causes named")
    for res in results:
        named = "; ".join(f"seed {n['seed']}: {n['cause']}" for n in res["named"]) or "none"
        errors = "; ".join(f"seed {e['seed']}: {e['error']}" for e in res["errors"])
        print(
            f"   {res['robot']:6s} {res['no_cause']:>4d} of {res['seeds']:<3d} "
            f"{res['keeps_all']:>4d} of {res['seeds']:<3d} {_fmt(res['median_seconds'], '9.1f')} "
            f"{res['total_seconds']:8.0f}  {named}" + (f"  ERRORS {errors}" if errors else "")
        )


def print_timing(results: list[dict[str, Any]]) -> None:
    repeat = results[0]["repeat"] if results else 0
    print(f"\n3. time of calibrate: {TIMING_POSES} fitted poses, median of {repeat} alternating runs [ms]")
    head = f"{'auto':>8s} {'all':>8s} {'auto/all':>9s} {'nested':>8s}"
    print(f"   {'robot':6s} {head}  ok (<= {MAX_TIME_RATIO})")
    for r in results:
        print(
            f"   {r['robot']:6s} {r['auto_s'] * 1e3:8.1f} {r['all_s'] * 1e3:8.1f} {r['ratio']:9.2f} "
            f"{r['auto_nested_s'] * 1e3:8.1f}  {'yes' if r['ok'] else 'NO'}"
        )


def print_hidden_effects(results: list[dict[str, Any]]) -> None:
    print(
        f"\n4. a hidden effect ({EFFECT_RMS * 1e3:.1f} mm RMS at the tip), {CLEAN_POSES} fitted poses, "
        f"held-out RMS on {TEST_POSES} [mm]: the default (--extend auto) with its sidecar and its URDF "
        "alone, --geometry joint, --extend none"
    )
    heads = ("default", "URDF alone", "joint", "--extend none")
    print(f"   {'robot':6s} {'effect':40s} " + " ".join(f"{h:>16s}" for h in heads) + "  named (seeds)")
    for res in results:
        by: dict[str, list[dict[str, Any]]] = {}
        for r in res["rows"]:
            by.setdefault(r["effect"], []).append(r)
        for effect, rows in by.items():
            named = sum(r["named"] == effect for r in rows)
            columns = ([r[k] for r in rows] for k in ("default_mm", "alone_mm", "joint_mm", "none_mm"))
            spans = " ".join(f"{min(v):7.3f}-{max(v):<8.3f}" for v in columns)
            print(
                f"   {res['robot']:6s} {effect:40s} {spans}  "
                f"{named} of {len(rows)}{'' if all(r['ok'] for r in rows) else '  NOT ACCEPTED'}"
            )
        print(
            f"   {res['robot']:6s} noise floor {res['floor_mm']:.3f} mm; accepted: joint up to "
            f"{FLOOR_FACTOR} x the floor, URDF alone up to {ALONE_FACTOR} x --extend none"
        )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20, help="seeds per robot of part 2 (default 20)")
    parser.add_argument("--fit-seeds", type=int, default=10, help="seeds per robot of part 1 (default 10)")
    parser.add_argument("--repeat", type=int, default=7, help="timed runs of part 3 (default 7)")
    parser.add_argument("--robots", nargs="+", default=["ur5", "panda"], help="robots (default ur5 panda)")
    parser.add_argument("--parts", nargs="+", type=int, choices=(1, 2, 3, 4), default=[1, 2, 3, 4])
    parser.add_argument("--effect-seeds", type=int, default=5, help="seeds per robot and effect of part 4")
    parser.add_argument("--quick", action="store_true", help="3 seeds in parts 1 and 2, 3 timed runs")
    parser.add_argument("--json", metavar="FILE", help="write the numbers to FILE")
    parser.add_argument("--markdown", metavar="FILE", help="also write what is printed as a page")
    args = parser.parse_args(argv)
    if args.quick:
        args.seeds, args.fit_seeds, args.repeat = min(args.seeds, 3), min(args.fit_seeds, 3), 3
        args.effect_seeds = min(args.effect_seeds, 3)
    printed = Tee(sys.stdout)
    with contextlib.redirect_stdout(printed):
        ok = run_parts(args)
    if args.markdown:
        given = sys.argv[1:] if argv is None else argv
        write_page(
            Path(args.markdown), command_line("auto_choice.py", given, {}), [text_block(printed.getvalue())]
        )
    return 0 if ok else 1


def run_parts(args: argparse.Namespace) -> bool:
    """Run and print the parts ``args`` asks for; whether every acceptance holds."""
    start = time.perf_counter()
    out: dict[str, Any] = {"robots": args.robots, "noise_m": NOISE}
    ok = True
    if 1 in args.parts:
        out["accuracy"] = [accuracy(name, args.fit_seeds) for name in args.robots]
        print_accuracy(out["accuracy"])
        ok &= not any(res["failures"] for res in out["accuracy"])
    if 2 in args.parts:
        out["false_alarms"] = [false_alarms(name, args.seeds) for name in args.robots]
        print_false_alarms(out["false_alarms"])
        ok &= all(res["no_cause"] == res["seeds"] for res in out["false_alarms"])
    if 4 in args.parts:
        out["hidden_effects"] = [hidden_effects(name, args.effect_seeds) for name in args.robots]
        print_hidden_effects(out["hidden_effects"])
        ok &= all(r["ok"] for res in out["hidden_effects"] for r in res["rows"])
    if 3 in args.parts:
        out["timing"] = [timing(name, args.repeat) for name in args.robots]
        print_timing(out["timing"])
        ok &= all(r["ok"] for r in out["timing"])
    out["seconds"] = time.perf_counter() - start
    out["accepted"] = bool(ok)
    print(f"\nacceptance: {'all passed' if ok else 'FAILED (see above)'}; {out['seconds']:.0f} s")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(out, fh, indent=2)
            fh.write("\n")
    return bool(ok)


if __name__ == "__main__":
    sys.exit(main())
