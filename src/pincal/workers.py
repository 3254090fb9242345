"""Worker processes for independent work, and the library's entry points' set-up.

Independent pieces of work (the folds of a cross-validation, the draws of a null) run in worker
processes, one per core (:func:`parallel_map`): Python's own work in pincal's loops is most of
their time, so threads would share one interpreter lock (``benchmarks/speed_bars.py`` times
commands in worker processes and in one, ``PINCAL_WORKERS=1``). Each worker runs with one BLAS
thread and does exactly what the serial loop does, so the answers are bit-for-bit the same
(``tests/test_fast_paths.py``).
``PINCAL_WORKERS``: the number of worker processes (default: the cores this process may use; 1:
serial). A worker never starts workers of its own.

Inside one call of a library entry point (:func:`limited`) or one command, the workers are
forked once, at the first :func:`parallel_map`, and kept until the call returns
(:func:`kept_workers`): a fresh worker's first task costs two to three times the later ones (it
copies every memory page it writes, about 1,500 of them, which is slow on a virtual machine), and
a command runs six batches or more. A task is then sent to the kept workers pickled, the robot
that was there when they forked by reference (:func:`share`); a task that cannot be pickled (a
closure) or is large (:data:`SENT_MAX`) gets workers forked for it, which inherit it.
"""

from __future__ import annotations

import functools
import io
import multiprocessing
import os
import pickle
import signal
import threading
import weakref
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any, TypeVar

from pincal.errors import PincalError
from pincal.threads import blas_threads

#: Environment variable with the number of worker processes (1: serial).
WORKERS_ENV = "PINCAL_WORKERS"
#: A task pickled to more than this many bytes is not sent to kept workers: workers are forked
#: for it and inherit it (large data made after the pool forked).
SENT_MAX = 4_000_000
#: Workers are not kept by a process that has held more than this [MB] (large data): each kept
#: worker keeps its own copy of every page the parent changes after the fork, until the call ends.
KEEP_MAX_MB = 600

F = TypeVar("F", bound=Callable[..., Any])
T = TypeVar("T")
_task: list[Callable[[int], Any]] = []  # the work of the pool being forked (inherited, not pickled)
_in_worker: list[bool] = []  # set in a worker process: its own work runs serially
_shared: weakref.WeakValueDictionary[int, Any] = weakref.WeakValueDictionary()  # share()'s, by id
_at_fork: list[frozenset[int]] = []  # in a worker: the ids of the objects shared when it forked
_scopes: list[list[_Kept]] = []  # kept_workers()'s open scope: its pool, once made


def limited(func: F) -> F:
    """Decorate a library entry point to run with :func:`blas_threads`' default, its worker
    processes kept for the whole call (:func:`kept_workers`)."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with blas_threads(), kept_workers():
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
    """Let ``obj`` cross to and from worker processes by reference, not by value.

    A worker is forked, so an object the parent held when the pool started is the worker's too,
    at the same address. A task sent to kept workers, or an answer, that holds such an object (a
    fold's calibration holds its robot, whose Pinocchio model is 150 kB of pickle) goes with its
    id in its place, and the other side puts its own object back there. Only immutable objects
    may be shared (a robot).
    """
    _shared[id(obj)] = obj


def parallel_map(
    task: Callable[[int], T],
    count: int,
    workers: int | None = None,
    done: Callable[[int], None] | None = None,
) -> list[T]:
    """``[task(0), ..., task(count - 1)]``, computed by forked worker processes.

    The task is inherited by workers forked for it (any callable, a closure too), or sent pickled
    to the workers kept for the call (:func:`kept_workers`); the answers come back pickled, so
    bit-for-bit. An exception a task raises is raised here, the one of the lowest index, as the
    serial loop would raise it.

    Args:
        task: the work of one index.
        count: the number of indices.
        workers: worker processes (default :func:`worker_count`); 1 runs the loop here.
        done: called with each index, in order, once its answer is here.
    """
    available = worker_count(workers)
    n_workers = min(available, count)
    if n_workers <= 1:
        return _serial(task, count, done)
    kept = _kept(available)
    sent = None if kept is None else kept.payload(task)
    if kept is not None and sent is not None:
        return kept.map(sent, count, done)
    _task.append(task)
    held = dict(_shared)  # what the workers may send by reference, alive while they run
    try:
        context = multiprocessing.get_context("fork")
        with context.Pool(n_workers, initializer=_start_worker) as pool:
            return _collected(pool.imap(_run, range(count), chunksize=1), held, done)
    finally:
        _task.pop()


def _collected(
    results: Iterator[tuple[bool, Any]], held: dict[int, Any], done: Callable[[int], None] | None
) -> list[Any]:
    """The workers' answers in index order, each read back with the shared objects ``held``
    (:class:`_Unpickler`); the first exception a task raised is raised here."""
    answers = []
    for k, (ok, answer) in enumerate(results):
        if not ok:
            raise answer
        answers.append(_Unpickler(io.BytesIO(answer), held).load())
        if done is not None:
            done(k)
    return answers


def run_jobs(jobs: Sequence[Callable[[], Any]]) -> list[Any]:
    """Every job's answer, in order: independent work run together by the worker processes
    (:func:`parallel_map`; bit-for-bit the serial loop's answers)."""
    return parallel_map(functools.partial(_run_job, jobs), len(jobs)) if jobs else []


def _run_job(jobs: Sequence[Callable[[], Any]], k: int) -> Any:
    """Job ``k``'s answer (a task that pickles: the workers kept for the call are sent it)."""
    return jobs[k]()


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
    return _answer(_task[-1], index)


def _answer(task: Callable[[int], Any], index: int) -> tuple[bool, Any]:
    """``task(index)`` pickled for the parent (:class:`_Pickler`), or the exception it raised."""
    try:
        with blas_threads(1):
            answer = task(index)
        out = io.BytesIO()
        _Pickler(out, pickle.HIGHEST_PROTOCOL, _shared_at_fork()).dump(answer)
        return True, out.getvalue()
    except Exception as exc:  # noqa: BLE001 (raised again in the parent, at its index)
        return False, exc


def _shared_at_fork() -> dict[int, Any]:
    """In a worker: the shared objects the parent held when it forked, by id."""
    return {token: obj for token in _at_fork[-1] if (obj := _shared.get(token)) is not None}


class _Pickler(pickle.Pickler):
    """A pickler across a fork: a shared object both sides hold (``held``, by id) goes by its id."""

    def __init__(self, file: io.BytesIO, protocol: int, held: dict[int, Any]) -> None:
        super().__init__(file, protocol)
        self.held = held

    def persistent_id(self, obj: Any) -> int | None:
        token = id(obj)
        return token if token in self.held and self.held[token] is obj else None


class _Unpickler(pickle.Unpickler):
    """An unpickler across a fork: an id the other side sent is this side's object ``held[id]``."""

    def __init__(self, file: io.BytesIO, held: dict[int, Any]) -> None:
        super().__init__(file)
        self.held = held

    def persistent_load(self, pid: Any) -> Any:
        return self.held[pid]


@contextmanager
def kept_workers() -> Iterator[None]:
    """Keep the worker processes that :func:`parallel_map` forks first inside the block for
    every later one, and end them with it (an inner block: the outer one's)."""
    if _scopes or _in_worker:
        yield
        return
    scope: list[_Kept] = []
    _scopes.append(scope)
    try:
        yield
    finally:
        _scopes.pop()
        for kept in scope:
            kept.close()


def _kept(n_workers: int) -> _Kept | None:
    """The open scope's pool of ``n_workers`` (forked now if it has none yet), else None."""
    if not _scopes or not _may_fork():
        return None
    scope = _scopes[-1]
    if _peak_mb() > KEEP_MAX_MB:  # large data: kept workers would each keep copies of it
        while scope:
            scope.pop().close()
        return None
    if not scope:
        scope.append(_Kept(n_workers))
    return scope[0] if scope[0].workers == n_workers else None


def _peak_mb() -> float:
    """This process's peak resident memory so far [MB] (0 where it cannot be read)."""
    try:
        import resource
    except ImportError:  # pragma: no cover - Windows, where no worker is forked
        return 0.0
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # kB on Linux


class _Kept:
    """Worker processes kept for a scope, sent each task pickled."""

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self.held = dict(_shared)  # alive while the workers are: their ids stay these objects'
        self.pool = multiprocessing.get_context("fork").Pool(workers, initializer=_start_worker)

    def payload(self, task: Callable[[int], Any]) -> bytes | None:
        """``task`` pickled for the workers, or None: it cannot be pickled, or is too large."""
        out = io.BytesIO()
        try:
            _Pickler(out, pickle.HIGHEST_PROTOCOL, self.held).dump(task)
        except (pickle.PicklingError, TypeError, AttributeError):
            return None
        return out.getvalue() if out.tell() <= SENT_MAX else None

    def map(self, sent: bytes, count: int, done: Callable[[int], None] | None) -> list[Any]:
        """:func:`parallel_map` of the pickled task ``sent`` on the kept workers."""
        jobs = ((sent, k) for k in range(count))
        return _collected(self.pool.imap(_run_sent, jobs, chunksize=1), self.held, done)

    def close(self) -> None:
        """End the workers."""
        self.pool.terminate()
        self.pool.join()


def _run_sent(job: tuple[bytes, int]) -> tuple[bool, Any]:
    """A kept worker's answer to one index of a pickled task (:func:`_run`'s)."""
    sent, index = job
    try:
        task = _Unpickler(io.BytesIO(sent), _shared_at_fork()).load()
    except Exception as exc:  # noqa: BLE001 (raised again in the parent)
        return False, exc
    return _answer(task, index)
