"""The fast paths give what the plain ones give.

- :func:`pincal.kinematics.chain.log3` and :func:`~pincal.kinematics.chain.jlog3`, vectorised over poses,
  equal Pinocchio's ``log3`` and ``Jlog3`` from tiny angles to nearly half a turn;
- ``Problem.jacobian(theta, free)`` is the full Jacobian's columns ``free``, for every measure;
- the linearised screen of :mod:`pincal.auto.screening` ranks a hidden effect first and its
  cross-validated RMS is close to the nonlinear cross-validation's;
- one BLAS thread by default, ``PINCAL_THREADS`` and ``--threads`` to change it;
- the folds of a cross-validation run in two processes, and the answer is bit-for-bit the
  serial one; a worker's answer holds the parent's robot, not a copy;
- Levenberg-Marquardt finds SciPy's least-squares minimum, and follows a curved valley to it;
- ``import pincal`` and ``pincal --help`` load neither NumPy nor Pinocchio; ``calibrate`` and
  ``diagnose`` load neither ``scipy.optimize`` nor ``scipy.special`` (0.3 s of start-up), their
  outlier screen's robust refit included, until a robust loss is asked for (``--loss``);
- the diagnosis' batches of worker jobs and the command's BLAS loaded with one thread.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pinocchio as pin
import pytest

import pincal
import pincal.kinematics.chain
from pincal.auto.choice import ModelChoice
from pincal.auto.crossval import cross_validate
from pincal.auto.screening import Linearised
from pincal.identify.solver import set_up
from pincal.kinematics.effects import Extension, candidates
from pincal.kinematics.so3 import jlog3, log3
from pincal.simulation.truth import hide_effect
from pincal.threads import blas_threads, thread_count
from pincal.workers import kept_workers, parallel_map, worker_count


def _rotations(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    scales = (1e-9, 1e-6, 1e-3, 5e-2, 1.0, 3.0)
    vectors = np.concatenate([rng.normal(size=(20, 3)) * s for s in scales])
    vectors[-10:] *= (np.pi - 2e-3) / np.linalg.norm(vectors[-10:], axis=1, keepdims=True)  # near π
    return np.array([pin.exp3(v) for v in vectors])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_log3_and_jlog3_equal_pinocchio(seed: int) -> None:
    rot = _rotations(seed)
    expected = np.array([pin.log3(r) for r in rot])
    assert np.abs(log3(rot) - expected).max() < 1e-9  # [rad], angles up to π
    # Pinocchio's closed form loses digits below 1e-3 rad, where jlog3 uses its series.
    assert np.abs(jlog3(rot) - np.array([pin.Jlog3(r) for r in rot])).max() < 1e-8


@pytest.mark.parametrize("measure", ["position", "pose", "distance"])
def test_jacobian_columns_are_the_full_jacobians(get_robot, measure: str) -> None:
    robot = get_robot("panda")
    _, fit, _ = pincal.simulate(robot, n_fit=15, n_test=0, seed=4, rot_noise=1e-3)
    ext = Extension.parse(robot, "joint_compliance:panda_joint2")
    setup = set_up(robot, fit, "poe", measure, extension=ext)
    problem = setup.problem
    theta = problem.initial_theta() + np.random.default_rng(5).normal(0.0, 1e-3, problem.n_params)
    full = problem.jacobian(theta)
    free = np.random.default_rng(6).random(problem.n_params) < 0.5
    assert free.sum() > 5
    assert np.array_equal(problem.jacobian(theta, free), full[:, free])
    assert np.array_equal(problem.jacobian(theta, np.flatnonzero(free)), full[:, free])


def test_linearised_screen_matches_the_nonlinear_cross_validation(get_robot) -> None:
    robot = get_robot("ur5")
    truth, fit, _ = pincal.simulate(robot, n_fit=60, n_test=0, seed=3)
    hidden = Extension.parse(robot, "joint_compliance:shoulder_lift_joint")
    truth = hide_effect(truth, hidden, fit.q, 4e-4, seed=3)
    fit = truth.measure(fit.q, 3e-5, None, seed=5)
    base = pincal.calibrate(robot, fit)
    lin = Linearised(base, fit, folds=5, seed=0)
    decoy = Extension.parse(robot, "encoder_scale:wrist_2_joint")
    screens = {ext.label: lin.screen(ext) for ext in (hidden, decoy)}
    plain = lin.screen()
    assert screens[hidden.label].cv_rms_mm < 0.7 * plain.cv_rms_mm
    assert screens[hidden.label].cv_rms_mm < screens[decoy.label].cv_rms_mm
    joint = {"extension": hidden, "deliver": "none"}  # the screen linearises the joint fit
    nonlinear = cross_validate(robot, fit, "placements", None, 5, 0, **joint).after.rms_mm
    assert screens[hidden.label].cv_rms_mm == pytest.approx(nonlinear, rel=0.05)
    no_effect = cross_validate(robot, fit, "placements", None, 5, 0).after.rms_mm
    assert plain.cv_rms_mm == pytest.approx(no_effect, rel=0.05)
    found, effect = screens[hidden.label].params, truth.effect
    assert found is not None and effect is not None and found[0] == pytest.approx(effect[0], rel=0.2)


@pytest.mark.parametrize("measure", ["position", "pose"])
def test_every_candidate_screened_at_once_is_each_screened_alone(get_robot, measure: str) -> None:
    robot = get_robot("ur5")
    truth, fit, _ = pincal.simulate(robot, n_fit=40, n_test=0, seed=3, rot_noise=5e-4)
    hidden = Extension.parse(robot, "joint_compliance:shoulder_lift_joint")
    fit = hide_effect(truth, hidden, fit.q, 4e-4, seed=3).measure(fit.q, 3e-5, 5e-4, seed=5)
    base = pincal.calibrate(robot, fit, measure=measure, deliver="none")
    pool = candidates(robot, None)
    lin = Linearised(base, fit, folds=5, seed=0, pool=pool)
    plain, each = lin.screen_all(pool)
    for alone, together in zip([lin.screen(), *(lin.screen(ext) for ext in pool)], [plain, *each]):
        assert together.cv_rms_mm == pytest.approx(alone.cv_rms_mm, rel=1e-9)
        assert together.rss == pytest.approx(alone.rss, rel=1e-9)
        assert np.allclose(together.params, alone.params, rtol=1e-7, atol=1e-15)
        assert together.identifiable == alone.identifiable
    assert min(each, key=lambda screen: screen.cv_rms_mm) is each[[e.label for e in pool].index(hidden.label)]


def _blas_threads() -> int:
    from threadpoolctl import threadpool_info

    return max(lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas")


def test_one_blas_thread_by_default(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("PINCAL_THREADS", raising=False)
    assert thread_count() == 1
    with blas_threads():
        assert _blas_threads() == 1
    monkeypatch.setenv("PINCAL_THREADS", "2")
    assert thread_count() == 2
    with blas_threads():
        assert _blas_threads() == 2
    monkeypatch.setenv("PINCAL_THREADS", "0")
    assert thread_count() == 0
    for bad in ("-1", "two", "1.5"):
        monkeypatch.setenv("PINCAL_THREADS", bad)
        with pytest.raises(pincal.PincalError, match="PINCAL_THREADS"):
            thread_count()


def test_help_loads_no_numpy() -> None:
    code = (
        "import sys, pincal, pincal.cli.parser\n"
        "pincal.cli.parser.build_parser().format_help()\n"
        "print(sorted(m for m in ('numpy', 'pinocchio', 'scipy') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's allocator")
@pytest.mark.parametrize("kept", [False, True])
def test_freed_large_arrays_are_reused_without_new_page_faults(kept: bool) -> None:
    """Once the command has told the allocator to keep freed memory, 10 arrays of 40 MB made and
    dropped one after another fault in no new page after the first; by default, each one does."""
    code = (
        "import resource, numpy as np\n"
        "from pincal.memory import keep_freed_memory\n"
        f"assert {kept} is False or keep_freed_memory()\n"
        "a = np.ones(5_000_000); del a\n"
        "before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt\n"
        "for _ in range(10):\n"
        "    a = np.ones(5_000_000); del a\n"
        "print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    faults = int(out.stdout)
    assert faults < 10 if kept else faults >= 10


def test_commands_load_no_scipy_optimize() -> None:
    code = (
        "import sys, pincal.cli.calibrate, pincal.cli.diagnose\n"
        "print(sorted(m for m in ('scipy.optimize', 'scipy.special') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_a_default_calibration_with_its_outlier_screen_loads_no_scipy_optimize(tmp_path) -> None:
    """The outlier screen's robust refit runs (a pose 5 mm off is left out) and SciPy's
    optimisers stay unloaded: the refit is :func:`pincal.identify.lm.soft_l1_roots`'s."""
    robot = pincal.load_robot("ur5")
    _, fit, _ = pincal.simulate(robot, n_fit=40, n_test=0, seed=0)
    fit.points[5] += 0.005
    pincal.write_csv(tmp_path / "fit.csv", fit)
    code = (
        "import sys, io, contextlib, pincal.cli\n"
        "with contextlib.redirect_stdout(io.StringIO()) as out:\n"
        f"    pincal.cli.main(['calibrate', 'ur5', {str(tmp_path / 'fit.csv')!r}, '--extend', 'none'])\n"
        "print('excluded' if 'left out' in out.getvalue() else 'kept', 'scipy.optimize' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["excluded", "False"]


def test_cli_threads_option_is_checked() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "pincal.cli", "--threads", "-2", "demo"], capture_output=True, text=True
    )
    assert out.returncode == 2
    assert out.stderr.startswith("pincal: error:") and "--threads" in out.stderr


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_levenberg_marquardt_finds_least_squares_minimum(seed: int) -> None:
    from scipy.optimize import least_squares

    from pincal.identify.lm import levenberg_marquardt

    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 3.0, 40)
    truth = np.array([2.0, -1.3, 0.5, 0.7])
    y = truth[0] * np.exp(truth[1] * t) + truth[2] * np.sin(truth[3] * 4 * t) + rng.normal(0, 0.01, t.size)

    def fun(x: np.ndarray) -> np.ndarray:
        return x[0] * np.exp(x[1] * t) + x[2] * np.sin(x[3] * 4 * t) - y

    def jac(x: np.ndarray) -> np.ndarray:
        e, s = np.exp(x[1] * t), np.sin(x[3] * 4 * t)
        return np.column_stack([e, x[0] * t * e, s, x[2] * 4 * t * np.cos(x[3] * 4 * t)])

    start = truth + rng.normal(0.0, 0.1, 4)
    ours = levenberg_marquardt(fun, jac, start, np.ones(4))
    reference = least_squares(fun, start, jac=jac, method="lm", xtol=1e-14, ftol=1e-14, gtol=1e-14)
    assert ours.success and ours.status in (1, 2, 3)
    assert np.allclose(ours.x, reference.x, rtol=1e-7, atol=1e-9)
    assert ours.cost == pytest.approx(reference.cost, rel=1e-10)
    assert np.abs(jac(ours.x).T @ fun(ours.x)).max() < 1e-9  # the normal equations hold


@pytest.mark.parametrize("start", [(-1.2, 1.0), (-2.0, 2.0), (-0.8, 1.5)])
def test_levenberg_marquardt_follows_a_curved_valley(start: tuple[float, float]) -> None:
    """Rosenbrock's valley as least squares: the damping that follows the gain ratio reaches its
    minimum within the evaluations a fit may take (a factor of 10 each way crawls and stops short)."""
    from pincal.identify.lm import levenberg_marquardt
    from pincal.identify.solver import MAX_EVALUATIONS

    def fun(x: np.ndarray) -> np.ndarray:
        return np.array([100.0 * (x[1] - x[0] ** 2), 1.0 - x[0]])

    def jac(x: np.ndarray) -> np.ndarray:
        return np.array([[-200.0 * x[0], 100.0], [-1.0, 0.0]])

    found = levenberg_marquardt(fun, jac, np.array(start), np.ones(2), max_nfev=MAX_EVALUATIONS)
    assert found.success, found.message
    assert np.allclose(found.x, [1.0, 1.0], atol=1e-8)


def test_parallel_map_uses_two_processes_in_order() -> None:
    import multiprocessing
    import os

    both = multiprocessing.get_context("fork").Barrier(2)  # the first two tasks meet: two processes

    def task(k: int) -> tuple[int, int]:
        if k < 2:
            both.wait(timeout=60)
        return k * k, os.getpid()

    answers = parallel_map(task, 6, workers=2)
    assert [a for a, _ in answers] == [k * k for k in range(6)]
    assert len({pid for _, pid in answers}) == 2 and os.getpid() not in {pid for _, pid in answers}


def test_parallel_map_raises_the_first_error_as_the_loop_would() -> None:
    def task(k: int) -> int:
        if k >= 2:
            raise pincal.IdentifiabilityError(f"fold {k}", 10 + k)
        return k

    with pytest.raises(pincal.IdentifiabilityError, match="fold 2") as caught:
        parallel_map(task, 5, workers=2)
    assert caught.value.poses_needed == 12


class _Held:
    """An object a worker's answer may hold."""


def test_a_worker_sends_a_shared_object_back_by_reference(get_robot) -> None:
    from pincal.workers import share

    robot, shared = get_robot("ur5"), _Held()
    share(shared)

    def task(k: int) -> tuple[object, object, object]:
        made_here = _Held()
        share(made_here)  # made in the worker: the parent has no such object, it comes by value
        return robot, shared, made_here

    for back_robot, back_shared, made in parallel_map(task, 3, workers=2):
        assert back_robot is robot and back_shared is shared  # the parent's own objects
        assert isinstance(made, _Held) and made is not shared


def _square_and_pid(k: int) -> tuple[int, int]:
    import os

    return k * k, os.getpid()


def _pids_of_two_calls() -> tuple[set[int], set[int]]:
    first = parallel_map(_square_and_pid, 6, workers=2)
    second = parallel_map(_square_and_pid, 6, workers=2)
    assert [a for a, _ in first] == [a for a, _ in second] == [k * k for k in range(6)]
    return {pid for _, pid in first}, {pid for _, pid in second}


def test_workers_are_kept_for_a_call_and_end_with_it(monkeypatch: pytest.MonkeyPatch) -> None:
    import os

    import pincal.workers

    monkeypatch.setenv("PINCAL_WORKERS", "2")
    with kept_workers():
        first, second = _pids_of_two_calls()
        kept = pincal.workers._scopes[-1][0].pool
        assert first | second <= {worker.pid for worker in kept._pool}  # both calls: the kept two
        assert [a for a, _ in parallel_map(lambda k: (k + 1, 0), 3)] == [1, 2, 3]  # a closure: forked
    assert os.getpid() not in first
    assert all(not worker.is_alive() for worker in kept._pool)  # ended with the block
    first, second = _pids_of_two_calls()
    assert not first & second  # outside a call: forked for each
    monkeypatch.setattr(pincal.workers, "KEEP_MAX_MB", 0.0)
    with kept_workers():  # a large process keeps none: each would hold copies of its pages
        first, second = _pids_of_two_calls()
    assert not first & second


def test_workers_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    import threading

    monkeypatch.setenv("PINCAL_WORKERS", "3")
    assert worker_count() == 3
    off_main: list[int] = []
    thread = threading.Thread(target=lambda: off_main.append(worker_count()))
    thread.start()
    thread.join()
    assert off_main == [1]  # forking off the main thread is not safe: serial
    for bad in ("0", "two"):
        monkeypatch.setenv("PINCAL_WORKERS", bad)
        with pytest.raises(pincal.PincalError, match="PINCAL_WORKERS"):
            worker_count()


def test_nested_cross_validation_in_two_processes_is_the_serial_one(
    get_robot, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Four of the five folds in the two workers, the fifth here with the workers for its own
    diagnosis: bit-for-bit the serial loop."""
    robot = get_robot("ur5")
    _, fit, _ = pincal.simulate(robot, n_fit=40, n_test=0, seed=3)
    runs = {}
    for workers in ("1", "2"):
        monkeypatch.setenv("PINCAL_WORKERS", workers)
        runs[workers] = pincal.calibrate(robot, fit, params="auto", extension="auto", nested=True)
    one, two = runs["1"].choice, runs["2"].choice
    assert isinstance(one, ModelChoice) and isinstance(two, ModelChoice)
    serial, parallel = one.nested, two.nested
    assert serial is not None and parallel is not None
    assert serial.after == parallel.after and serial.before == parallel.before
    for fold_one, fold_two in zip(serial.calibrations, parallel.calibrations):
        assert np.array_equal(fold_one.theta, fold_two.theta)
    assert np.array_equal(runs["1"].theta, runs["2"].theta)


@pytest.mark.parametrize("quick", [False, True])
def test_diagnosis_in_two_processes_is_the_serial_one(
    get_robot, monkeypatch: pytest.MonkeyPatch, quick: bool
) -> None:
    """The baseline's folds, the finalists' fits and all their folds run as one batch of
    workers: every figure and fit is the serial loop's."""
    robot = get_robot("ur5")
    truth, fit, _ = pincal.simulate(robot, n_fit=40, n_test=0, seed=4)
    hidden = Extension.parse(robot, "gear_harmonic:elbow_joint")
    fit = hide_effect(truth, hidden, fit.q, 3e-4, seed=4).measure(fit.q, 3e-5, None, seed=6)
    runs = {}
    for workers in ("1", "2"):
        monkeypatch.setenv("PINCAL_WORKERS", workers)
        runs[workers] = pincal.diagnose(robot, fit, quick=quick)
    one, two = runs["1"], runs["2"]
    assert one.cause is not None and one.cause.extension.label == hidden.label
    assert one.baseline_cv_rms_mm == two.baseline_cv_rms_mm
    assert [c.extension.label for c in one.candidates] == [c.extension.label for c in two.candidates]
    assert [c.cv_rms_mm for c in one.candidates] == [c.cv_rms_mm for c in two.candidates]
    finals = [(a, b) for a, b in zip(one.candidates, two.candidates) if a.calibration is not None]
    assert finals
    for a, b in finals:
        assert b.calibration is not None and np.array_equal(a.calibration.theta, b.calibration.theta)


@pytest.mark.parametrize(("pincal_threads", "loaded"), [(None, 1), ("0", None)])
def test_the_command_loads_blas_with_its_threads(pincal_threads: str | None, loaded: int | None) -> None:
    """``pincal.cli`` has OpenBLAS load with one thread (its workers then start none), unless
    ``PINCAL_THREADS=0`` leaves BLAS as it is."""
    import os

    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "PINCAL_THREADS")}
    if pincal_threads is not None:
        env["PINCAL_THREADS"] = pincal_threads
    code = (
        "import os, pincal.cli, numpy\n"
        "from threadpoolctl import threadpool_info\n"
        "print(os.environ.get('OPENBLAS_NUM_THREADS'), "
        "min(i['num_threads'] for i in threadpool_info() if i['user_api'] == 'blas'))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    said, threads = out.stdout.split()
    assert said == str(loaded)
    if loaded is not None:
        assert int(threads) == loaded
