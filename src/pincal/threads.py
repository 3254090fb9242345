"""BLAS threads: one by default.

pincal's dense algebra is small (a few thousand rows of some fifty columns, 6 × 6 and 3 × 3
blocks): starting and synchronising BLAS threads costs more than it saves. On a 2-core machine,
OpenBLAS's default threads made ``calibrate`` on 100 poses 7-10 × slower, and a second thread
(``benchmarks/speed.py``) gains nothing at 1,000 or 10,000 poses and 14 % at 100,000 (the QR
of a 300,000 × 45 Jacobian). So the library's entry points (:func:`pincal.calibrate`,
:func:`pincal.auto.diagnose.diagnose`, ...) and the command line run with one BLAS thread unless told
otherwise:

- the environment variable ``PINCAL_THREADS``: a number of threads, or ``0`` to leave BLAS as
  it is (its own default or the caller's ``threadpoolctl`` limits);
- ``pincal --threads N`` on the command line; :func:`blas_threads` in code.

Independent pieces of work (the folds of a cross-validation) run in worker processes, one per
core (:func:`parallel_map`): Python's own work in pincal's loops is most of their time, so
threads would share one interpreter lock (``benchmarks/speed.py`` measures processes against
the serial loop). Each worker runs with one
BLAS thread and does exactly what the serial loop does, so the answers are bit-for-bit the same
(``tests/test_fast_paths.py``). ``PINCAL_WORKERS``: the number of worker processes (default:
the cores this process may use; 1: serial). A worker never starts workers of its own.
"""

from __future__ import annotations

import functools
import io
import multiprocessing
import os
import pickle
import signal
import sys
import threading
import weakref
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

from pincal.errors import PincalError

#: Environment variable with the number of BLAS threads (0: leave BLAS as it is).
ENV = "PINCAL_THREADS"
#: Threads when neither the call nor the environment says.
DEFAULT = 1

#: Environment variable with the number of worker processes (1: serial).
WORKERS_ENV = "PINCAL_WORKERS"

F = TypeVar("F", bound=Callable[..., Any])
T = TypeVar("T")
_controller: list[Any] = []  # threadpoolctl's controller, made at the first limited call
_task: list[Callable[[int], Any]] = []  # the work of the pool being forked (inherited, not pickled)
_in_worker: list[bool] = []  # set in a worker process: its own work runs serially
_shared: weakref.WeakValueDictionary[int, Any] = weakref.WeakValueDictionary()  # share()'s, by id
_at_fork: list[frozenset[int]] = []  # in a worker: the ids of the objects shared when it forked


def thread_count(value: int | str | None = None) -> int:
    """The BLAS threads to use: ``value``, else ``$PINCAL_THREADS``, else 1 (0: unlimited).

    Raises:
        PincalError: not a whole number of 0 or more.
    """
    text = os.environ.get(ENV, "") if value is None else str(value)
    if text.strip() == "":
        return DEFAULT
    try:
        count = int(text)
    except ValueError:
        raise PincalError(
            f"{ENV}={text!r}: give a number of BLAS threads, or 0 to leave BLAS as it is"
        ) from None
    if count < 0:
        raise PincalError(f"{ENV}={text!r}: give a number of BLAS threads, or 0 to leave BLAS as it is")
    return count


@contextmanager
def blas_threads(value: int | str | None = None) -> Iterator[None]:
    """Run the block with ``value`` BLAS threads (default: :func:`thread_count`)."""
    count = thread_count(value)
    if count == 0:
        yield
        return
    if not _controller:
        from threadpoolctl import ThreadpoolController  # here: after NumPy and SciPy are loaded

        _controller.append(ThreadpoolController())
    with _controller[0].limit(limits=count, user_api="blas"):
        yield


def load_blas_with_default() -> None:
    """Have OpenBLAS load with :func:`thread_count`'s threads (``OPENBLAS_NUM_THREADS``), unless
    NumPy is loaded already, the variable is set, or ``PINCAL_THREADS`` is 0 or not a number."""
    if "numpy" in sys.modules or "OPENBLAS_NUM_THREADS" in os.environ:
        return
    try:
        count = thread_count()
    except PincalError:
        return  # said where the count is used
    if count > 0:
        os.environ["OPENBLAS_NUM_THREADS"] = str(count)


def limited(func: F) -> F:
    """Decorate a library entry point to run with :func:`blas_threads`' default."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with blas_threads():
            return func(*args, **kwargs)

    return wrapper  # type: ignore[return-value]


def worker_count(value: int | str | None = None) -> int:
    """Worker processes for independent work: ``value``, else ``$PINCAL_WORKERS``, else the
    cores this process may use; 1 where forking is not safe or not allowed: inside a worker, in
    a daemonic process (a ``multiprocessing`` pool's worker may have no children), off the main
    thread (another thread may hold a lock the child would inherit locked), or where processes
    cannot be forked.

    Raises:
        PincalError: not a whole number of 1 or more.
    """
    if _in_worker or not _may_fork():
        return 1
    text = os.environ.get(WORKERS_ENV, "") if value is None else str(value)
    if text.strip() == "":
        return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    try:
        count = int(text)
    except ValueError:
        count = 0
    if count < 1:
        raise PincalError(f"{WORKERS_ENV}={text!r}: give a number of worker processes, 1 or more")
    return count


def _may_fork() -> bool:
    """Whether this process may fork workers (see :func:`worker_count`)."""
    return (
        "fork" in multiprocessing.get_all_start_methods()
        and not multiprocessing.current_process().daemon
        and threading.current_thread() is threading.main_thread()
    )


def share(obj: Any) -> None:
    """Let worker processes send ``obj`` back by reference, not by value.

    A worker is forked, so an object the parent held when the pool started is the worker's too,
    at the same address. An answer that holds such an object (a fold's calibration holds its
    robot, whose Pinocchio model is 150 kB of pickle) is sent with its id in its place, and the
    parent puts its own object back there. Only immutable objects may be shared (a robot).
    """
    _shared[id(obj)] = obj


def parallel_map(
    task: Callable[[int], T],
    count: int,
    workers: int | None = None,
    done: Callable[[int], None] | None = None,
) -> list[T]:
    """``[task(0), ..., task(count - 1)]``, computed by forked worker processes.

    The task is inherited by the workers (any callable, a closure too); only the indices go to
    them and only the answers (pickled, so bit-for-bit) come back. An exception a task raises
    is raised here, the one of the lowest index, as the serial loop would raise it.

    Args:
        task: the work of one index.
        count: the number of indices.
        workers: worker processes (default :func:`worker_count`); 1 runs the loop here.
        done: called with each index, in order, once its answer is here.
    """
    n_workers = min(worker_count(workers), count)
    if n_workers <= 1:
        return _serial(task, count, done)
    _task.append(task)
    held = dict(_shared)  # what the workers may send by reference, alive while they run
    try:
        context = multiprocessing.get_context("fork")
        with context.Pool(n_workers, initializer=_start_worker) as pool:
            answers = []
            for k, (ok, answer) in enumerate(pool.imap(_run, range(count), chunksize=1)):
                if not ok:
                    raise answer
                answers.append(_Unpickler(io.BytesIO(answer), held).load())
                if done is not None:
                    done(k)
            return answers
    finally:
        _task.pop()


def _serial(task: Callable[[int], T], count: int, done: Callable[[int], None] | None) -> list[T]:
    """The loop of :func:`parallel_map`, in this process."""
    answers = []
    for k in range(count):
        answers.append(task(k))
        if done is not None:
            done(k)
    return answers


def _start_worker() -> None:
    """A worker: Ctrl-C is the parent's to handle, SIGTERM ends it, its BLAS runs one thread."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    _in_worker.append(True)
    _at_fork.append(frozenset(_shared.keys()))


def _run(index: int) -> tuple[bool, Any]:
    """One index's answer, or the exception it raised (``(False, exc)``)."""
    try:
        with blas_threads(1):
            answer = _task[-1](index)
        out = io.BytesIO()
        _Pickler(out, pickle.HIGHEST_PROTOCOL).dump(answer)
        return True, out.getvalue()
    except Exception as exc:  # noqa: BLE001 (raised again in the parent, at its index)
        return False, exc


class _Pickler(pickle.Pickler):
    """A worker's pickler: a shared object the parent holds too (:func:`share`) goes by its id."""

    def persistent_id(self, obj: Any) -> int | None:
        token = id(obj)
        return token if token in _at_fork[-1] and _shared.get(token) is obj else None


class _Unpickler(pickle.Unpickler):
    """The parent's unpickler: an id a worker sent is the parent's shared object ``held[id]``."""

    def __init__(self, file: io.BytesIO, held: dict[int, Any]) -> None:
        super().__init__(file)
        self.held = held

    def persistent_load(self, pid: Any) -> Any:
        return self.held[pid]
