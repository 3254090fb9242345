"""Untrusted work in a child process, within a time and a memory limit.

A xacro's ``${...}`` expressions are Python evaluated by the xacro package: a hostile file can
compute for ever (``${9**9**9}``) or fill the memory, and Ctrl-C cannot interrupt a long integer
power. :func:`run_limited` runs such work in a forked child whose address space is capped, waits
for it at most a given time, and kills it past that. A :class:`~pincal.errors.PincalError` the
work raises is raised again in the caller; any other failure becomes one error naming the work.
Where the platform cannot fork (Windows), the work runs in the process itself, without limits.
"""

from __future__ import annotations

import contextlib
import multiprocessing
from collections.abc import Callable
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any, TypeVar

from pincal.errors import PincalError, RobotError

T = TypeVar("T")


def run_limited(
    work: Callable[..., T],
    args: tuple[Any, ...],
    *,
    seconds: float,
    memory: int,
    what: str,
    error: type[PincalError] = RobotError,
) -> T:
    """``work(*args)`` in a forked child, within ``seconds`` [s] and ``memory`` [B] more than the
    process holds.

    Args:
        work, args: the function (its result must pickle) and its arguments.
        seconds, memory: the limits.
        what: the start of the error message ("cannot process xacro FILE").
        error: the class of the error raised when the work fails otherwise than with a
            :class:`PincalError`, or goes past a limit.

    Raises:
        PincalError: the work's own, or ``error`` past a limit or on another failure.
    """
    if "fork" not in multiprocessing.get_all_start_methods():  # pragma: no cover - Windows
        return work(*args)
    context = multiprocessing.get_context("fork")
    mine, theirs = context.Pipe(duplex=False)
    child = context.Process(target=_child, args=(theirs, work, args, memory, what), daemon=True)
    child.start()
    theirs.close()
    try:
        if not mine.poll(seconds):
            raise error(f"{what}: it did not finish in {seconds:.0f} s (a computation without end?)")
        kind, value = mine.recv()
    except EOFError:
        raise error(f"{what}: the child process doing it died (exit code {child.exitcode})") from None
    finally:
        if child.is_alive():
            child.kill()
        child.join()
        mine.close()
    if kind == "raise":
        raise value
    if kind == "error":
        raise error(value)
    return value


def _child(conn: Connection, work: Callable[..., Any], args: tuple[Any, ...], memory: int, what: str) -> None:
    """The child's side of :func:`run_limited`: cap the memory, work, send the outcome."""
    with contextlib.suppress(ValueError, OSError, ImportError):
        import resource

        held = int(Path("/proc/self/statm").read_text().split()[0]) * resource.getpagesize()  # [B]
        resource.setrlimit(resource.RLIMIT_AS, (held + memory, resource.RLIM_INFINITY))
    outcome: tuple[str, Any]
    try:
        outcome = ("ok", work(*args))
    except PincalError as exc:
        outcome = ("raise", exc)
    except MemoryError:
        outcome = ("error", f"{what}: it needs more than {memory / 1e9:.1f} GB of memory")
    except BaseException as exc:  # noqa: BLE001 - whatever the child meets, the caller says it
        outcome = ("error", f"{what}: {' '.join(str(exc).split())}")
    conn.send(outcome)
    conn.close()
