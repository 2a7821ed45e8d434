"""Benchmark of the bootstrap particle filter (thesis Algorithm 1) on the 4-state cart-pole of issue #12.

Model: state (theta, theta', p, v), explicit Euler h = 0.01, theta'' = -(g/l) sin theta + (u/l) cos theta
- 0.1 theta', p'' = u, g = 9.81, l = 1; process noise std 0.01 on each state; y = (theta, p) + N(0, 0.05^2);
known input u; T = 1000; x0 ~ N(0, 0.1 I); systematic resampling when ESS < N/2; the weighted mean and
the log-likelihood every step.  Figure of merit: particle-steps per millisecond (N * T / time).

Two figures per row: ``cpu_*`` from ``time.process_time()`` (CPU time of this single-threaded process: the
primary figure on a loaded machine, where other processes inflate wall-clock time) and ``wall_*`` from
``time.perf_counter()``; ``seconds``/``particle_steps_per_ms`` are the wall-clock ones.  Two floor rows time
only the random numbers every filter needs (4 standard normals per particle-step, N * T * 4 in all):
numpy's ``standard_normal`` (float64, what the hand-tuned filter uses) and drake_est's float32 Box-Muller
(``pf.box_muller_f32``, what drake_est's filters use).

Rows (all timed in the same run, interleaved, best of ``--repeat`` rounds; ``particles`` once):
  * ``drake_est fused (numba)``: ``ParticleFilter.gaussian(..., f_point=, h_point=)`` -- the model
    compiled per particle, one fused loop (random numbers drawn by numpy, included in the time);
  * ``drake_est generic (numpy f, h)``: ``ParticleFilter.gaussian(f, h, ...)`` with the plain vectorised
    numpy model functions a user writes (no compilation), ``covariances=False`` (mean + loglik, as the
    reference) and, separately, with covariances;
  * ``hand-tuned numpy``: a numpy filter written for this one model only (below, ``handtuned_pf``);
  * ``particles`` (N. Chopin's library) ``Bootstrap`` + ``SMC`` on the same model, when installed.
filterpy has no particle filter (only resampling helpers), so it has no row here.

Usage: python benchmarks/bench_pf.py [--repeat 3] [--T 1000] [--N 500 5000] [--json out.json]
"""
from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse
import json
import time

import numpy as np

G, L, H = 9.81, 1.0, 0.01
SIG_V, SIG_E = 0.01, 0.05


# --- the model, as a user writes it --------------------------------------------------------------
def f(x, u, t):
    th, w = x[..., 0], x[..., 1]
    a = -(G / L) * np.sin(th) + (u[0] / L) * np.cos(th) - 0.1 * w
    return np.stack([th + H * w, w + H * a, x[..., 2] + H * x[..., 3], x[..., 3] + H * u[0]], axis=-1)


def h(x, u, t):
    return x[..., [0, 2]]


def f_point(x, u, t, out):
    a = -(G / L) * np.sin(x[0]) + (u[0] / L) * np.cos(x[0]) - 0.1 * x[1]
    out[0] = x[0] + H * x[1]
    out[1] = x[1] + H * a
    out[2] = x[2] + H * x[3]
    out[3] = x[3] + H * u[0]


def h_point(x, u, t, out):
    out[0] = x[0]
    out[1] = x[2]


def simulate(T, seed=0):
    rng = np.random.default_rng(seed)
    u = np.sin(0.01 * np.arange(T)) + 0.5 * np.sin(0.037 * np.arange(T))
    x = np.array([0.3, 0.0, 0.0, 0.0])
    X, Y = [], []
    for t in range(T):
        X.append(x)
        Y.append(h(x, u[t:t + 1], t) + SIG_E * rng.standard_normal(2))
        x = f(x, u[t:t + 1], t) + SIG_V * rng.standard_normal(4)
    return u[:, None], np.array(Y), np.array(X)


# --- a numpy filter hand-tuned for this one model --------------------------------------------------
def handtuned_pf(u, y, N, seed=0):
    """Bootstrap PF for the cart-pole only: state as 4 contiguous rows (4, N), the model inlined, in-place
    updates, one (4, N) normal draw per step, systematic resampling by searchsorted."""
    rng = np.random.default_rng(seed)
    T = y.shape[0]
    X = np.sqrt(0.1) * rng.standard_normal((4, N))
    logw = np.full(N, -np.log(N))
    uni = np.full(N, -np.log(N))
    c0 = -np.log(2 * np.pi * SIG_E ** 2)           # log N normalisation for 2 independent channels
    inv = 1.0 / SIG_E
    ar = np.arange(N, dtype=float)
    means = np.empty((T, 4))
    ll = 0.0
    acc = np.empty(N)
    for t in range(T):
        e0 = (y[t, 0] - X[0]) * inv
        e1 = (y[t, 1] - X[2]) * inv
        a = logw - 0.5 * (e0 * e0 + e1 * e1)
        m = a.max()
        w = np.exp(a - m)
        s = w.sum()
        ll += m + np.log(s) + c0
        w /= s
        means[t] = X @ w
        if 1.0 / np.dot(w, w) < 0.5 * N:
            idx = np.searchsorted(np.cumsum(w), (rng.random() + ar) / N)
            np.minimum(idx, N - 1, out=idx)
            X = X[:, idx]
            logw = uni
        else:
            logw = a - (m + np.log(s))
        ut = u[t, 0]
        th, om = X[0], X[1]
        np.sin(th, out=acc)
        acc *= -(G / L)
        acc += (ut / L) * np.cos(th) - 0.1 * om
        Z = rng.standard_normal((4, N))
        Z *= SIG_V
        Z[0] += th + H * om
        Z[1] += om + H * acc
        Z[2] += X[2] + H * X[3]
        Z[3] += X[3] + H * ut
        X = Z
    return means, ll


def particles_pf(u, y, N, seed=0):
    import particles
    import particles.distributions as dists
    from particles import state_space_models as ssm

    class CartPole(ssm.StateSpaceModel):
        def PX0(self):
            return dists.MvNormal(loc=np.zeros(4), scale=np.sqrt(0.1), cov=np.eye(4))

        def PX(self, t, xp):
            return dists.MvNormal(loc=f(xp, u[t - 1], t - 1), scale=SIG_V, cov=np.eye(4))

        def PY(self, t, xp, x):
            return dists.MvNormal(loc=x[:, [0, 2]], scale=SIG_E, cov=np.eye(2))

    np.random.seed(seed)
    fk = ssm.Bootstrap(ssm=CartPole(), data=list(y))
    alg = particles.SMC(fk=fk, N=N, resampling="systematic", ESSrmin=0.5, collect=None)
    alg.run()
    return alg.summaries.logLts[-1]


def _best(fun, repeat):
    """(best wall seconds, best CPU seconds, last output) over ``repeat`` calls."""
    best_w = best_c = np.inf
    out = None
    for _ in range(repeat):
        c0, t0 = time.process_time(), time.perf_counter()
        out = fun()
        t1, c1 = time.perf_counter(), time.process_time()
        best_w, best_c = min(best_w, t1 - t0), min(best_c, c1 - c0)
    return best_w, best_c, out


def _rate(N, T, sec):
    return N * T / sec / 1e3


def bench_pf(Ns=(500, 5000), T=1000, repeat=3, with_peers=True):
    """Time every row at each N; returns a list of dicts (row, N, seconds, particle_steps_per_ms [wall],
    cpu_seconds, cpu_particle_steps_per_ms, loglik, rmse_theta).

    The rows of one N are timed *interleaved* (round r runs every row once) and the best round is kept, so a
    change in the machine's load during the run affects all rows alike."""
    from drake_est.estimation import ParticleFilter
    from drake_est.estimation.pf import box_muller_f32

    u, y, X = simulate(T)
    R1, R2 = SIG_V ** 2 * np.eye(4), SIG_E ** 2 * np.eye(2)
    rows = []
    for N in Ns:
        fused = ParticleFilter.gaussian(f, h, R1, R2, np.zeros(4), 0.1 * np.eye(4), n_particles=N, seed=1,
                                        f_point=f_point, h_point=h_point, nu=1)
        gen = ParticleFilter.gaussian(f, h, R1, R2, np.zeros(4), 0.1 * np.eye(4), n_particles=N, seed=1, nu=1)
        t0 = time.perf_counter()
        fused.forward_trajectory(u[:5], y[:5], covariances=False)      # compile (not timed)
        compile_fused = time.perf_counter() - t0
        gen.forward_trajectory(u[:5], y[:5], covariances=False)
        compile_s = time.perf_counter() - t0
        M = N * T * 4
        zbuf = np.empty(M)
        z32, sc = np.empty(M, np.float32), np.empty((2, (M + 1) // 2), np.float32)
        rng = np.random.default_rng(0)
        cands = {
            "drake_est fused (numba)": lambda: fused.forward_trajectory(u, y, covariances=False),
            "drake_est generic (numpy f, h)": lambda: gen.forward_trajectory(u, y, covariances=False),
            "drake_est generic + covariances": lambda: gen.forward_trajectory(u, y),
            "hand-tuned numpy (this model only)": lambda: handtuned_pf(u, y, N, seed=1),
            "floor: numpy standard_normal, N*T*4 float64": lambda: rng.standard_normal(out=zbuf) is None,
            "floor: drake_est Box-Muller, N*T*4 float32": lambda: box_muller_f32(rng, z32, sc) is None,
        }
        best_w = {k: np.inf for k in cands}
        best_c = {k: np.inf for k in cands}
        out = {}
        for _ in range(repeat):
            for name, fun in cands.items():
                w_, c_, out[name] = _best(fun, 1)
                best_w[name] = min(best_w[name], w_)
                best_c[name] = min(best_c[name], c_)
        for name in cands:
            r = out[name]
            row = dict(row=name, N=N, seconds=best_w[name], particle_steps_per_ms=_rate(N, T, best_w[name]),
                       cpu_seconds=best_c[name], cpu_particle_steps_per_ms=_rate(N, T, best_c[name]),
                       loglik=None, rmse_theta=None)
            if not isinstance(r, bool):                # the floor rows return a bool
                ll, xm = (r[1], r[0]) if isinstance(r, tuple) else (r.loglik, r.x_filt)
                row.update(loglik=float(ll), rmse_theta=float(np.sqrt(np.mean((xm[:, 0] - X[:, 0]) ** 2))))
            if name == "drake_est fused (numba)":
                row["compile_seconds"] = compile_fused
            if name == "drake_est generic (numpy f, h)":
                row["compile_seconds"] = compile_s - compile_fused
            rows.append(row)
        if with_peers:
            try:
                import particles  # noqa: F401
            except ImportError:
                continue
            w_, c_, ll = _best(lambda: particles_pf(u, y, N, seed=1), 1)
            rows.append(dict(row="particles (Bootstrap + SMC)", N=N, seconds=w_,
                             particle_steps_per_ms=_rate(N, T, w_), cpu_seconds=c_,
                             cpu_particle_steps_per_ms=_rate(N, T, c_), loglik=float(ll), rmse_theta=None))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--T", type=int, default=1000)
    ap.add_argument("--N", type=int, nargs="+", default=[500, 5000])
    ap.add_argument("--no-peers", action="store_true")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    rows = bench_pf(tuple(a.N), a.T, a.repeat, not a.no_peers)
    print("particle-steps per millisecond (N * T / time); CPU = time.process_time() of this process, "
          "wall = time.perf_counter(); load average " + ", ".join(f"{v:.1f}" for v in os.getloadavg()))
    print(f"{'implementation':46s} {'N':>6s} {'CPU psteps/ms':>14s} {'wall psteps/ms':>15s} {'loglik':>10s}")
    for r in rows:
        ll = "" if r["loglik"] is None else f"{r['loglik']:10.1f}"
        print(f"{r['row']:46s} {r['N']:6d} {r['cpu_particle_steps_per_ms']:14.0f} "
              f"{r['particle_steps_per_ms']:15.0f} {ll:>10s}")
    for N in a.N:
        by = {r["row"]: r for r in rows if r["N"] == N}
        g, ht = by["drake_est generic (numpy f, h)"], by["hand-tuned numpy (this model only)"]
        fu = by["drake_est fused (numba)"]
        for kind, key in (("CPU", "cpu_particle_steps_per_ms"), ("wall", "particle_steps_per_ms")):
            print(f"N={N} [{kind}]: generic / hand-tuned = {g[key] / ht[key]:.2f}; fused / hand-tuned = "
                  f"{fu[key] / ht[key]:.2f}; fused = {fu[key]:.0f} psteps/ms (target 12,000)")
        print(f"N={N}: compile time (not in the timings): fused {fu['compile_seconds']:.1f} s, generic "
              f"{g['compile_seconds']:.1f} s")
    if a.json:
        from drake_est.jsonutil import dump_json
        dump_json({"T": a.T, "repeat": a.repeat, "rows": rows,
                   "load_average": list(os.getloadavg())}, a.json)
    return rows


if __name__ == "__main__":
    main()
