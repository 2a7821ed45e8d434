"""``drake-est demo``: the main job on bundled default data.

Simulates an IRB 140 joint-1 experiment (piecewise-constant-velocity sweeps, thesis Sec. 9.6) in Drake,
fits the nominal Coulomb + viscous friction model (9.2) on the samples that satisfy (9.9), prints
the validation metrics and writes a PNG plot."""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np


def register(sub):
    p = sub.add_parser("demo", help="run the main job on bundled default data and write a report")
    p.add_argument("--out", default=None, help="output folder (default: a new ./drake_est_demo-N folder)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.set_defaults(func=run)


def new_out_dir(prefix: str, out=None) -> Path:
    if out is not None:
        path = Path(out)
        path.mkdir(parents=True, exist_ok=True)
        return path
    k = 1
    while Path(f"{prefix}-{k}").exists():
        k += 1
    path = Path(f"{prefix}-{k}")
    path.mkdir(parents=True)
    return path


def run(args) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from drake_est.data import save_log
    from drake_est.metrics import metrics_table
    from drake_est.robots import irb140
    from drake_est.synth import synthesize

    out = new_out_dir("drake_est_demo", args.out)
    t0 = time.time()
    print("Simulating an IRB 140 joint-1 sweep in Drake (60 s, 100 Hz)...")
    log, truth = synthesize("none", seed=args.seed, joints=[1], duration=60.0, sample_rate=100.0)
    save_log(log, out / "irb140_joint1_sweep.csv")
    log = log.with_derivatives()
    tau_rb = irb140().inverse_dynamics_batch(log.q, log.dq, log.ddq)[:, 0]
    y = log.tau[:, 0] - tau_rb
    v, a = log.dq[:, 0], log.ddq[:, 0]
    keep = (np.abs(v) > 0.05) & (np.abs(a) < 0.2)
    half = log.t < log.t[0] + 0.6 * log.duration
    A = np.column_stack([v, np.sign(v)])
    tr, va = keep & half, keep & ~half
    k, *_ = np.linalg.lstsq(A[tr], y[tr], rcond=None)
    m = metrics_table(y[va], A[va] @ k, 2)
    true = truth["friction"][1]
    print(f"samples: {log.n_samples}; used {keep.sum()} satisfying (9.9) (dropped {log.n_samples - keep.sum()}: "
          f"|v| <= 0.05 rad/s or |a| >= 0.2 rad/s^2)")
    print(f"nominal friction, joint 1:  kv = {k[0]:.3f} N m s/rad (true {true['kv']:.3f}),  "
          f"kc = {k[1]:.3f} N m (true {true['kc']:.3f})")
    print(f"validation (last 40 %): RMSE {m['rmse']:.3f} N m (noise {truth['noise_std']:.3f}), MAE {m['mae']:.3f}, "
          f"Fit {m['fit']:.1f} %, FPE {m['fpe']:.3g}")
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    ax[0].plot(v[keep], y[keep], ".", ms=2, alpha=0.4, label="measured tau - rigid body")
    vv = np.linspace(v.min(), v.max(), 400)
    ax[0].plot(vv, k[0] * vv + k[1] * np.sign(vv), "r-", lw=2, label="Coulomb + viscous fit (9.2)")
    ax[0].set_xlabel("joint 1 velocity [rad/s]")
    ax[0].set_ylabel("friction torque [N m]")
    ax[0].legend()
    ax[0].set_title("Nominal friction fit")
    ax[1].plot(log.t[va], y[va] - A[va] @ k, ".", ms=2)
    ax[1].set_xlabel("time [s]")
    ax[1].set_ylabel("validation residual [N m]")
    ax[1].set_title(f"Held-out residual, RMSE {m['rmse']:.3f} N m")
    fig.tight_layout()
    fig.savefig(out / "friction_fit.png", dpi=110)
    plt.close(fig)
    print(f"done in {time.time() - t0:.1f} s; outputs in {out.resolve()}/ (friction_fit.png, irb140_joint1_sweep.csv)")
    return 0
