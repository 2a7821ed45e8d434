"""Reproductions of thesis Ch. 7 (LTV identification): ltv-jump, ltv-drift, ltv-robot."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from drake_est.identification import ltv
from drake_est.progress import progress


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


# ---------------------------------------------------------------------------------------------
# Sec. 7.6, Fig. 7.1
# ---------------------------------------------------------------------------------------------
def _local_refine(x, u, y, t, half=20):
    """Exact 1-switch DP (7.8) in a window around a group-lasso knot (the two-step idea of (7.10))."""
    T = u.shape[0]
    a, b = max(0, t - half), min(T, t + half)
    r = ltv.ltv_segments(x[a:b], u[a:b], 1, y=y[a:b])
    return a + r.change_times[0]


def ltv_jump(out_dir, quick=False, seed=0, lam=20.0, n_seeds=None, **kw):
    """Sec. 7.6 / Fig. 7.1: jump-linear system, switch at t = 200 found by the group lasso (7.6)."""
    out_dir = Path(out_dir)
    plt = _plt()
    x, u, y, A, B = ltv.jump_system(T=400, t_switch=200, sigma=0.2, seed=seed)
    g = ltv.ltv_group_lasso(x[:-1], u, lam, y=y)
    t_gl = ltv.change_points(g.k, n=1)[0]
    seg = ltv.ltv_segments(x[:-1], u, 1, y=y)
    fig, ax = plt.subplots(figsize=(7, 4))
    for i in range(2):
        for j in range(2):
            ax.plot(g.A[:, i, j], label=f"A[{i + 1},{j + 1}] (7.6)")
            ax.plot(A[:, i, j], "k--", lw=1, label="truth" if i == j == 0 else None)
    ax.axvline(t_gl, color="r", lw=0.8, ls=":", label=f"detected change t={t_gl}")
    ax.set_xlabel("time index t")
    ax.set_ylabel("coefficient of A_t [-]")
    ax.set_title(f"Fig. 7.1: jump-linear system, group lasso (7.6), lambda={lam:g}", fontsize=10)
    ax.legend(fontsize=7, ncol=3, loc="upper center", bbox_to_anchor=(0.5, -0.16), frameon=False)
    fig.tight_layout()
    fig.savefig(out_dir / "ltv_jump_fig7_1.png", dpi=120)
    plt.close(fig)
    n_seeds = n_seeds or (5 if quick else 20)
    found_gl, found_ref, found_dp = [], [], []
    for s in progress(range(n_seeds), desc="ltv-jump seeds"):
        xs, us, ys, *_ = ltv.jump_system(T=400, t_switch=200, sigma=0.2, seed=s)
        gs = ltv.ltv_group_lasso(xs[:-1], us, lam, y=ys)
        t = ltv.change_points(gs.k, n=1)[0]
        found_gl.append(int(t))
        found_ref.append(int(_local_refine(xs[:-1], us, ys, t)))
        found_dp.append(int(ltv.ltv_segments(xs[:-1], us, 1, y=ys).change_times[0]))

    def rate(v):
        return float(np.mean(np.abs(np.array(v) - 200) <= 2))

    return {
        "thesis": {"switch_time": 200, "detected": "at t = 200 (Fig. 7.1)"},
        "lambda": lam,
        "seed": seed,
        "detected_change_group_lasso": int(t_gl),
        "detected_change_dp_7_8": int(seg.change_times[0]),
        "admm_iterations": int(g.info["iterations"]),
        "n_seeds": n_seeds,
        "located_within_2_rate_group_lasso": rate(found_gl),
        "located_within_2_rate_group_lasso_refined": rate(found_ref),
        "located_within_2_rate_dp": rate(found_dp),
        "change_times_group_lasso": found_gl,
        "change_times_refined": found_ref,
        "change_times_dp": found_dp,
    }


# ---------------------------------------------------------------------------------------------
# Sec. 7.7, Figs. 7.2-7.4
# ---------------------------------------------------------------------------------------------
def ltv_drift(out_dir, quick=False, seed=0, T=None, **kw):
    """Sec. 7.7 / Figs. 7.2-7.4: slowly drifting system, lambda by maximum likelihood (peak near 10)."""
    from scipy import stats

    out_dir = Path(out_dir)
    plt = _plt()
    T = T or (800 if quick else 2000)
    x, u, A, B = ltv.drift_system(T=T, n=3, m=2, sigma_v=0.01, sigma_w=0.001, seed=seed)
    lams_grid = np.logspace(-0.5, 3.5, 9 if quick else 33)
    lam_ml, lams, lls = ltv.ltv_select_lambda_ml(x, u, lams=lams_grid)
    show = [1.0, 10.0, 100.0, 1000.0]
    fits = {lam: ltv.ltv_smoother(x, u, lam) for lam in show}
    # Fig. 7.2
    fig, axes = plt.subplots(3, 3, figsize=(9, 6), sharex=True)
    for i in range(3):
        for j in range(3):
            ax = axes[i, j]
            ax.plot(A[:, i, j], "k", lw=1.5, label="true")
            for lam in show:
                ax.plot(fits[lam].A[:, i, j], lw=0.8, label=f"lambda={lam:g}")
            ax.set_title(f"A[{i + 1},{j + 1}]", fontsize=8)
    axes[0, 0].legend(fontsize=6)
    for ax in axes[-1]:
        ax.set_xlabel("time index t")
    fig.suptitle("Fig. 7.2: parameters of A_t, truth (black) and (7.3) for several lambda")
    fig.tight_layout()
    fig.savefig(out_dir / "ltv_drift_fig7_2.png", dpi=120)
    plt.close(fig)
    # Fig. 7.3
    pred_err, model_err = {}, {}
    fig = plt.figure(figsize=(11, 6.5))
    gs = fig.add_gridspec(2, 4)
    top = [fig.add_subplot(gs[0, 0:2]), fig.add_subplot(gs[0, 2:4])]
    qq = [fig.add_subplot(gs[1, c]) for c in range(4)]
    for c, lam in enumerate(show):
        r = fits[lam]
        e = (x[1:] - r.predict(x[:-1], u)).reshape(-1)
        pred_err[lam] = float(np.mean(e ** 2))
        model_err[lam] = float(np.mean(np.sum((r.A - A) ** 2, axis=(1, 2)) + np.sum((r.B - B) ** 2, axis=(1, 2))))
        stats.probplot(e, dist="norm", plot=qq[c])
        qq[c].set_title(f"Q-Q, lambda={lam:g}", fontsize=9)
        qq[c].set_ylabel("ordered residuals" if c == 0 else "")
        qq[c].set_xlabel("theoretical quantiles", fontsize=9)
        qq[c].tick_params(labelsize=8)
    top[0].loglog(show, [pred_err[l] for l in show], "o-")
    top[0].set_ylabel("mean squared prediction error")
    top[1].loglog(show, [model_err[l] for l in show], "o-")
    top[1].set_ylabel("mean squared model error")
    for ax in top:
        ax.set_xlabel("lambda")
        ax.tick_params(which="minor", labelsize=7)
        ax.grid(True, which="major", alpha=0.3)
    fig.suptitle("Fig. 7.3: prediction and model errors on training data")
    fig.tight_layout()
    fig.savefig(out_dir / "ltv_drift_fig7_3.png", dpi=120)
    plt.close(fig)
    # Fig. 7.4
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.semilogx(lams, lls)
    ax.semilogx([lam_ml], [max(lls)], "o", label=f"maximum near lambda={lam_ml:.3g}")
    ax.set_xlabel("lambda")
    ax.set_ylabel("log-likelihood")
    ax.set_title("Fig. 7.4: likelihood of (7.1)-(7.2) vs lambda")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out_dir / "ltv_drift_fig7_4.png", dpi=120)
    plt.close(fig)
    return {
        "thesis": {"lambda_optimal": 10.0, "note": "lambda ~ sigma_v / sigma_w = 10 (Figs. 7.2-7.4)"},
        "T": T, "seed": seed, "lambda_ml": lam_ml,
        "model_error_by_lambda": {str(k): v for k, v in model_err.items()},
        "prediction_error_by_lambda": {str(k): v for k, v in pred_err.items()},
        "best_lambda_by_model_error": float(min(model_err, key=model_err.get)),
    }


# ---------------------------------------------------------------------------------------------
# Sec. 7.8, Figs. 7.5-7.6
# ---------------------------------------------------------------------------------------------
def two_link_arm_plant(time_step=1e-3):
    """A planar two-link arm moving in the horizontal plane (joint axes along gravity, so gravity does
    no work): link lengths 0.5 m / 0.4 m, masses 2 / 1 kg; built by
    :func:`drake_est.systems.builders.MakeTwoLinkArmPlant`."""
    from drake_est.systems.builders import MakeTwoLinkArmPlant
    return MakeTwoLinkArmPlant(time_step, actuators=False)   # torques are applied by _simulate_arm


def _simulate_arm(plant, u_traj, dt, fc, wall, k_wall, d_wall, q0, v0, substeps=10):
    """Simulate the arm with Coulomb friction and a stiff joint-space contact (wall on q2).

    The rigid-body dynamics come from the MultibodyPlant (mass matrix, bias and gravity terms);
    friction and contact torques are added and integrated semi-implicitly at dt / substeps."""
    ctx = plant.CreateDefaultContext()
    n = 2
    T = u_traj.shape[0]
    q = np.array(q0, float)
    v = np.array(v0, float)
    h = dt / substeps
    X = np.zeros((T + 1, 2 * n))
    X[0, :n], X[0, n:] = q, v
    contact = np.zeros(T, bool)
    for t in range(T):
        for _ in range(substeps):
            plant.SetPositions(ctx, q)
            plant.SetVelocities(ctx, v)
            M = plant.CalcMassMatrix(ctx)
            Cv = plant.CalcBiasTerm(ctx)
            g = plant.CalcGravityGeneralizedForces(ctx)
            tau = u_traj[t] - fc * np.sign(v)
            pen = q[1] - wall
            if pen > 0:
                tau[1] -= k_wall * pen + d_wall * v[1]
                contact[t] = True
            a = np.linalg.solve(M, tau + g - Cv)
            v = v + h * a
            q = q + h * v
        X[t + 1, :n], X[t + 1, n:] = q, v
    return X, contact


def ltv_robot(out_dir, quick=False, seed=0, lam=None, **kw):
    """Sec. 7.8 / Figs. 7.5-7.6: two-link arm (Drake MultibodyPlant) with Coulomb friction and a stiff
    contact, LTV model by (7.6) on normalized data; training and validation simulations."""
    out_dir = Path(out_dir)
    plt = _plt()
    from pydrake.multibody.tree import MultibodyForces

    plant, _ = two_link_arm_plant(0.0)
    ctx = plant.CreateDefaultContext()
    dt, T = 0.01, 200
    tt = np.arange(T) * dt
    # reference: joint 2 reverses (velocity zero crossing near t = 70) and then runs into a wall at
    # q2 = 0 rad (contact near t = 140); joint 1 moves slowly
    sgrid = tt / tt[-1]
    q_ref = np.column_stack([0.5 * sgrid, -0.2 + 1.5 * (sgrid - 0.35) ** 2])
    dq_ref = np.gradient(q_ref, dt, axis=0)
    ddq_ref = np.gradient(dq_ref, dt, axis=0)
    fc = np.array([0.2, 0.1])
    u_nom = np.zeros((T, 2))
    for t in range(T):
        plant.SetPositions(ctx, q_ref[t])
        plant.SetVelocities(ctx, dq_ref[t])
        u_nom[t] = plant.CalcInverseDynamics(ctx, ddq_ref[t], MultibodyForces(plant)) + fc * np.sign(dq_ref[t])
    rng = np.random.default_rng(seed)
    sig_u = 0.02
    u_tr = u_nom + sig_u * rng.standard_normal((T, 2))
    u_va = u_nom + sig_u * rng.standard_normal((T, 2))
    wall, k_wall, d_wall = 0.0, 200.0, 2.0
    X_tr, c_tr = _simulate_arm(plant, u_tr, dt, fc, wall, k_wall, d_wall, q_ref[0], dq_ref[0],
                               substeps=5 if quick else 10)
    X_va, c_va = _simulate_arm(plant, u_va, dt, fc, wall, k_wall, d_wall, q_ref[0], dq_ref[0],
                               substeps=5 if quick else 10)
    # normalize (zero mean, unit variance) with training statistics, as in the thesis
    mx, sx = X_tr.mean(0), X_tr.std(0) + 1e-12
    mu_, su = u_tr.mean(0), u_tr.std(0) + 1e-12
    Z = lambda X: (X - mx) / sx  # noqa: E731
    W = lambda U: (U - mu_) / su  # noqa: E731
    xn, un = Z(X_tr), W(u_tr)
    # affine LTV model: append a constant input so that the normalization offsets are representable
    un1 = np.column_stack([un, np.ones(T)])
    if lam is None:
        lam = 2.0
    g = ltv.ltv_group_lasso(xn, un1, lam, eps_abs=1e-7, eps_rel=1e-6)
    sim_tr = g.simulate(xn[0], un1)
    xv, uv1 = Z(X_va), np.column_stack([W(u_va), np.ones(T)])
    sim_va = g.simulate(xv[0], uv1)
    pred_va = g.predict(xv[:-1], uv1)

    def rms(a, b):
        return float(np.sqrt(np.mean((a - b) ** 2)))

    sc = np.flatnonzero(np.diff(np.sign(X_tr[:, 3])) != 0)
    zero_cross = int(sc[0]) if sc.size else -1
    t_contact = int(np.argmax(c_tr)) if c_tr.any() else -1
    for name, title, Xs, sim, U in (("fig7_5_training", "Fig. 7.5 (training)", xn, sim_tr, un),
                                    ("fig7_6_validation", "Fig. 7.6 (validation)", xv, sim_va, W(u_va))):
        fig, axes = plt.subplots(3, 2, figsize=(9, 6.5), sharex=True)
        labels = ["q1", "q2", "dq1", "dq2"]
        for i in range(4):
            ax = axes[i // 2, i % 2]
            ax.plot(Xs[:, i], "k", label="simulated arm")
            ax.plot(sim[:, i], "C1--", label="LTV model simulation")
            ax.set_ylabel(f"{labels[i]} (normalized)")
        for j in range(2):
            axes[2, j].plot(U[:, j], "C2")
            axes[2, j].set_ylabel(f"u{j + 1} (normalized)")
            axes[2, j].set_xlabel("time index t")
        for ax in axes.ravel():
            if zero_cross >= 0:
                ax.axvline(zero_cross, color="gray", ls="--", lw=0.8)
            if t_contact >= 0:
                ax.axvline(t_contact, color="r", ls=":", lw=0.8)
        axes[0, 0].legend(fontsize=7)
        fig.suptitle(f"{title}: arm (black) vs simulated LTV model (7.6); q2 velocity sign change (gray) "
                     f"and contact (red) of the training run", fontsize=9)
        fig.tight_layout()
        fig.savefig(out_dir / f"ltv_robot_{name}.png", dpi=120)
        plt.close(fig)
    return {
        "thesis": {"result": "model captures friction sign change and contact on training data; "
                             "error transient around the contact on validation data (Figs. 7.5-7.6)"},
        "lambda": lam, "T": T, "dt": dt,
        "velocity_zero_crossing_index_q2": zero_cross,
        "contact_index_training": t_contact,
        "contact_index_validation": int(np.argmax(c_va)) if c_va.any() else -1,
        "change_times_group_lasso": g.change_times[:20],
        "admm_iterations": int(g.info["iterations"]),
        "sim_rms_training_normalized": rms(sim_tr, xn),
        "sim_rms_validation_normalized": rms(sim_va, xv),
        "one_step_rms_validation_normalized": rms(pred_va, xv[1:]),
    }


EXPERIMENTS = {"ltv-jump": ltv_jump, "ltv-drift": ltv_drift, "ltv-robot": ltv_robot}
