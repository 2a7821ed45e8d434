"""Benchmark of the state estimators of issue #12 (thesis Ch. 4), one run, peers beside ours when installed.

Sections (each a function returning a list of row dicts):
  * :func:`bench_kalman` -- Kalman filter + RTS smoother, nx = 4, ny = 2, T = 20,000, constant model:
    ``KalmanFilter.smooth`` (fused numba loop; and the pure-numpy loop, ``fused=False``) vs filterpy's
    ``KalmanFilter.batch_filter(update_first=True)`` + ``rts_smoother`` on the same model and data; the
    ratio filterpy / ours and the max abs difference of the smoothed means and covariances;
  * :func:`bench_ekf_ukf` -- EKF and UKF per-step time (``smooth`` = forward pass + RTS-type backward pass,
    divided by T, and ``forward_trajectory`` alone) on a chain of damped pendulums with nx = 4 and nx = 12
    (12 = the IRB140 joint state, 6 positions + 6 velocities), EKF with user Jacobians and with finite
    differences; filterpy's ``UnscentedKalmanFilter`` (Merwe sigma points, same alpha/beta/kappa) per step
    beside ours; and the EKF built from the IRB140 ``MultibodyPlant`` (``ExtendedKalmanFilter.from_system``,
    1 ms discrete step) per step;
  * :func:`pf_section` -- HOOK for the particle-filter helper: runs ``bench_pf.bench_pf`` from
    ``benchmarks/bench_pf.py`` when present (``--pf``).

Times are the best of ``--repeat`` runs; numba compilation is done before timing (not timed).
Usage: python benchmarks/bench_estimation.py [--repeat 3] [--T 20000] [--pf] [--json out.json]
"""
from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import sys
import time

import numpy as np


def _best(f, repeat):
    out, best = None, np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        out = f()
        best = min(best, time.perf_counter() - t)
    return best, out


def kalman_model(T=20000, seed=0):
    """Constant stable 4-state, 2-output model and simulated data."""
    rng = np.random.default_rng(seed)
    nx, ny = 4, 2
    A = np.eye(nx) + 0.05 * rng.standard_normal((nx, nx))
    A *= 0.99 / max(abs(np.linalg.eigvals(A)))
    C = rng.standard_normal((ny, nx))
    R1 = 0.01 * np.eye(nx)
    R2 = 0.1 * np.eye(ny)
    x0, P0 = np.zeros(nx), np.eye(nx)
    x = rng.standard_normal(nx)
    y = np.empty((T, ny))
    for t in range(T):
        y[t] = C @ x + rng.normal(0, np.sqrt(0.1), ny)
        x = A @ x + rng.normal(0, 0.1, nx)
    return A, C, R1, R2, x0, P0, y


def bench_kalman(T=20000, repeat=3):
    from drake_est.estimation import KalmanFilter

    A, C, R1, R2, x0, P0, y = kalman_model(T)
    kf = KalmanFilter(A, C, R1, R2, x0, P0)
    kf.smooth(None, y[:10])                                   # numba compile / cache load (not timed)
    rows = []
    sec, ours = _best(lambda: kf.smooth(None, y), repeat)
    rows.append(dict(section="kalman", row="drake_est KalmanFilter.smooth (fused numba)", T=T, seconds=sec,
                     us_per_step=sec / T * 1e6))
    sec_np, ours_np = _best(lambda: kf.smooth(None, y, fused=False), 1)
    rows.append(dict(section="kalman", row="drake_est KalmanFilter.smooth (numpy loop)", T=T, seconds=sec_np,
                     us_per_step=sec_np / T * 1e6,
                     max_abs_diff_vs_fused=float(max(np.abs(ours_np.x_smooth - ours.x_smooth).max(),
                                                     np.abs(ours_np.P_smooth - ours.P_smooth).max()))))
    try:
        from filterpy.kalman import KalmanFilter as FPKF
    except ImportError:
        return rows

    def fp_run():
        fp = FPKF(dim_x=4, dim_z=2)
        fp.x, fp.P, fp.F, fp.H, fp.Q, fp.R = x0.copy(), P0.copy(), A, C, R1, R2
        mu, cov, _, _ = fp.batch_filter(y, update_first=True)
        xs, Ps, _, _ = fp.rts_smoother(mu, cov)
        return mu, xs, Ps

    sec_fp, (mu, xs, Ps) = _best(fp_run, repeat)
    diff = float(max(np.abs(xs - ours.x_smooth).max(), np.abs(Ps - ours.P_smooth).max(),
                     np.abs(mu - ours.filtered.x_filt).max()))
    rows.append(dict(section="kalman", row="filterpy batch_filter + rts_smoother", T=T, seconds=sec_fp,
                     us_per_step=sec_fp / T * 1e6, max_abs_diff_vs_ours=diff,
                     speedup_of_ours=sec_fp / rows[0]["seconds"]))
    return rows


def pendulum_chain(nx, dt=0.01):
    """nx/2 damped pendulums, explicit Euler: q+ = q + dt v, v+ = v + dt (-9.81 sin q - 0.5 v + u); y = q."""
    n = nx // 2

    def f(x, u, t):
        q, v = x[..., :n], x[..., n:]
        acc = -9.81 * np.sin(q) - 0.5 * v + (0.0 if u is None else u)
        return np.concatenate([q + dt * v, v + dt * acc], axis=-1)

    def F(x, u, t):
        q = x[:n]
        J = np.eye(nx)
        J[:n, n:] = dt * np.eye(n)
        J[n:, :n] = -dt * 9.81 * np.diag(np.cos(q))
        J[n:, n:] = (1 - 0.5 * dt) * np.eye(n)
        return J

    def h(x, u, t):
        return x[..., :n]

    Hm = np.eye(nx)[:n]
    return f, F, h, (lambda x, u, t: Hm), n


def bench_ekf_ukf(sizes=(4, 12), T=2000, repeat=3, irb140_steps=50):
    from drake_est.estimation import ExtendedKalmanFilter, UnscentedKalmanFilter

    rows = []
    for nx in sizes:
        f, F, h, H, n = pendulum_chain(nx)
        rng = np.random.default_rng(nx)
        R1, R2 = 1e-6 * np.eye(nx), 1e-4 * np.eye(n)
        x = np.r_[0.5 * np.ones(n), np.zeros(n)]
        y = np.empty((T, n))
        for t in range(T):
            y[t] = h(x, None, t) + rng.normal(0, 0.01, n)
            x = f(x, None, t) + rng.normal(0, 1e-3, nx)
        x0, P0 = np.r_[0.4 * np.ones(n), np.zeros(n)], 0.1 * np.eye(nx)
        filters = {"EKF (user Jacobians)": ExtendedKalmanFilter(f, h, R1, R2, x0, P0, F=F, H=H),
                   "EKF (finite differences)": ExtendedKalmanFilter(f, h, R1, R2, x0, P0),
                   "UKF": UnscentedKalmanFilter(f, h, R1, R2, x0, P0)}
        for name, filt in filters.items():
            sec_f, _ = _best(lambda: filt.forward_trajectory(None, y), repeat)
            sec_s, _ = _best(lambda: filt.smooth(None, y), repeat)
            rows.append(dict(section="ekf_ukf", row=f"drake_est {name}", nx=nx, T=T,
                             us_per_step_filter=sec_f / T * 1e6, us_per_step_filter_smoother=sec_s / T * 1e6))
        try:
            from filterpy.kalman import MerweScaledSigmaPoints
            from filterpy.kalman import UnscentedKalmanFilter as FPUKF
        except ImportError:
            continue

        def fp_ukf():
            pts = MerweScaledSigmaPoints(nx, alpha=1.0, beta=2.0, kappa=0.0)
            uk = FPUKF(dim_x=nx, dim_z=n, dt=0.01, hx=lambda s: h(s, None, 0), fx=lambda s, dt: f(s, None, 0),
                       points=pts)
            uk.x, uk.P, uk.Q, uk.R = x0.copy(), P0.copy(), R1, R2
            mu, cov = uk.batch_filter(y)
            return mu

        sec, _ = _best(fp_ukf, repeat)
        rows.append(dict(section="ekf_ukf", row="filterpy UnscentedKalmanFilter.batch_filter", nx=nx, T=T,
                         us_per_step_filter=sec / T * 1e6, us_per_step_filter_smoother=None,
                         note="filterpy predicts before the first update (different convention, same cost)"))
    if irb140_steps:
        from drake_est.systems.builders import MakeIrb140ControllerPlant

        plant = MakeIrb140ControllerPlant(time_step=1e-3)
        nx, nq = plant.num_multibody_states(), plant.num_positions()
        C = np.eye(nx)[:nq]
        x0 = np.r_[0.0, 0.3, 0.2, 0.0, 0.1, 0.0, np.zeros(6)]
        ekf = ExtendedKalmanFilter.from_system(plant, 1e-8 * np.eye(nx), 1e-6 * np.eye(nq), x0, 1e-4 * np.eye(nx),
                                               measurement=C)
        ukf = UnscentedKalmanFilter.from_system(plant, 1e-8 * np.eye(nx), 1e-6 * np.eye(nq), x0,
                                                1e-4 * np.eye(nx), measurement=C)
        u = np.zeros((irb140_steps, 6))
        y = np.tile(x0[:nq], (irb140_steps, 1))
        for name, filt in (("EKF from IRB140 MultibodyPlant (AutoDiffXd Jacobian)", ekf),
                           ("UKF from IRB140 MultibodyPlant", ukf)):
            sec, _ = _best(lambda: filt.forward_trajectory(u, y), 1)
            rows.append(dict(section="ekf_ukf", row=f"drake_est {name}", nx=nx, T=irb140_steps,
                             us_per_step_filter=sec / irb140_steps * 1e6, us_per_step_filter_smoother=None))
    return rows


# ------------------------------------------------------------------------------------------------------
# HOOK for the particle-filter helper: the PF section of issue #12 (benchmarks/bench_pf.py::bench_pf).
# ------------------------------------------------------------------------------------------------------
def pf_section(repeat=3):
    """Rows of ``bench_pf.bench_pf`` (bootstrap PF on the cart-pole, particle-steps per ms) when present."""
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    try:
        import bench_pf
    except ImportError:
        return []
    return [dict(section="pf", **r) for r in bench_pf.bench_pf(repeat=repeat)]


def _print(rows):
    for r in rows:
        if r["section"] == "kalman":
            extra = ""
            if "speedup_of_ours" in r:
                extra = f"  ours is {r['speedup_of_ours']:.1f}x faster; max |diff| {r['max_abs_diff_vs_ours']:.1e}"
            elif "max_abs_diff_vs_fused" in r:
                extra = f"  max |diff| vs fused {r['max_abs_diff_vs_fused']:.1e}"
            print(f"{r['row']:58s} T={r['T']:6d} {r['seconds']:8.4f} s {r['us_per_step']:8.2f} us/step{extra}")
        elif r["section"] == "ekf_ukf":
            s = r["us_per_step_filter_smoother"]
            print(f"{r['row']:58s} nx={r['nx']:3d} filter {r['us_per_step_filter']:9.1f} us/step"
                  + ("" if s is None else f"   filter+smoother {s:9.1f} us/step"))
        else:
            print(f"{r['row']:58s} N={r['N']:6d} {r['particle_steps_per_ms']:10.0f} particle-steps/ms")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--T", type=int, default=20000, help="Kalman benchmark length")
    ap.add_argument("--T-ekf", type=int, default=2000)
    ap.add_argument("--irb140-steps", type=int, default=50)
    ap.add_argument("--pf", action="store_true", help="also run the particle-filter section (bench_pf.py)")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    rows = bench_kalman(a.T, a.repeat)
    rows += bench_ekf_ukf(T=a.T_ekf, repeat=a.repeat, irb140_steps=a.irb140_steps)
    if a.pf:
        rows += pf_section(a.repeat)
    _print(rows)
    if a.json:
        from drake_est.jsonutil import dump_json
        dump_json({"repeat": a.repeat, "rows": rows, "load_average": list(os.getloadavg())}, a.json)
    return rows


if __name__ == "__main__":
    main()
