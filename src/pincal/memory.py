"""Large arrays' memory kept for reuse by the C allocator (the ``pincal`` command).

glibc's ``malloc`` gives an allocation above its mmap threshold (128 kB, raised as large blocks
are freed, to at most 32 MB) pages of its own, and hands them back to the kernel when it is
freed: the next one of the same size is faulted in again, page by page, and zeroed. A large
calibration makes and drops arrays of 10-40 MB for each block of poses in every pass over its
rows (:mod:`pincal.identify.chunked`). On 200,000 pose rows in one process the command spent
5.1-6.6 s in the kernel, 1.8-2.1 s once freed memory stays with the process (3 runs each,
alternating: 31.7 against 26.5 s in all); on 10⁶ pose rows with another process keeping a core
busy it took 102-103 against 95-98 s (2 runs each), its peak memory the same (1.42 GB).

Only the command sets this (a library caller's process is its own); elsewhere than glibc it does
nothing.
"""

from __future__ import annotations

import ctypes

#: ``mallopt`` parameters (glibc's ``malloc.h``).
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
#: Allocations below this [bytes] come from the heap, and freed memory up to this stays there.
KEPT_BYTES = 1 << 30


def keep_freed_memory() -> bool:
    """Have the C allocator keep large freed blocks for reuse; whether it could (glibc only)."""
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (AttributeError, OSError):  # not glibc (macOS, musl...): its own policy stays
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    return bool(mallopt(M_MMAP_THRESHOLD, KEPT_BYTES)) and bool(mallopt(M_TRIM_THRESHOLD, KEPT_BYTES))
