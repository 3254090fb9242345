"""BLAS threads: one by default.

pincal's dense algebra is small (a few thousand rows of some fifty columns, 6 × 6 and 3 × 3
blocks): starting and synchronising BLAS threads costs more than it saves. On a 2-core machine,
OpenBLAS's default threads made ``calibrate`` on 100 poses 7-10 × slower, and a second thread
(``benchmarks/speed.py``) gains nothing at 1,000 or 10,000 poses and 14 % at 100,000 (the QR
of a 300,000 × 45 Jacobian). So the library's entry points (:func:`pincal.calibrate`,
:func:`pincal.auto.diagnose.diagnose`, ... decorated with :func:`pincal.workers.limited`) and the
command line run with one BLAS thread unless told otherwise:

- the environment variable ``PINCAL_THREADS``: a number of threads, or ``0`` to leave BLAS as
  it is (its own default or the caller's ``threadpoolctl`` limits);
- ``pincal --threads N`` on the command line; :func:`blas_threads` in code.

Independent work runs in worker processes instead (:mod:`pincal.workers`).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from pincal.errors import PincalError

#: Environment variable with the number of BLAS threads (0: leave BLAS as it is).
ENV = "PINCAL_THREADS"
#: Threads when neither the call nor the environment says.
DEFAULT = 1

_controller: list[Any] = []  # threadpoolctl's controller, made at the first limited call


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
