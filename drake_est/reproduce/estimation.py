"""Reproduction for thesis Ch. 4 (state estimation): ng-growth.

The univariate nonstationary growth model (Kitagawa 1996; Gordon, Salmond & Smith 1993), the classic
benchmark on which the particle filter (Sec. 4.2, Algorithm 1) beats Kalman-type filters::

    x[k+1] = x/2 + 25 x / (1 + x^2) + 8 cos(1.2 (k+1)) + v,   v ~ N(0, 10)
    y[k]   = x^2 / 20 + e,                                   e ~ N(0, 1),    x[0] ~ N(0, 5)

T = 100 steps; EKF (finite-difference Jacobians), UKF (kappa = 2, i.e. n + kappa = 3) and the bootstrap PF
(N = 500) filter the same simulated data; RMSE of the filtered mean over 100 Monte-Carlo runs (quick: 20).
The measurement x^2/20 is symmetric in x, so the posterior is often bimodal: the Gaussian filters lose the
sign of x, the PF keeps both modes.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from drake_est.estimation.pf import ParticleFilter
from drake_est.progress import progress

Q_NG, R_NG, P0_NG = 10.0, 1.0, 5.0


def ng_f(x, u, t):
    """Growth-model transition mean, broadcasting over (..., 1)."""
    return 0.5 * x + 25.0 * x / (1.0 + x ** 2) + 8.0 * np.cos(1.2 * (t + 1))


def ng_h(x, u, t):
    """Measurement mean x^2/20, broadcasting over (..., 1)."""
    return x ** 2 / 20.0


def simulate_ng(T=100, seed=0):
    """One trajectory (x (T, 1), y (T, 1)) of the growth model."""
    rng = np.random.default_rng([seed, 42])
    x = np.sqrt(P0_NG) * rng.standard_normal(1)
    X, Y = np.empty((T, 1)), np.empty((T, 1))
    for k in range(T):
        X[k] = x
        Y[k] = ng_h(x, None, k) + np.sqrt(R_NG) * rng.standard_normal(1)
        x = ng_f(x, None, k) + np.sqrt(Q_NG) * rng.standard_normal(1)
    return X, Y


def _filters(n_particles, seed):
    from drake_est.estimation.ekf import ExtendedKalmanFilter
    from drake_est.estimation.ukf import UnscentedKalmanFilter

    args = (ng_f, ng_h, [[Q_NG]], [[R_NG]], [0.0], [[P0_NG]])
    return {
        "EKF": ExtendedKalmanFilter(*args),
        "UKF": UnscentedKalmanFilter(*args, kappa=2.0),
        "PF": ParticleFilter.gaussian(*args, n_particles=n_particles, seed=seed),
    }


def ng_growth(out_dir, quick=False, seed=0, n_runs=None, T=100, n_particles=500, **kw):
    """RMSE of EKF, UKF and bootstrap PF on the nonstationary growth model over Monte-Carlo runs."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    n_runs = int(n_runs or (20 if quick else 100))
    names = ("EKF", "UKF", "PF")
    rmse = {k: np.empty(n_runs) for k in names}
    n_degenerate = 0
    example = None
    for r in progress(range(n_runs), desc="ng-growth", total=n_runs):
        X, Y = simulate_ng(T, seed=seed * 100_003 + r)
        for name, flt in _filters(n_particles, seed * 100_003 + r).items():
            res = flt.forward_trajectory(None, Y)
            rmse[name][r] = float(np.sqrt(np.mean((res.x_filt[:, 0] - X[:, 0]) ** 2)))
            if name == "PF":
                n_degenerate += res.extras["n_degenerate"]
            if r == 0:
                example = example or {"x": X[:, 0], "y": Y[:, 0]}
                example[name] = res.x_filt[:, 0]
    fig, ax = plt.subplots(1, 2, figsize=(11, 4), gridspec_kw={"width_ratios": [2, 1]})
    k = np.arange(T)
    ax[0].plot(k, example["x"], "k", lw=2, label="true x")
    for name, c in zip(names, ("tab:red", "tab:orange", "tab:blue")):
        ax[0].plot(k, example[name], color=c, lw=1, label=f"{name} (RMSE {rmse[name][0]:.2f})")
    ax[0].set_xlabel("time step k")
    ax[0].set_ylabel("state x")
    ax[0].set_title("growth model, Monte-Carlo run 0")
    ax[0].legend(fontsize=8, ncol=2)
    ax[1].boxplot([rmse[n] for n in names], tick_labels=list(names))
    ax[1].set_ylabel("RMSE of the filtered mean")
    ax[1].set_title(f"{n_runs} Monte-Carlo runs, T = {T}")
    fig.tight_layout()
    fig.savefig(out_dir / "ng_growth.png", dpi=110)
    plt.close(fig)
    mean = {n: float(rmse[n].mean()) for n in names}
    return {
        "n_runs": n_runs, "T": T, "n_particles": int(n_particles),
        "rmse_mean": mean,
        "rmse_median": {n: float(np.median(rmse[n])) for n in names},
        "pf_beats_ukf_runs": int(np.sum(rmse["PF"] < rmse["UKF"])),
        "ukf_beats_ekf_runs": int(np.sum(rmse["UKF"] < rmse["EKF"])),
        "order_pf_ukf_ekf": bool(mean["PF"] < mean["UKF"] < mean["EKF"]),
        "pf_degenerate_steps": int(n_degenerate),
        "figure": "ng_growth.png",
    }


EXPERIMENTS = {"ng-growth": ng_growth}
