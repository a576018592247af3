"""Process-wide settings that must be made before numpy is imported."""

from __future__ import annotations

import os

#: Environment variables that set the thread count of the BLAS libraries numpy may use.
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def limit_blas_threads() -> None:
    """Run BLAS and LAPACK single-threaded unless the user chose otherwise.

    Identification solves many small dense problems (a few hundred rows, a few columns); a
    threaded BLAS only adds synchronisation there, and on a loaded machine its threads stall a
    fit for tens of milliseconds. A value already set in the environment is kept. Call this
    before the first import of numpy, or it has no effect.
    """
    for variable in BLAS_THREAD_VARIABLES:
        os.environ.setdefault(variable, "1")
