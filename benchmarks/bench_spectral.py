"""Benchmarks of the LPV spectral method (run: .venv/bin/python benchmarks/bench_spectral.py).

* LPV decomposition with N = 50,000 samples and 2,000 real parameters (J = 10 basis functions x
  O = 100 frequencies x [Re, Im]): direct normal-equation solver (acceptance: < 10 s on 2 cores);
* 4,000 real parameters: beyond ``direct_max`` the matrix-free LSQR solver is chosen automatically;
* find_periodic_components on a 45,000-sample ripple log (scan up to the default limit + 2 components).

NUFFT part (issue 20, ``--part nufft``; single-threaded: finufft nthreads=1, OPENBLAS/OMP_NUM_THREADS=1):

* ``ls_scan`` (NUFFT engine) against astropy's ``LombScargle(fit_mean=False, center_data=False)``
  ``method="fast"`` and ``"slow"`` on N = 5,000 / 50,000 / 500,000 irregular samples x 20,000 frequencies
  (astropy "slow" only at N = 5,000: it is O(N F) in Python-level loops and takes tens of seconds there);
  errors are elementwise relative differences to the exact periodogram (our direct sums: on the whole grid
  at N = 5,000, on 300 random grid frequencies above, where the full O(N F) direct sums would take minutes);
* the LPV periodogram with J = 4 basis functions, N = 500,000, 20,000 frequencies (target < 5 s);
* a 2-hour 1 kHz log (7.2 M samples): plain periodogram with 20,000 frequencies.

Usage: python benchmarks/bench_spectral.py [--part all|lpv|nufft] [--json FILE] [--check]
"""
from __future__ import annotations

import os

# as the CLI does: single-threaded BLAS is several times faster for this size on shared 2-core machines
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("DRAKE_EST_NUFFT_THREADS", "1")

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


def _timed(fn, repeats=1):
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def _rel(a, b):
    return float(np.max(np.abs(np.asarray(a) - b) / np.abs(b)))


def run_nufft(sizes=(5_000, 50_000, 500_000), n_freq: int = 20_000, slow_max: int = 5_000, n_ref: int = 300,
              repeats: int = 3, long_log: bool = True, seed: int = 0) -> dict:
    """ls_scan (NUFFT) vs astropy LombScargle, LPV J = 4 periodogram, 7.2 M-sample log (see module doc)."""
    from drake_est.spectral import ls_scan
    from drake_est.spectral.basis import ScheduleBasis

    try:
        from astropy.timeseries import LombScargle
    except ImportError:                       # optional comparison
        LombScargle = None
    rng = np.random.default_rng(seed)
    out = {"threads": "single (finufft nthreads=1, OPENBLAS_NUM_THREADS=1, OMP_NUM_THREADS=1)",
           "n_freq": n_freq, "astropy": LombScargle is not None}
    for N in sizes:
        span = 100.0
        x = np.sort(rng.uniform(0, span, N))
        y = np.sin(2 * np.pi * 1.7 * x) + 0.5 * np.cos(2 * np.pi * 11.3 * x + 1) + rng.standard_normal(N)
        df = 1.0 / (4 * span)
        f = df * np.arange(1, n_freq + 1)
        sumsq = float(y @ y)
        ls = None if LombScargle is None else LombScargle(x, y, fit_mean=False, center_data=False,
                                                          normalization="standard")
        # interleaved repeats (ours, astropy fast, ours, ...), best of each: fair on a loaded machine
        t_ours = t_fast = np.inf
        for _ in range(repeats):
            t, ess = _timed(lambda: ls_scan(x, y, f, method="nufft"))
            t_ours = min(t_ours, t)
            if ls is not None:
                t, p_fast = _timed(lambda: ls.power(f, method="fast", assume_regular_frequency=True))
                t_fast = min(t_fast, t)
        p_ours = ess / sumsq
        idx = np.arange(n_freq) if N <= slow_max else np.sort(rng.choice(n_freq, n_ref, replace=False))
        p_exact = ls_scan(x, y, f[idx], method="direct") / sumsq
        row = {"N": N, "ours_seconds": t_ours, "ours_max_rel_error": _rel(p_ours[idx], p_exact),
               "error_evaluated_on": "whole grid" if idx.size == n_freq else f"{idx.size} random grid frequencies"}
        if LombScargle is not None:
            row.update(astropy_fast_seconds=t_fast, astropy_fast_max_rel_error=_rel(p_fast[idx], p_exact),
                       speedup_vs_astropy_fast=t_fast / t_ours)
            if N <= slow_max:
                t_slow, p_slow = _timed(lambda: ls.power(f, method="slow"))
                row.update(astropy_slow_seconds=t_slow, astropy_slow_max_rel_error=_rel(p_slow, p_exact))
            else:
                row["astropy_slow"] = f"skipped (N > {slow_max}: O(N F), minutes)"
        out[f"ls_scan_N{N}"] = row
        print(json.dumps(row, default=float), flush=True)
    # LPV periodogram, J = 4 normalized Gaussians over a schedule
    N = 500_000
    x = np.sort(rng.uniform(0, 100.0, N))
    v = rng.uniform(-1, 1, N)
    y = (1 + v) * np.cos(2 * np.pi * 3.1 * x) + rng.standard_normal(N)
    Phi = ScheduleBasis.from_data(v, 4)(v)
    f = np.arange(1, n_freq + 1) / 400.0
    t_lpv, ess = _timed(lambda: ls_scan(x, y, f, Phi, method="nufft"), repeats)
    idx = np.sort(rng.choice(n_freq, 100, replace=False))
    out["lpv_J4_N500000"] = {"seconds": t_lpv, "n_freq": n_freq,
                             "max_rel_error_100_random_freqs": _rel(ess[idx], ls_scan(x, y, f[idx], Phi,
                                                                                       method="direct"))}
    print(json.dumps(out["lpv_J4_N500000"], default=float), flush=True)
    if long_log:
        N = 7_200_000
        t = np.arange(N) * 1e-3 + rng.uniform(-2e-4, 2e-4, N)       # 2 h at 1 kHz, jittered clock
        y = np.sin(2 * np.pi * 50.0 * t) + rng.standard_normal(N)
        f = 0.01 + np.arange(n_freq) * (499.0 / n_freq)
        t_long, ess = _timed(lambda: ls_scan(t, y, f, method="nufft"))
        idx = np.sort(rng.choice(n_freq, 20, replace=False))
        out["ls_scan_2h_1kHz_N7200000"] = {"seconds": t_long, "n_freq": n_freq, "peak_hz": float(f[np.argmax(ess)]),
                                           "max_rel_error_20_random_freqs":
                                           _rel(ess[idx], ls_scan(t, y, f[idx], method="direct"))}
        print(json.dumps(out["ls_scan_2h_1kHz_N7200000"], default=float), flush=True)
    return out


def check_nufft(res: dict) -> list:
    """Acceptance targets of issue 20; returns the failed ones."""
    failed = []
    for k, row in res.items():
        if not k.startswith("ls_scan_N"):
            continue
        if row["ours_max_rel_error"] >= 1e-6:
            failed.append(f"{k}: error {row['ours_max_rel_error']:.2g} >= 1e-6")
        if "astropy_fast_seconds" in row and row["ours_seconds"] > row["astropy_fast_seconds"]:
            failed.append(f"{k}: slower than astropy fast")
    if res["lpv_J4_N500000"]["seconds"] >= 5.0:
        failed.append("LPV J=4 N=500000 F=20000 not under 5 s")
    return failed


def check(res: dict) -> list:
    """The acceptance targets of the LPV benchmark (moved here from tests/test_spectral_bench.py); returns the
    failed ones (empty when all hold)."""
    d = res["direct_N50000_p2000"]
    a = res["auto_N50000_p4000"]
    targets = {"direct solver used for 2000 parameters": d["solver"] == "direct" and d["params"] == 2000,
               "direct N=50000, 2000 parameters < 10 s (2 cores)": d["seconds"] < 10.0,
               "iterative solver chosen for 4000 parameters and converged": a["solver"] == "iterative"
               and bool(a.get("converged")),
               "find_periodic_components frequency within 1 %":
               res["find_periodic_components_N45000"]["rel_error"] < 0.01}
    return [k for k, ok in targets.items() if not ok]


if __name__ == "__main__":
    import argparse
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("repeats", nargs="?", type=int, default=1)
    ap.add_argument("--part", choices=("all", "lpv", "nufft"), default="all")
    ap.add_argument("--no-long-log", action="store_true", help="skip the 7.2 M-sample log of the NUFFT part")
    ap.add_argument("--json", default=None, help="write the figures to this file")
    ap.add_argument("--check", action="store_true", help="exit 1 when an acceptance target is missed")
    args = ap.parse_args()
    res, failed = {}, []
    if args.part in ("all", "lpv"):
        res.update(run(repeats=args.repeats))
        failed += check(res)
    if args.part in ("all", "nufft"):
        res["nufft"] = run_nufft(repeats=max(args.repeats, 3), long_log=not args.no_long_log)
        failed += check_nufft(res["nufft"])
    print(json.dumps(res, indent=2, default=float))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(res, f, indent=2, default=float)
    for k in failed:
        print("MISSED:", k)
    sys.exit(1 if (args.check and failed) else 0)
