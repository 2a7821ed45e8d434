"""Monte-Carlo on Dask: map a seeded function over parameter sets, deterministic for any worker count.

Example::

    from drake_est.fleet import mc_map

    def trial(params, seed):
        rng = np.random.default_rng(seed)
        return float(np.mean(rng.normal(params["mu"], 1.0, params["n"])))

    out = mc_map(trial, [{"mu": m, "n": 100} for m in range(50)], seed=0, workers=2)

Task ``i`` receives ``seed = child_seed(seed, i)``, a 63-bit integer drawn from
``numpy.random.SeedSequence([seed, i])``; it depends only on the base seed and the task's position,
never on which worker runs it or in which order, so the results are the same with 0 (in-process),
1 or N workers and on any cluster.
"""
from __future__ import annotations

import numpy as np

from drake_est.errors import DataError


def child_seed(seed: int, index: int) -> int:
    """The seed of task ``index`` of a Monte-Carlo run with base ``seed``."""
    return int(np.random.SeedSequence([int(seed), int(index)]).generate_state(1, np.uint64)[0] >> np.uint64(1))


def _call(func, params, seed):
    from drake_est.threads import single_thread_blas
    with single_thread_blas():
        return func(params, seed=seed)


def mc_map(func, param_sets, seed: int = 0, client=None, workers: int | None = None, desc: str = "monte carlo",
           scheduler: str | None = None) -> list:
    """``[func(p, seed=child_seed(seed, i)) for i, p in enumerate(param_sets)]``, in that order.

    ``client``: an existing ``distributed.Client``; ``scheduler``: an address to connect to;
    otherwise ``workers`` local processes (``None``: the local cores; ``0``: run in this process
    without Dask).  ``func`` must be picklable (module-level or cloudpickle-able) for process workers.
    A progress bar counts finished tasks; an exception in a task is raised here with its index."""
    from drake_est.progress import progress
    params = list(param_sets)
    if workers is not None and int(workers) < 0:
        raise DataError(f"workers must be >= 0, got {workers}")
    seeds = [child_seed(seed, i) for i in range(len(params))]
    if not params:
        return []
    if client is None and scheduler is None and workers is not None and int(workers) == 0:
        return [_call(func, p, s) for p, s in zip(progress(params, desc=desc), seeds)]
    from distributed import Client, as_completed
    cluster = own = None
    try:
        if client is None:
            if scheduler:
                own = Client(scheduler, timeout="20s")
            else:
                from drake_est.fleet.run import local_cluster
                cluster = local_cluster(workers)
                own = Client(cluster)
            client = own
        futs = [client.submit(_call, func, p, s, pure=False) for p, s in zip(params, seeds)]
        index = {f.key: i for i, f in enumerate(futs)}
        out = [None] * len(futs)
        bar = progress(total=len(futs), desc=desc)
        try:
            for fut in as_completed(futs):
                i = index[fut.key]
                try:
                    out[i] = fut.result()
                except Exception as err:
                    raise RuntimeError(f"mc_map: task {i} (params {params[i]!r}) failed: {err}") from err
                bar.update(1)
        finally:
            bar.close()
        return out
    finally:
        if own is not None:
            own.close()
        if cluster is not None:
            cluster.close()
