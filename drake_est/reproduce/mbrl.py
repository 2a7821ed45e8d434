"""Reproduction of thesis Sec. 11.2 (Figs. 11.1 and 11.2): model-based RL on the Drake cart-pole.

``drake-est reproduce mbrl-cartpole``: Algorithm 7 (:func:`drake_est.control.mbrl.mbrl`) with the true model
(optimal control, DDP), an LTV model by (7.5) with lambda by maximum likelihood, an LTI model, and the two
neural-network-prior variants of Sec. 11.2 (LTV with the prior of a network refit every iteration, covariance
decaying as 1/iteration, ``"ltv-nn"``; LTV with the prior of a network pretrained once on random-input
identification experiments, fixed covariance, ``"ltv-nn-pretrained"``), all over the same seeds; cost per
learning iteration (median and interquartile band) and the optimized trajectories.
"""
from __future__ import annotations

import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from drake_est.progress import progress

KINDS = ("ltv", "lti", "ltv-nn", "ltv-nn-pretrained")
LABELS = {"ltv": "LTV model (7.5)", "lti": "LTI model", "ltv-nn": "LTV + successive NN prior",
          "ltv-nn-pretrained": "LTV + pretrained NN prior"}
COLORS = {"ltv": "C0", "lti": "C3", "ltv-nn": "C2", "ltv-nn-pretrained": "C1"}


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _one(args):
    kind, seed, iterations, kl_step, extra = args
    from drake_est.control.cartpole import benchmark_problem
    from drake_est.systems.cartpole_plant import CartPoleTrueSystem
    from drake_est.control.mbrl import mbrl
    try:
        from threadpoolctl import threadpool_limits
        limit = threadpool_limits(1)         # one BLAS thread per worker process (the workers fill the cores)
    except ImportError:  # pragma: no cover
        import contextlib
        limit = contextlib.nullcontext()
    model, cost, x0, _, lo, hi = benchmark_problem()
    true = CartPoleTrueSystem()
    t0 = time.perf_counter()
    with limit:
        r = mbrl(true, model, cost, x0, 400, model=kind, iterations=iterations, kl_step=kl_step, seed=seed,
                 lower=lo, upper=hi, **extra)
    return kind, seed, r, time.perf_counter() - t0


def first_within(curve, tol):
    """1-based first learning iteration at which ``curve`` <= ``tol`` (None if never)."""
    hit = np.nonzero(np.asarray(curve) <= tol)[0]
    return int(hit[0]) + 1 if hit.size else None


def _variant_stats(curves, J_opt, tol):
    """Per model: median cost curve, first iteration of the median curve within 5 %, per-seed first
    iterations (median over seeds, a seed that never gets there counting as later than any), seeds there."""
    med = np.median(curves, axis=0)
    per_seed = [first_within(c, tol) for c in curves]
    reached = sorted(i for i in per_seed if i is not None)
    n = len(per_seed)
    # median over all seeds with "never" as +infinity: defined when more than half of the seeds get there
    big = [np.inf if i is None else i for i in per_seed]
    med_first = float(np.median(big))
    return {
        "median_cost": med.tolist(),
        "median_ratio": (med / J_opt).tolist(),
        "first_iteration_median_within_5pct": first_within(med, tol),
        "median_over_seeds_first_iteration_within_5pct": med_first if np.isfinite(med_first) else None,
        "seeds_within_5pct": len(reached),
        "n_seeds": n,
        "best_median_ratio": float(med.min() / J_opt),
        "final_median_ratio": float(med[-1] / J_opt),
        "mean_median_ratio_iterations_2_to_5": float(np.mean(med[1:5] / J_opt)) if len(med) >= 5 else None,
    }


def mbrl_cartpole(out_dir, quick=False, seed=0, n_seeds=None, iterations=20, kl_step=400.0, jobs=None,
                  nn_variants=True, noise_scale=0.25, lam_grid=None, nn_prior_cov=1.0,
                  nn_pretrained_prior_cov=10.0, **kw):
    """Fig. 11.1 / 11.2: cost per learning iteration (median over seeds) for true-model DDP, LTV, LTI and the
    two NN-prior variants (``nn_variants``; same seeds).

    Acceptance (issue 14): the median LTV cost comes within 5 % of the true-model DDP cost in at most 20
    iterations while the LTI one does not.  ``noise_scale`` scales the exploration covariance Q_uu^{-1};
    ``lam_grid`` = (log10 low, log10 high, count) is the lambda grid of the LTV fit; ``nn_prior_cov``: prior
    covariance of the successive NN prior at iteration 1 (then / iteration); ``nn_pretrained_prior_cov``: the
    fixed one of the pretrained prior (both per parameter, in absolute units, with the data weighted by the
    ML noise level, :func:`drake_est.control.mbrl.fit_ltv`).  The pretrained network is trained once here
    (:func:`drake_est.control.mbrl.pretrain_network_prior`, seed ``seed``) and shared by all seeds.  Seeds run
    in ``jobs`` worker processes (default: min(4, cores))."""
    from drake_est.control.mbrl import pretrain_network_prior
    t_start = time.perf_counter()
    out_dir = Path(out_dir)
    plt = _plt()
    if jobs is None:
        import os
        jobs = min(4, os.cpu_count() or 1)
    n_seeds = n_seeds or (3 if quick else 20)
    seeds = [seed + s for s in range(n_seeds)]
    extra = {"noise_scale": float(noise_scale)}
    if lam_grid is not None:
        extra["lams"] = np.logspace(float(lam_grid[0]), float(lam_grid[1]), int(lam_grid[2]))
    kinds = KINDS if nn_variants else KINDS[:2]
    extras = {k: dict(extra) for k in kinds}
    pre_info = None
    if nn_variants:
        t0 = time.perf_counter()
        pre = pretrain_network_prior(seed=seed)
        pre_info = {"seconds": time.perf_counter() - t0, "gradient_steps": pre.total_steps,
                    "data": "20 random low-pass-input rollouts (T = 400) of the analytic cart-pole (8.11)-(8.12), "
                            "nominal parameters, random initial states"}
        extras["ltv-nn"]["nn_prior_cov"] = float(nn_prior_cov)
        extras["ltv-nn-pretrained"].update(pretrained=pre, nn_prior_cov=float(nn_pretrained_prior_cov))
    tasks = [("true", seed, iterations, kl_step, {})] + [(k, s, iterations, kl_step, extras[k])
                                                          for k in kinds for s in seeds]
    results = {k: {} for k in ("true",) + kinds}
    run_seconds = {k: 0.0 for k in ("true",) + kinds}
    if jobs > 1:
        with ProcessPoolExecutor(jobs) as ex:
            for kind, s, r, sec in progress(ex.map(_one, tasks), total=len(tasks), desc="mbrl-cartpole runs"):
                results[kind][s] = r
                run_seconds[kind] += sec
    else:
        for t in progress(tasks, desc="mbrl-cartpole runs"):
            kind, s, r, sec = _one(t)
            results[kind][s] = r
            run_seconds[kind] += sec
    J_opt = results["true"][seed].costs[0]
    curves = {k: np.array([results[k][s].costs for s in seeds]) for k in kinds}
    tol = 1.05 * J_opt
    stats = {k: _variant_stats(curves[k], J_opt, tol) for k in kinds}
    med = {k: np.asarray(stats[k]["median_cost"]) for k in kinds}

    it = np.arange(1, iterations + 1)
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for k in kinds:
        lo, hi = np.percentile(curves[k], [25, 75], axis=0)
        ax.plot(it, med[k], color=COLORS[k], label=f"{LABELS[k]} (median of {n_seeds})")
        ax.fill_between(it, lo, hi, color=COLORS[k], alpha=0.15)
    ax.axhline(J_opt, color="k", ls="--", label=f"DDP with the true model ({J_opt:.1f})")
    ax.axhline(tol, color="k", ls=":", lw=0.8, label="+5 %")
    ax.set_yscale("log")
    ax.set_xlabel("learning iteration (= experiments on the system)")
    ax.set_ylabel("cost J over T = 400 steps [-]")
    ax.set_title("Fig. 11.1: model-based RL on the Drake cart-pole (bands: 25-75 %)", fontsize=10)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out_dir / "mbrl_cartpole_fig11_1.png", dpi=120)
    plt.close(fig)

    names = ["theta [rad]", "theta' [rad/s]", "p [m]", "v [m/s]", "u [m/s^2]"]
    fig, axs = plt.subplots(5, 1, figsize=(7, 8), sharex=True)
    tt = np.arange(401) * 0.01
    for k in ("true",) + kinds:
        r = results[k][seed]
        X, U = (r.X, r.U) if k == "true" else (r.X_rollout, r.U_rollout)
        lab = "DDP (true model)" if k == "true" else f"{LABELS[k]} (last rollout, with exploration noise)"
        style = "-"
        color = "k" if k == "true" else COLORS[k]
        for i in range(4):
            axs[i].plot(tt, X[:, i], style, color=color, lw=1, label=lab)
        axs[4].plot(tt[:-1], U[:, 0], style, color=color, lw=0.8)
    for a, nme in zip(axs, names):
        a.set_ylabel(nme, fontsize=8)
    axs[0].legend(fontsize=6)
    axs[-1].set_xlabel("time [s]")
    fig.suptitle(f"Fig. 11.2: optimized trajectories after {iterations} iterations (seed {seed})", fontsize=10)
    fig.tight_layout()
    fig.savefig(out_dir / "mbrl_cartpole_fig11_2.png", dpi=120)
    plt.close(fig)

    ltv_hit = stats["ltv"]["first_iteration_median_within_5pct"]
    lti_hit = stats["lti"]["first_iteration_median_within_5pct"]
    out = {
        "J_true_model_ddp": J_opt,
        "n_seeds": n_seeds, "iterations": iterations, "kl_step_initial": kl_step, "noise_scale": float(noise_scale),
        "lam_grid_log10": list(lam_grid) if lam_grid is not None else "default (-2, 4, 7)",
        "median_cost_ltv": med["ltv"].tolist(), "median_cost_lti": med["lti"].tolist(),
        "best_median_ratio_ltv": stats["ltv"]["best_median_ratio"],
        "best_median_ratio_lti": stats["lti"]["best_median_ratio"],
        "final_median_ratio_ltv": stats["ltv"]["final_median_ratio"],
        "final_median_ratio_lti": stats["lti"]["final_median_ratio"],
        "first_iteration_median_ltv_within_5pct": ltv_hit,
        "first_iteration_median_lti_within_5pct": lti_hit,
        "acceptance_ltv_within_5pct_in_20_and_lti_not": bool(ltv_hit is not None and ltv_hit <= 20
                                                               and lti_hit is None),
        "seeds_ltv_within_5pct": stats["ltv"]["seeds_within_5pct"],
        "lambda_ltv_median": float(np.median([l for s in seeds for l in results["ltv"][s].lam])),
        "true_system": "Drake MultibodyPlant models/cartpole.urdf + CartAccelerationActuator, Euler h = 0.01",
        "variants": stats,
        "run_seconds_summed_over_seeds": run_seconds,
        "jobs": int(jobs),
    }
    if nn_variants:
        out["nn_prior"] = {"successive_prior_cov_iteration_1": float(nn_prior_cov),
                           "pretrained_prior_cov": float(nn_pretrained_prior_cov), "pretraining": pre_info}
        out["nn_prior_speeds_start_vs_ltv"] = {
            k: bool(stats[k]["mean_median_ratio_iterations_2_to_5"]
                    < stats["ltv"]["mean_median_ratio_iterations_2_to_5"])
            for k in ("ltv-nn", "ltv-nn-pretrained")} if iterations >= 5 else None
    out["wall_seconds"] = time.perf_counter() - t_start
    return out


EXPERIMENTS = {"mbrl-cartpole": mbrl_cartpole}

_ROW_NAMES = {"ltv": "LTV (7.5)", "lti": "LTI", "ltv-nn": "LTV + successive NN prior (`ltv-nn`)",
              "ltv-nn-pretrained": "LTV + pretrained NN prior (`ltv-nn-pretrained`)"}


def variants_markdown(result: dict, label: str = "") -> str:
    """The README's Fig. 11.1 table, made from the JSON that :func:`mbrl_cartpole` returns (so that the
    README's numbers are the measured ones): per model the median cost / DDP at iterations 2, 3, 5, 10 and the
    last, the first iteration of the median curve within 5 % (with its ratio), the median over seeds of the
    first iteration within 5 %, how many seeds get there, and the mean median ratio over iterations 2-5."""
    var = result["variants"]
    its = [i for i in (2, 3, 5, 10) if i < result["iterations"]] + [result["iterations"]]
    head = (f"| model ({result['n_seeds']} seeds{', ' + label if label else ''}) | median cost / DDP at iteration "
            f"{', '.join(map(str, its))} | first iteration of the median curve within 5 % | median over seeds of "
            "the first iteration within 5 % | seeds within 5 % | mean median ratio, iterations 2–5 |")
    rows = [head, "|---|---|---|---|---|---|"]
    for k, name in _ROW_NAMES.items():
        if k not in var:
            continue
        v = var[k]
        r = v["median_ratio"]
        ratios = ", ".join(f"{r[i - 1]:.3g}" for i in its[:-1]) + f", {r[its[-1] - 1]:.4g}"
        hit = v["first_iteration_median_within_5pct"]
        first = f"never (best {v['best_median_ratio']:.4g})" if hit is None else f"{hit} ({r[hit - 1]:.3f} ×)"
        med = v["median_over_seeds_first_iteration_within_5pct"]
        med = "never" if med is None else f"{med:g}"
        rows.append(f"| {name} | {ratios} | {first} | {med} | {v['seeds_within_5pct']} | "
                    f"{v['mean_median_ratio_iterations_2_to_5']:.4g} |")
    return "\n".join(rows)


if __name__ == "__main__":  # python -m drake_est.reproduce.mbrl --markdown FILE.json [LABEL]
    import argparse
    import json

    ap = argparse.ArgumentParser(description="Print the README's Fig. 11.1 table from a mbrl-cartpole JSON.")
    ap.add_argument("--markdown", required=True, metavar="JSON")
    ap.add_argument("label", nargs="?", default="")
    a = ap.parse_args()
    print(variants_markdown(json.loads(Path(a.markdown).read_text()), a.label))
