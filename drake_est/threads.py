"""Thread limits for the numerical libraries.

:func:`single_thread_blas` keeps BLAS/OpenMP at one thread while a block of work runs: the diagnosis and the
fleet workers run many small least-squares problems, for which a multi-threaded BLAS only adds contention on a
machine whose cores are already busy (one worker process per core).
"""
from __future__ import annotations

import contextlib


def single_thread_blas():
    """Context limiting BLAS/OpenMP to one thread (threadpoolctl); worker processes also get
    ``OMP_NUM_THREADS=1`` etc. from :func:`drake_est.fleet.run.worker_env`."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - a declared dependency; kept usable without it
        return contextlib.nullcontext()
    return threadpool_limits(1)
