"""Benchmarks of the LPV spectral method (run: .venv/bin/python benchmarks/bench_spectral.py).

* LPV decomposition with N = 50,000 samples and 2,000 real parameters (J = 10 basis functions x
  O = 100 frequencies x [Re, Im]): direct normal-equation solver (acceptance: < 10 s on 2 cores);
* 4,000 real parameters: beyond ``direct_max`` the matrix-free LSQR solver is chosen automatically;
* find_periodic_components on a 45,000-sample ripple log (scan up to the default limit + 2 components).
"""
from __future__ import annotations

import os

# as the CLI does: single-threaded BLAS is several times faster for this size on shared 2-core machines
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import json
import sys
import time

import numpy as np


def lpv_problem(N=50_000, O=100, seed=0):
    rng = np.random.default_rng(seed)
    x = rng.uniform(0, 20, N)
    v = rng.uniform(-1, 1, N)
    freqs = np.linspace(0.5, 50, O)
    y = (1 + v) * np.cos(2 * np.pi * freqs[7] * x) + 0.5 * np.sin(2 * np.pi * freqs[40] * x) \
        + 0.1 * rng.standard_normal(N)
    return x, y, v, freqs


def run(repeats: int = 1) -> dict:
    from drake_est.spectral import LPVSpectrum, find_periodic_components
    from drake_est.spectral.testsignal import ripple_signal

    out = {}
    x, y, v, freqs = lpv_problem()
    for J, key in ((10, "direct_N50000_p2000"), (20, "auto_N50000_p4000")):
        best = np.inf
        for _ in range(repeats):
            t0 = time.perf_counter()
            m = LPVSpectrum(freqs, n_basis=J, lam=1e-6).fit(x, y, v)
            best = min(best, time.perf_counter() - t0)
        out[key] = {"seconds": best, "solver": m.solver_used, "params": m.n_spectral_params,
                    "explained": m.explained_fraction(), **getattr(m, "iterative_info", {})}
    q, vq, tau, truth = ripple_signal(n=45_000, seed=0)
    base = np.column_stack([np.sign(vq), vq])
    t0 = time.perf_counter()
    pc = find_periodic_components(q, tau, schedule=vq, base=base, n_components=2)
    out["find_periodic_components_N45000"] = {
        "seconds": time.perf_counter() - t0, "found": pc.freqs[0], "true": truth["frequency_per_arm_rad"],
        "rel_error": abs(pc.freqs[0] - truth["frequency_per_arm_rad"]) / truth["frequency_per_arm_rad"]}
    return out


if __name__ == "__main__":
    res = run(repeats=int(sys.argv[1]) if len(sys.argv) > 1 else 1)
    print(json.dumps(res, indent=2, default=float))
