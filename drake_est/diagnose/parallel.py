"""Threads for one diagnosis: the candidates of a round, and the trial shapes of a detector, at once.

A round of the forward search (:func:`drake_est.diagnose.core._round`) proposes about ten candidate extensions
per joint and tests each against the current model; the candidates are independent of one another, and most of
their cost is numpy and LAPACK work, which releases the GIL.  :func:`diagnosis_threads` runs a block of work with a
pool of threads; inside it :func:`pmap` maps a function over a list on the pool and keeps the list's order, so
the diagnosis makes the same choices, on the same numbers, with one thread or several (every candidate is computed
exactly as before; BLAS stays single-threaded).  Outside such a block, and inside the pool's own threads (no
nesting), :func:`pmap` is a plain ``map``.

The number of threads: the ``threads`` argument of :func:`drake_est.diagnose.diagnose` (CLI ``--threads``), else
the environment variable ``DRAKE_EST_DIAG_THREADS``, else :data:`DEFAULT_MAX_THREADS` or the number of cores,
whichever is less.  Worker processes of a fleet run set it to 1 (one process per core already).
"""
from __future__ import annotations

import contextlib
import contextvars
import os
from concurrent.futures import ThreadPoolExecutor

from drake_est.errors import DataError

#: the environment variable that sets the default number of threads of one diagnosis
THREADS_ENV = "DRAKE_EST_DIAG_THREADS"
#: at most this many threads by default: a round's candidates are about ten, of unequal cost (the motor-ripple
#: scan is the largest), so more threads gain little
DEFAULT_MAX_THREADS = 4

_POOL: contextvars.ContextVar = contextvars.ContextVar("drake_est_diagnosis_pool", default=None)


def check_threads(threads, name: str = "threads") -> int:
    """``threads`` as an int >= 1, or a one-line :class:`~drake_est.errors.DataError` naming ``name``."""
    text = str(threads).strip()
    if isinstance(threads, bool) or not text.isdigit():
        raise DataError(f"{name} must be a whole number of threads (at least 1), got {threads!r}")
    n = int(text)
    if n < 1:
        raise DataError(f"{name} must be at least 1, got {n}")
    return n


def default_threads() -> int:
    """The threads of one diagnosis when none are given: ``DRAKE_EST_DIAG_THREADS`` if set, else
    min(:data:`DEFAULT_MAX_THREADS`, cores)."""
    env = os.environ.get(THREADS_ENV)
    if env is not None and env.strip():
        return check_threads(env.strip(), THREADS_ENV)
    return max(1, min(DEFAULT_MAX_THREADS, os.cpu_count() or 1))


@contextlib.contextmanager
def diagnosis_threads(threads: int | None = None):
    """Run the enclosed work with a pool of ``threads`` threads for :func:`pmap` (None: :func:`default_threads`;
    1: no pool).  Yields the number of threads used."""
    n = default_threads() if threads is None else check_threads(threads)
    outer = _POOL.get()
    if outer is not None:           # inside another block: its pool serves
        yield outer[1]
        return
    if n <= 1:
        yield 1
        return
    pool = ThreadPoolExecutor(max_workers=n, thread_name_prefix="drake_est_diagnosis")
    token = _POOL.set((pool, n))
    try:
        yield n
    finally:
        _POOL.reset(token)
        pool.shutdown(wait=True)


def pmap(fn, items, first=()) -> list:
    """``[fn(x) for x in items]``, on the pool of the enclosing :func:`diagnosis_threads` when there is one (the
    order kept; an exception in ``fn`` is raised here).  The pool's threads do not see the pool (a context
    variable), so a :func:`pmap` inside ``fn`` runs in its caller's thread: no nesting, no deadlock.  ``first``:
    indices of items started before the others (the longest ones: the last to start sets the end), the results still
    in the order of ``items``."""
    items = list(items)
    cur = _POOL.get()
    if cur is None or len(items) < 2:
        return [fn(x) for x in items]
    lead = [i for i in dict.fromkeys(first) if 0 <= i < len(items)]
    if lead:
        led = set(lead)
        order = lead + [i for i in range(len(items)) if i not in led]
        done = pmap(fn, [items[i] for i in order])
        out = [None] * len(items)
        for i, r in zip(order, done):
            out[i] = r
        return out

    def alone(x):
        token = _POOL.set(None)       # whether or not the thread inherited the caller's context
        try:
            return fn(x)
        finally:
            _POOL.reset(token)
    return list(cur[0].map(alone, items))
