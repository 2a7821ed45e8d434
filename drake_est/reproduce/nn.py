"""Reproductions of thesis Sec. 8.6 (neural dynamics, weight decay vs Jacprop): nn-linear, nn-cartpole.

Both experiments train f (x+ = net) and g + x (x+ = net + x) models with no regularization, L2 weight decay
and Jacprop (8.9).  The regularization weight of each (form, method) is chosen on validation data: a grid of
values is trained on ``n_tune`` separate tuning draws and the value with the lowest median validation
prediction error is then used in every Monte-Carlo run ("tuned such that prediction error on the test
data is minimized", Sec. 8.6; ``grid={"weight_decay": [...], "jacprop": [...]}`` overrides the values).  Monte-Carlo runs are spread over all local cores (a process pool).
"""
from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

from drake_est.identification.nn import NeuralDynamicsModel
from drake_est.identification.nn_tasks import (cartpole_step, eigenvalue_distance, jacobian_error,
                                               lowpass_noise, random_stable_system, simulate_cartpole,
                                               simulate_linear)
from drake_est.progress import progress

FORMS = ("f", "g")
METHODS = ("none", "weight_decay", "jacprop")
GRIDS = {
    "linear": {"weight_decay": (1e-4, 1e-3, 1e-2, 1e-1), "jacprop": (1e-3, 1e-2, 1e-1, 1.0, 10.0)},
    "cartpole": {"weight_decay": (1e-4, 1e-3, 1e-2, 1e-1), "jacprop": (1e-2, 1e-1, 1.0, 10.0)},
}


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


# ---------------------------------------------------------------------------------------------
# data of one Monte-Carlo draw
# ---------------------------------------------------------------------------------------------
def _noisy(rng, x, rel):
    return x + rel * x.std(axis=0, keepdims=True) * rng.standard_normal(x.shape) if rel > 0 else x


def _linear_draw(seq, T=200, n=10, m=10, dt=0.02, noise=0.02, cutoff=0.3):
    """Algorithm 5 system, two training and two validation trajectories driven by low-pass noise."""
    rng = np.random.default_rng(seq)
    A, B = random_stable_system(rng, n, m, dt)
    trajs = []
    for _ in range(4):
        u = lowpass_noise(rng, T, m, cutoff)
        trajs.append((_noisy(rng, simulate_linear(A, B, u), noise), u))
    return {"A": A, "B": B, "train": trajs[:2], "val": trajs[2:], "dt": dt}


def _cartpole_draw(seq, T=200, dt=0.02, noise=0.01):
    """Pendulum on a cart (8.11)-(8.12): two training and two validation trajectories."""
    rng = np.random.default_rng(seq)
    trajs = []
    for _ in range(4):
        x, u = simulate_cartpole(rng, T, dt)
        trajs.append((_noisy(rng, x, noise), u))
    return {"train": trajs[:2], "val": trajs[2:], "dt": dt}


def _true_jacobian(task, draw, X, U):
    if task == "linear":
        return np.broadcast_to(np.hstack([draw["A"], draw["B"]]), (X.shape[0],) + draw["A"].shape[:1]
                               + (draw["A"].shape[1] + draw["B"].shape[1],))
    return cartpole_step(X, U, draw["dt"], jacobian=True)[1]


def _one(task, seq, configs, settings, keep):
    """Train every (form, method, value) in ``configs`` on one draw; validation error and Jacobian error.
    With ``keep`` also returns arrays for the figures."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    draw = _linear_draw(seq) if task == "linear" else _cartpole_draw(seq)
    xs = [x for x, _ in draw["train"]]
    us = [u for _, u in draw["train"]]
    xv = [x for x, _ in draw["val"]]
    uv = [u for _, u in draw["val"]]
    Xv = np.vstack([x[:-1] for x in xv])
    Uv = np.vstack([u[:-1] for u in uv])
    Jtrue = _true_jacobian(task, draw, Xv, Uv)
    n = Xv.shape[1]
    out = {}
    for form, method, value in configs:
        kw = {"weight_decay": value} if method == "weight_decay" else ({"jacprop": value} if method == "jacprop" else {})
        model = NeuralDynamicsModel(hidden=settings["hidden"], form=form, epochs=settings["epochs"],
                                    batch_size=settings["batch_size"], learning_rate=settings["lr"],
                                    validation_every=settings["validation_every"], seed=int(seq.generate_state(1)[0]),
                                    progress_bar=False, **kw)
        model.fit(xs, us, xv, uv)
        J = model.jacobian(Xv, Uv)
        if task == "linear":
            jerr = eigenvalue_distance(Jtrue[0, :, :n], J[:, :, :n])
        else:
            jerr = jacobian_error(Jtrue, J)
        rec = {"val_mse": model.score(xv, uv), "jac_err": jerr, "best_epoch": model.best_epoch_,
               "diverged": model.diverged_ is not None}
        if keep:
            rec["eig"] = np.linalg.eigvals(J[:, :, :n])
            rec["J_traj"] = model.jacobian(xv[0][:-1], uv[0][:-1])
        out[(form, method, value)] = rec
    if keep:
        out["_truth"] = {"eig": np.linalg.eigvals(Jtrue[:, :, :n]),
                         "J_traj": _true_jacobian(task, draw, xv[0][:-1], uv[0][:-1])}
    return out


def _map(task, seqs, configs, settings, desc, workers, keep_first=False):
    """Run ``_one`` for every seed sequence on a process pool (all local cores) with a progress bar."""
    results = [None] * len(seqs)
    workers = max(1, min(workers or os.cpu_count() or 1, len(seqs)))
    if workers == 1:
        for i in progress(range(len(seqs)), desc=desc, total=len(seqs)):
            results[i] = _one(task, seqs[i], configs, settings, keep_first and i == 0)
        return results
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futs = {pool.submit(_one, task, seqs[i], configs, settings, keep_first and i == 0): i
                for i in range(len(seqs))}
        for fut in progress(as_completed(futs), desc=desc, total=len(futs)):
            results[futs[fut]] = fut.result()
    return results


def _stats(v):
    v = np.asarray(v, float)
    return {"median": float(np.median(v)), "q25": float(np.percentile(v, 25)), "q75": float(np.percentile(v, 75)),
            "min": float(v.min()), "max": float(v.max()), "n": int(v.size)}


def _experiment(task, out_dir, quick, seed, n_runs, n_tune, settings, workers, grid=None):
    if grid is None:
        grid = GRIDS[task] if not quick else {k: v[1:3] for k, v in GRIDS[task].items()}
    grid = {k: tuple(float(x) for x in grid[k]) for k in ("weight_decay", "jacprop")}
    root = np.random.SeedSequence([seed, 8 if task == "linear" else 9])
    tune_seqs, run_seqs = root.spawn(n_tune), None
    run_seqs = np.random.SeedSequence([seed, 80 if task == "linear" else 90]).spawn(n_runs)
    # --- tuning on separate draws: pick each (form, method) value by median validation error
    tune_cfg = [(f, m, v) for f in FORMS for m in ("weight_decay", "jacprop") for v in grid[m]]
    tuned = _map(task, tune_seqs, tune_cfg, settings, f"{task} tuning", workers)
    chosen, tuning, tuning_jac = {}, {}, {}
    for f in FORMS:
        for m in ("weight_decay", "jacprop"):
            med = {v: float(np.median([r[(f, m, v)]["val_mse"] for r in tuned])) for v in grid[m]}
            tuning[f"{f}/{m}"] = {f"{v:g}": s for v, s in med.items()}
            tuning_jac[f"{f}/{m}"] = {f"{v:g}": float(np.median([r[(f, m, v)]["jac_err"] for r in tuned]))
                                      for v in grid[m]}
            chosen[(f, m)] = min(med, key=med.get)
    configs = [(f, "none", 0.0) for f in FORMS] + [(f, m, chosen[(f, m)]) for f in FORMS
                                                    for m in ("weight_decay", "jacprop")]
    runs = _map(task, run_seqs, configs, settings, f"{task} monte carlo", workers, keep_first=True)
    summary = {}
    for f, m, v in configs:
        recs = [r[(f, m, v)] for r in runs]
        summary[f"{f}/{m}"] = {"value": v, "val_mse": _stats([r["val_mse"] for r in recs]),
                               "jac_err": _stats([r["jac_err"] for r in recs]),
                               "diverged": int(sum(r["diverged"] for r in recs)),
                               "jac_err_runs": [r["jac_err"] for r in recs],
                               "val_mse_runs": [r["val_mse"] for r in recs]}
    res = {"settings": {**settings, "hidden": list(settings["hidden"]), "n_runs": n_runs, "n_tune": n_tune,
                        "grid": {k: list(v) for k, v in grid.items()}, "seed": seed, "quick": quick},
           "chosen": {f"{f}/{m}": v for (f, m), v in chosen.items()}, "tuning_median_val_mse": tuning,
           "tuning_median_jac_err": tuning_jac,
           "results": summary}
    return res, runs[0], configs


def _box(plt, ax, data, labels, title, log=True):
    ax.boxplot(data, showfliers=True)
    ax.set_xticks(range(1, len(labels) + 1), labels, rotation=20, fontsize=8)
    if log:
        ax.set_yscale("log")
    ax.set_title(title, fontsize=9)


def _checks(res):
    r = res["results"]
    med = lambda k, q: r[k][q]["median"]  # noqa: E731
    return {
        "jacprop_lowers_median_jac_err_f": bool(med("f/jacprop", "jac_err") < med("f/weight_decay", "jac_err")),
        "jacprop_lowers_median_jac_err_g": bool(med("g/jacprop", "jac_err") < med("g/weight_decay", "jac_err")),
        "g_lower_median_val_mse_than_f": bool(min(med(f"g/{m}", "val_mse") for m in METHODS)
                                              < min(med(f"f/{m}", "val_mse") for m in METHODS)),
    }


# ---------------------------------------------------------------------------------------------
# nn-linear (Algorithm 5, Figs. 8.1-8.3)
# ---------------------------------------------------------------------------------------------
def nn_linear(out_dir, quick=False, seed=0, n_runs=None, n_tune=None, epochs=None, workers=None, grid=None,
              figures=True, **kw):
    """Sec. 8.6 randomized linear systems: 10 states, 10 inputs, 1 hidden layer of 20, two 200-step
    trajectories, 300 epochs, 12 Monte-Carlo runs; validation prediction error and eigenvalue-distance
    Jacobian error for f and g + x with no regularization, weight decay and Jacprop."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    settings = {"hidden": (20,), "epochs": epochs or (60 if quick else 300), "batch_size": 50, "lr": 1e-2,
                "validation_every": 5, "trajectory_length": 200, "dt": 0.02, "state_noise_rel": 0.02}
    res, first, configs = _experiment("linear", out_dir, quick, seed, n_runs or (2 if quick else 12),
                                      n_tune or (1 if quick else 3), settings, workers, grid)
    r = res["results"]
    res["checks"] = _checks(res)
    res["checks"]["weight_decay_moves_f_eigenvalues_away"] = bool(
        r["f/weight_decay"]["jac_err"]["median"] > r["f/none"]["jac_err"]["median"])
    res["checks"]["weight_decay_helps_g_eigenvalues"] = bool(
        r["g/weight_decay"]["jac_err"]["median"] < r["g/none"]["jac_err"]["median"])
    res["figures"] = []
    if not figures:
        return res
    plt = _plt()
    # Fig. 8.1: g + x, weight decay vs Jacprop
    fig, axs = plt.subplots(1, 2, figsize=(8, 3.5))
    keys = ["f/weight_decay", "f/jacprop", "g/weight_decay", "g/jacprop"]
    lab = [k.replace("weight_decay", "WD").replace("jacprop", "Jacprop").replace("g/", "g+x/") for k in keys]
    _box(plt, axs[0], [r[k]["val_mse_runs"] for k in keys], lab, "validation prediction error (mse)")
    _box(plt, axs[1], [r[k]["jac_err_runs"] for k in keys], lab, "eigenvalue-distance Jacobian error")
    fig.suptitle(f"Fig. 8.1: linear task, {res['settings']['n_runs']} Monte-Carlo runs", fontsize=10)
    fig.tight_layout()
    fig.savefig(out_dir / "nn_linear_fig8_1.png", dpi=110)
    plt.close(fig)
    th = np.linspace(0, 2 * np.pi, 200)
    truth = first["_truth"]["eig"][0]

    def eigplot(ax, key, title):
        e = first[key]["eig"].ravel()
        ax.plot(np.cos(th), np.sin(th), "k-", lw=0.5, label="unit circle")
        ax.plot(e.real, e.imag, ".", color="tab:blue", ms=2, alpha=0.4, label="learned")
        ax.plot(truth.real, truth.imag, "o", color="tab:red", ms=4, label="true")
        pts = np.concatenate([e, truth])          # zoom on the eigenvalues (they cluster near 1)
        lo = np.array([pts.real.min(), pts.imag.min()])
        hi = np.array([pts.real.max(), pts.imag.max()])
        pad = 0.08 * max(hi - lo) + 1e-3
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("Re")
        ax.set_ylabel("Im")

    cfg = {(f, m): (f, m, v) for f, m, v in configs}
    fig, axs = plt.subplots(1, 2, figsize=(8, 4))
    eigplot(axs[0], cfg[("g", "weight_decay")], "g + x, weight decay")
    eigplot(axs[1], cfg[("g", "jacprop")], "g + x, Jacprop")
    axs[1].legend(fontsize=7)
    fig.suptitle("Fig. 8.2: Jacobian eigenvalues at validation points", fontsize=10)
    fig.tight_layout()
    fig.savefig(out_dir / "nn_linear_fig8_2.png", dpi=110)
    plt.close(fig)
    fig, axs = plt.subplots(2, 2, figsize=(8, 8))
    for i, m in enumerate(("none", "weight_decay")):
        for j, f in enumerate(FORMS):
            eigplot(axs[i, j], cfg[(f, m)], f"{'f' if f == 'f' else 'g + x'}, "
                    f"{'no weight decay' if m == 'none' else 'weight decay %g' % cfg[(f, m)][2]}")
    fig.suptitle("Fig. 8.3: weight decay and the learned eigenvalues", fontsize=10)
    fig.tight_layout()
    fig.savefig(out_dir / "nn_linear_fig8_3.png", dpi=110)
    plt.close(fig)
    res["figures"] = ["nn_linear_fig8_1.png", "nn_linear_fig8_2.png", "nn_linear_fig8_3.png"]
    return res


# ---------------------------------------------------------------------------------------------
# nn-cartpole ((8.11)-(8.12), Figs. 8.5-8.7)
# ---------------------------------------------------------------------------------------------
def nn_cartpole(out_dir, quick=False, seed=0, n_runs=None, n_tune=None, epochs=None, workers=None, grid=None,
                figures=True, **kw):
    """Sec. 8.6 pendulum on a cart: 3 hidden layers of 30, 2,500 epochs on two 200-step trajectories,
    30 Monte-Carlo runs; validation prediction error and Frobenius Jacobian error against the simulator's
    exact Jacobian for f and g + x with no regularization, weight decay and Jacprop."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    settings = {"hidden": (30, 30, 30), "epochs": epochs or (150 if quick else 2500), "batch_size": 50,
                "lr": 1e-3, "validation_every": 10, "trajectory_length": 200, "dt": 0.02, "state_noise_rel": 0.01}
    res, first, configs = _experiment("cartpole", out_dir, quick, seed, n_runs or (2 if quick else 30),
                                      n_tune or (1 if quick else 2), settings, workers, grid)
    r = res["results"]
    res["checks"] = _checks(res)
    res["figures"] = []
    if not figures:
        return res
    plt = _plt()
    keys = ["f/weight_decay", "f/jacprop", "g/weight_decay", "g/jacprop"]
    lab = [k.replace("weight_decay", "WD").replace("jacprop", "Jacprop").replace("g/", "g+x/") for k in keys]
    fig, axs = plt.subplots(1, 2, figsize=(8, 3.5))
    _box(plt, axs[0], [r[k]["val_mse_runs"] for k in keys], lab, "validation prediction error (mse)")
    _box(plt, axs[1], [r[k]["jac_err_runs"] for k in keys], lab, "Jacobian error ||J - J_true||_F")
    fig.suptitle(f"Fig. 8.5: pendulum on a cart, {res['settings']['n_runs']} Monte-Carlo runs", fontsize=10)
    fig.tight_layout()
    fig.savefig(out_dir / "nn_cartpole_fig8_5.png", dpi=110)
    plt.close(fig)
    cfg = {(f, m): (f, m, v) for f, m, v in configs}
    fig, axs = plt.subplots(1, 2, figsize=(9, 4))
    te = first["_truth"]["eig"].ravel()
    for ax, f in zip(axs, FORMS):
        for m, col in (("weight_decay", "tab:orange"), ("jacprop", "tab:blue")):
            e = first[cfg[(f, m)]]["eig"].ravel()
            ax.plot(e.real, e.imag, ".", ms=2, alpha=0.4, color=col, label=m)
        ax.plot(te.real, te.imag, ".", ms=3, color="tab:red", label="true")
        ax.set_title("f" if f == "f" else "g + x", fontsize=9)
        ax.set_xlabel("Re")
        ax.set_ylabel("Im")
    axs[1].legend(fontsize=7)
    fig.suptitle("Fig. 8.6: Jacobian eigenvalues on validation data", fontsize=10)
    fig.tight_layout()
    fig.savefig(out_dir / "nn_cartpole_fig8_6.png", dpi=110)
    plt.close(fig)
    Jt = first["_truth"]["J_traj"]
    fig, axs = plt.subplots(4, 5, figsize=(12, 8), sharex=True)
    for i in range(4):
        for j in range(5):
            ax = axs[i, j]
            ax.plot(Jt[:, i, j], "k--", lw=1)
            ax.plot(first[cfg[("g", "weight_decay")]]["J_traj"][:, i, j], color="tab:orange", lw=0.8)
            ax.plot(first[cfg[("g", "jacprop")]]["J_traj"][:, i, j], color="tab:blue", lw=0.8)
            ax.set_title(f"({i + 1},{j + 1})", fontsize=8)
            ax.tick_params(labelsize=6)
    fig.suptitle("Fig. 8.7: Jacobian entries of g + x along a validation trajectory "
                 "(truth dashed, weight decay orange, Jacprop blue)", fontsize=10)
    fig.tight_layout()
    fig.savefig(out_dir / "nn_cartpole_fig8_7.png", dpi=110)
    plt.close(fig)
    res["figures"] = ["nn_cartpole_fig8_5.png", "nn_cartpole_fig8_6.png", "nn_cartpole_fig8_7.png"]
    return res


EXPERIMENTS = {"nn-linear": nn_linear, "nn-cartpole": nn_cartpole}
