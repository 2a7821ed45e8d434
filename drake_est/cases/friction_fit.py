"""Fit a friction model to one joint of a :class:`drake_est.data.Log` (thesis Ch. 9) -- the workflow behind
``drake-est fit-friction``, the friction reproductions and the friction tutorial: pick the joint, subtract the
rigid-body torque of a known robot, select steady samples (9.9), fit with hold-out validation, tabulate the
metrics and plot the fit."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from drake_est.errors import DataError, DrakeEstError


def _robot(kind, log):
    if kind == "none":
        return None, None
    if kind == "auto":
        if log.n_joints != 6 or log.joints != [1, 2, 3, 4, 5, 6]:
            return None, None
        kind = "irb140"
    from drake_est import robots

    if log.joints != [1, 2, 3, 4, 5, 6]:
        raise DataError(f"--robot irb140 needs all 6 joints in the log to compute ID(q, dq, ddq); log has {log.joints}")
    return robots.irb140(), robots.irb140_metadata()


def fit_log(log, model="nominal", joint=None, robot="auto", nominal="asymmetric", gear_ratio=None, holdout=0.3,
            v_min=None, a_max=None, n_position=None, width_factor=None, energy_iters=50, truth=None):
    """Fit from a :class:`drake_est.data.Log` (what the CLI does). Returns (FrictionResult, info dict)."""
    from drake_est.identification.friction import fit_friction, friction_target, select_steady

    if log.tau is None:
        raise DataError("the log has no torque columns (tau<j>); friction cannot be identified")
    log = log.with_derivatives()
    if joint is None:
        joint = log.joints[int(np.argmax(np.std(log.dq, axis=0)))]
    col = log.col(joint)
    span = float(np.ptp(log.q[:, col]))
    if span < 0.02 or float(np.quantile(np.abs(log.dq[:, col]), 0.95)) < 1e-3:
        raise DataError(f"joint {joint} is not excited (position range {span:.3g}, it holds still); "
                        f"friction cannot be identified -- pick a moving joint with --joint")
    if v_min is not None and v_min >= float(np.max(np.abs(log.dq[:, col]))):
        raise DataError(f"--v-min {v_min:g} rad/s is above the largest speed of joint {joint} "
                        f"({float(np.max(np.abs(log.dq[:, col]))):.3g} rad/s): no sample would be kept")
    rob, meta = _robot(robot, log)
    # (9.9) on this joint and, for the coupled model, on the coupled joints too (their sign(v) terms)
    sel_cols = [col]
    if model == "coupled" and meta is not None:
        from drake_est.joints import coupled_joints
        sel_cols += [log.col(i) for i in coupled_joints(meta.motor_from_arm, joint) if i in log.joints]
    sel = select_steady(log.dq[:, sel_cols], log.ddq[:, sel_cols], v_min=v_min, a_max=a_max)
    # constant-velocity experiment (Sec. 9.6 sweep): keep (9.9) samples, subtract ID(q, dq, 0) only;
    # otherwise (e.g. sinusoidal excitation: median |a| above 5 % of max |v| per second) subtract the full
    # ID(q, dq, ddq) and keep accelerating samples
    moving = np.abs(log.dq[:, col]) > sel.v_min
    med_a = float(np.median(np.abs(log.ddq[moving, col]))) if np.any(moving) else 0.0
    steady = rob is None or a_max is not None or med_a < 0.05 * float(np.quantile(np.abs(log.dq[:, col]), 0.99))
    if not steady:
        sel = select_steady(log.dq[:, sel_cols], log.ddq[:, sel_cols], v_min=v_min, a_max=np.inf)
    y = friction_target(log, col, rob, inertia=not steady)
    if gear_ratio is None and meta is not None:
        gear_ratio = float(meta.gear_ratios[joint - 1])
    coupling = None
    if model == "coupled":
        if meta is None:
            raise DrakeEstError("the coupled model needs the robot's coupling matrix: use --robot irb140 with a "
                                "6-joint log")
        coupling = meta.motor_from_arm
    res = fit_friction(log.t, log.q, log.dq, y, model=model, index=col, nominal=nominal, gear_ratio=gear_ratio,
                       coupling=coupling, holdout=holdout, selection=sel, n_position=n_position,
                       width_factor=width_factor, energy_iters=energy_iters, truth=truth, joint_number=joint,
                       joint_numbers=list(log.joints))
    info = {"joint": joint, "index": col, "robot": None if meta is None else meta.name,
            "rigid_body_subtracted": rob is not None, "gear_ratio": gear_ratio,
            "inertia_subtracted": bool(rob is not None and not steady),
            "experiment": "constant-velocity (9.9)" if steady else "excitation (ID subtracted)"}
    return res, info


def format_table(rows: dict) -> str:
    """rows: name -> metrics dict; prints Fit/FPE/RMSE/MAE (and NPE) side by side."""
    keys = [("fit", "Fit (%)", "{:9.3f}"), ("fpe", "FPE", "{:9.3e}"), ("rmse", "RMSE", "{:9.3e}"),
            ("mae", "MAE", "{:9.3e}"), ("npe", "NPE", "{:9.3e}")]
    names = list(rows)
    lines = ["metric     " + " ".join(f"{n:>16s}" for n in names)]
    for k, label, fmt in keys:
        if not any(k in rows[n] for n in names):
            continue
        vals = [fmt.format(rows[n][k]) if k in rows[n] else "        -" for n in names]
        lines.append(f"{label:10s} " + " ".join(f"{v:>16s}" for v in vals))
    return "\n".join(lines)


def plot_result(res, out_dir, prefix="", title=""):
    """PNG plots: torque vs position and velocity with the model, residual histogram,
    fit over time early (cold) and late (warm) in the log (cf. Fig. 9.8). Returns the paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    a = res.arrays
    t, q, v, y, yhat, sel, train = a["t"], a["q"], a["dq"], a["y"], a["yhat"], a["selected"], a["train"]
    val = sel & ~train
    paths = []
    # torque vs position and velocity
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    for sgn, c in ((1, "tab:blue"), (-1, "tab:red")):
        m = sel & (np.sign(v) == sgn)
        ax[0].plot(q[m], y[m], ".", ms=1.5, color=c, alpha=0.3, label=f"data, v {'>' if sgn > 0 else '<'} 0")
        # model at the measured (q, v) of each sample: points, since samples at one q have different v
        ax[0].plot(q[m], yhat[m], ".", ms=0.8, color="k" if sgn > 0 else "0.35",
                   label=f"model, v {'>' if sgn > 0 else '<'} 0")
    ax[0].set_xlabel("joint position q [rad]")
    ax[0].set_ylabel("friction torque [N m]")
    ax[0].set_title("torque vs position (black/grey: model)")
    ax[0].legend(loc="best", fontsize=8, markerscale=6)
    ax[1].plot(v[sel], y[sel], ".", ms=1.5, alpha=0.3, label="data")
    ax[1].plot(v[sel], yhat[sel], ".", ms=1.0, color="k", alpha=0.3, label="model")
    ax[1].set_xlabel("joint velocity v [rad/s]")
    ax[1].set_ylabel("friction torque [N m]")
    ax[1].set_title("torque vs velocity")
    ax[1].legend(loc="best", fontsize=8, markerscale=6)
    fig.suptitle(title)
    fig.tight_layout()
    p = out_dir / f"{prefix}torque_vs_position_velocity.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    paths.append(p)
    # residual histogram (validation block)
    fig, ax = plt.subplots(figsize=(6, 4))
    r = y[val] - yhat[val]
    ax.hist(r, bins=60, color="tab:gray")
    ax.set_xlabel("validation residual y - F [N m]")
    ax.set_ylabel("count")
    ax.set_title(f"residuals on held-out data (RMSE {res.validation['rmse']:.3g} N m)")
    fig.tight_layout()
    p = out_dir / f"{prefix}residual_histogram.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    paths.append(p)
    # fit over time, early and late (cold / warm)
    span = max(0.05 * (t[-1] - t[0]), min(30.0, t[-1] - t[0]))
    fig, ax = plt.subplots(2, 1, figsize=(10, 6))
    for k, (t0, lab) in enumerate(((t[0], "early (cold)"), (t[-1] - span, "late (warm, held out)"))):
        m = (t >= t0) & (t <= t0 + span)
        ax[k].plot(t[m], y[m], ".", ms=2, color="0.5", label="measured")
        ax[k].plot(t[m], np.where(sel[m], yhat[m], np.nan), "-", lw=1.0, color="tab:blue", label="model")
        ax[k].set_ylabel("friction torque [N m]")
        ax[k].set_title(lab)
        ax[k].legend(loc="upper right", fontsize=8)
    ax[1].set_xlabel("time [s]")
    fig.tight_layout()
    p = out_dir / f"{prefix}fit_over_time.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    paths.append(p)
    return paths
