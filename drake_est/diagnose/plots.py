"""PNG plots of the diagnosis (matplotlib, Agg): held-out residual of the nominal and the final
model against time, arm position, motor position and velocity, and the simulation windows."""
from __future__ import annotations

import numpy as np




#: the profile panels of unexplained.png, in the order they are looked for: (profile key, x label of the entry,
#: y label); each plots the entry's profile against "profile_mean_residual"
PROFILE_PANELS = (
    ("profile_snap", lambda u: "snap d^4q/dt^4 [rad/s^4] (accelerating samples left out by (9.9))", "mean residual"),
    ("profile_fitted_jerk_snap", lambda u: ("fitted jerk and snap part of the residual, torque smoothed like qdd "
                                            "(accelerating samples left out by (9.9))"),
     "mean residual (nuisance columns out)"),
    ("profile_jerk", lambda u: "jerk d^3q/dt^3 [rad/s^3] (accelerating samples left out by (9.9))",
     "mean residual (nuisance columns out)"),
    ("profile_torque_difference", lambda u: (f"(M(t - d) - M(t + d)) / 2, model torque, d = {u['best_shift_s']:.3g} s "
                                             "(nuisance columns out)"), "mean residual (nuisance columns out)"),
)

def _residual_panel(ax, x, r0, r1, extended: bool, j, xlabel, what):
    """Held-out residual of joint ``j`` vs ``x``: nominal model (grey) and, if any, the extended model."""
    k = _thin(x.size)
    ax.plot(x[k], r0[k], ".", ms=2, color="0.6", alpha=0.5, label="nominal model")
    if extended:
        ax.plot(x[k], r1[k], ".", ms=2, color="C0", alpha=0.5, label="extended model")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(f"joint {j} residual [N m]")
    ax.legend(loc="upper right", markerscale=5)
    ax.set_title(f"Held-out torque residual of joint {j} vs {what}")

def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _thin(n, m=15000):
    return np.arange(n) if n <= m else np.linspace(0, n - 1, m).astype(int)


def _motor_angle(rep, jd):
    """(angle, label): the motor angle mod 2 pi from the gear ratio when known, else from the
    frequency of a detected ripple (one period per cycle), else None."""
    if jd.gear_ratio:
        return np.mod(jd.gear_ratio * jd.q, 2 * np.pi), f"motor angle mod 2π (gear ratio {jd.gear_ratio:g}) [rad]"
    for s in rep.result.steps:
        if s.ext.effect == "motor_position_ripple" and s.ext.joint == jd.joint:
            f = s.ext.evidence["frequency_per_arm_rad"]
            return np.mod(2 * np.pi * f * jd.q, 2 * np.pi), f"phase of the detected ripple ({f:.4g} cycles/rad) [rad]"
    return None, None


def write_plots(rep, out) -> list:
    plt = _plt()
    res = rep.result
    prep = res.prep
    files = []
    joints = list(prep.joints)
    nj = len(joints)
    data = {}
    for j in joints:
        jd = prep.joints[j]
        val = jd.val
        r0 = (jd.y - res.nominal_fit.pred[j])[val]
        r1 = (jd.y - res.final_fit.pred[j])[val]
        rows = jd.rows[val]
        data[j] = (jd, rows, r0, r1)
    if res.unexplained:
        xs = {"position": lambda jd, rows: jd.q[rows], "velocity": lambda jd, rows: jd.v[rows],
              "acceleration": lambda jd, rows: jd.a[rows], "time": lambda jd, rows: jd.t[rows],
              "time_correlation": lambda jd, rows: jd.t[rows],
              "acceleration_excluded_samples": lambda jd, rows: jd.a[rows],
              "jerk_excluded_samples": lambda jd, rows: np.gradient(jd.a, jd.t)[rows],
              "time_shift_torque_vs_position": lambda jd, rows: np.gradient(jd.a, jd.t)[rows],
              "motor_position": lambda jd, rows: np.mod(jd.q[rows] * (jd.gear_ratio or 1.0), 2 * np.pi)}
        U = res.unexplained[:4]
        fig, axes = plt.subplots(len(U), 1, figsize=(10, 3.0 * len(U)), squeeze=False)
        for ax, u in zip(axes[:, 0], U):
            jd, rows, r0, r1 = data[u["joint"]]
            if "profile_time_s" in u:     # an event-aligned structure (velocity reversals): its mean profile
                ax.plot(u["profile_time_s"], u["profile_mean_residual"], ".-")
                ax.axvline(0.0, color="0.5", lw=0.8)
                ax.set_xlabel("time from the velocity reversal [s]")
                ax.set_ylabel("mean residual x new direction")
            elif any(k in u for k, _, _ in PROFILE_PANELS):    # left-out-sample tests: mean residual per bin
                key, xlabel, ylabel = next(p for p in PROFILE_PANELS if p[0] in u)
                ax.plot(u[key], u["profile_mean_residual"], ".-")
                ax.axhline(0.0, color="0.5", lw=0.8)
                ax.set_xlabel(xlabel(u))
                ax.set_ylabel(ylabel)
            else:
                ax.plot(xs[u["variable"]](jd, rows), r1, ".", ms=1.5, alpha=0.4)
                ax.set_xlabel(u["variable"])
                ax.set_ylabel("final residual")
            ax.set_title(f"joint {u['joint']}: unexplained structure in {u['variable']} "
                         f"({100 * u['share_of_residual_variance']:.1f} % of residual variance)")
        fig.tight_layout()
        fig.savefig(out / "unexplained.png", dpi=100)
        plt.close(fig)
        files.append("unexplained.png")
    conc = sorted((r for r in res.rejected if r.get("gain_concentration")),
                  key=lambda r: -float(r.get("rmse_reduction") or 0.0))[:4]
    if conc:
        # where each candidate's held-out gain lies (competition.gain_concentration): the gain per group of held-out
        # blocks over time, the stretches that hold it shaded (next_experiment asks for them to be repeated)
        fig, axes = plt.subplots(len(conc), 1, figsize=(10, 2.6 * len(conc)), squeeze=False)
        for ax, r in zip(axes[:, 0], conc):
            g = r["gain_concentration"]
            for s in g["stretches"]:
                ax.axvspan(s["t_s"][0], s["t_s"][1], color="C1", alpha=0.2, lw=0)
            for x in g["group_gains"]:
                a, b = x["t_s"]
                ax.bar(0.5 * (a + b), x["gain"], width=max(b - a, 1e-3), color="C0" if x["gain"] >= 0 else "C3")
            ax.axhline(0.0, color="0.5", lw=0.8)
            ax.set_xlabel("time [s]")
            ax.set_ylabel("squared error removed\n[held-out mean squares]")
            ax.set_title(f"{r['effect']} (joint {r.get('joint')}): {100 * g['share_of_gain']:.0f} % of its gain in "
                         f"{g['groups_holding_gain']} of {g['groups']} groups; the paired test needs "
                         f"{g['groups_needed']}")
        fig.tight_layout()
        fig.savefig(out / "next_experiment.png", dpi=100)
        plt.close(fig)
        files.append("next_experiment.png")
    specs = [("residual_time.png", "time [s]", lambda jd, rows: jd.t[rows]),
             ("residual_position.png", "arm position [rad]", lambda jd, rows: jd.q[rows]),
             ("residual_velocity.png", "velocity [rad/s]", lambda jd, rows: jd.v[rows])]
    for name, xlabel, xf in specs:
        fig, axes = plt.subplots(nj, 1, figsize=(10, 3.2 * nj), squeeze=False)
        for ax, j in zip(axes[:, 0], joints):
            jd, rows, r0, r1 = data[j]
            _residual_panel(ax, xf(jd, rows), r0, r1, bool(res.steps), j, xlabel, xlabel.split(" [")[0])
        fig.tight_layout()
        fig.savefig(out / name, dpi=100)
        plt.close(fig)
        files.append(name)
    fig, axes = plt.subplots(nj, 1, figsize=(10, 3.2 * nj), squeeze=False)
    any_motor = False
    for ax, j in zip(axes[:, 0], joints):
        jd, rows, r0, r1 = data[j]
        ang, label = _motor_angle(rep, jd)
        if ang is None:
            ax.text(0.5, 0.5, f"joint {j}: no gear ratio known and no ripple detected", ha="center",
                    transform=ax.transAxes)
            ax.set_axis_off()
            continue
        any_motor = True
        _residual_panel(ax, ang[rows], r0, r1, bool(res.steps), j, label, "motor angle")
    fig.tight_layout()
    if any_motor:
        fig.savefig(out / "residual_motor_position.png", dpi=100)
        files.append("residual_motor_position.png")
    plt.close(fig)
    sim = rep.simulation
    if sim and sim.get("_traces"):
        tr = sim["_traces"]
        fig, axes = plt.subplots(nj, len(tr), figsize=(3.6 * len(tr), 3.0 * nj), squeeze=False)
        for c, w in enumerate(tr):
            for r, j in enumerate(sim["joints"]):
                ax = axes[r, c]
                ts, Vm = w["measured"]
                ax.plot(ts, Vm[:, r], "k-", lw=1.5, label="measured")
                ax.plot(w["nominal"][0], w["nominal"][1][:, r], "--", color="0.5", label="nominal sim.")
                ax.plot(w["extended"][0], w["extended"][1][:, r], "-", color="C0", label="extended sim.")
                ax.set_xlabel("time [s]")
                ax.set_ylabel(f"joint {j} velocity [rad/s]")
                if r == 0 and c == 0:
                    ax.legend(fontsize=7)
        fig.suptitle("Simulation with the measured torque from the measured state (Sec. 3.1)")
        fig.tight_layout()
        fig.savefig(out / "simulation.png", dpi=100)
        plt.close(fig)
        files.append("simulation.png")
    return files
