"""Load BLAS with the command's thread count (imported first by :mod:`pincal.cli`).

OpenBLAS reads ``OPENBLAS_NUM_THREADS`` once, when NumPy loads it. Loaded with its default (one
thread per core) and limited to one afterwards (:func:`pincal.threads.blas_threads`), it starts
its threads again in every forked worker at the first call: about 0.1 s of two busy cores per
worker, paid by every cross-validation the workers run (measured on TIAGo's command: its folds
no faster in two processes than in one). Loaded with one thread, a worker starts none; a larger
``--threads`` or ``PINCAL_THREADS`` still raises it at run time.
"""

from __future__ import annotations

from pincal.threads import load_blas_with_default

load_blas_with_default()
