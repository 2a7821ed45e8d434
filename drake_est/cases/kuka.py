"""KUKA KR300 case study: per-axis friction + gravity identification (fit on two trajectories,
validate on the third), gearbox deflection vs torque on axes 1-3, and ``diagnose`` on each axis.

Per-axis models (link side, torque = gear ratio x motor torque), least squares:

* ``friction``: tau_j = J_j qdd_j + Fv_j qd_j + Fc_j sign(qd_j) + c_j      (Eq. (9.2) + inertia)
* ``friction+gravity``: plus gravity regressors of the arm configuration, axis 2:
  sin q2, cos q2, sin(q2 + s q3), cos(q2 + s q3); axis 3: sin(q2 + s q3), cos(q2 + s q3);
  axis 5: sin/cos(q2 + s q3 +- q5).  The sign convention s = +-1 of axis 3 is chosen on the
  training trajectories (the smaller training RMSE);
* ``+coupling`` (wrist axes 4-6, Sec. 9.2 "gear coupling"): plus qd_i and sign(qd_i) of the other
  two wrist axes, as the diagnosis proposes for the coupled wrist transmission.

Compliance (the C_j(tau) of Eq. (14.3)): deflection d_j = q_motor,j - q_link,j on axes 1-3 against
the link-side torque, d = d0 + C tau + h sign(qd) (linear compliance C, with a lost-motion /
friction hysteresis term h); stiffness k = 1/C.  Validation against the constant (training mean)
deflection.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from drake_est.datasets.kuka import LINK_ENCODER_AXES, TRAJECTORIES, load_kuka, load_kuka_parameters
from drake_est.errors import DataError
from drake_est.metrics import fit_percent, rmse

MODELS = ("friction", "friction+gravity")


def _gravity_cols(q, j, s):
    q2, q3 = q[:, 1], q[:, 2]
    a = q2 + s * q3
    if j == 2:
        return [np.sin(q2), np.cos(q2), np.sin(a), np.cos(a)]
    if j == 3:
        return [np.sin(a), np.cos(a)]
    if j == 5:
        q5 = q[:, 4]
        return [np.sin(a + q5), np.cos(a + q5), np.sin(a - q5), np.cos(a - q5)]
    return []


def axis_columns(log, j: int, model: str, s: int = 1) -> np.ndarray:
    """Regressors of axis ``j`` (1-based) for ``model`` ("friction", "friction+gravity",
    "friction+gravity+coupling")."""
    c = log.col(j)
    qd, qdd = log.dq[:, c], log.ddq[:, c]
    cols = [qdd, qd, np.sign(qd), np.ones_like(qd)]
    if "gravity" in model:
        cols += _gravity_cols(log.q, j, s)
    if "coupling" in model and j in (4, 5, 6):
        for i in (4, 5, 6):
            if i != j:
                v = log.dq[:, log.col(i)]
                cols += [v, np.sign(v)]
    return np.column_stack(cols)


def _fit(logs, j, model, s):
    A = np.vstack([axis_columns(lg, j, model, s) for lg in logs])
    y = np.concatenate([lg.tau[:, lg.col(j)] for lg in logs])
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    return coef, rmse(y, A @ coef)


def fit_axis(train_logs, j: int, model: str) -> dict:
    """Least-squares fit of one axis on the training trajectories (gravity convention chosen there)."""
    if "gravity" in model and j in (2, 3, 5):
        fits = {s: _fit(train_logs, j, model, s) for s in (1, -1)}
        s = min(fits, key=lambda k: fits[k][1])
        coef, r = fits[s]
    else:
        s = 1
        coef, r = _fit(train_logs, j, model, s)
    return {"coef": coef, "sign_q3": s, "rmse_train": r}


def friction_gravity_study(logs: dict, params: dict) -> dict:
    """Three folds: fit on two trajectories, validate on the third; every axis and model."""
    out = {"folds": [], "per_axis": {}}
    models = MODELS + ("friction+gravity+coupling",)
    for val in logs:
        train = [logs[k] for k in logs if k != val]
        fold = {"validate": val, "train": [k for k in logs if k != val], "axes": {}}
        for j in range(1, 7):
            yv = logs[val].tau[:, j - 1]
            ax = {"std_N_m": float(np.std(yv))}
            for m in models:
                if "coupling" in m and j not in (4, 5, 6):
                    continue
                f = fit_axis(train, j, m)
                pred = axis_columns(logs[val], j, m, f["sign_q3"]) @ f["coef"]
                ax[m] = {"val_rmse_N_m": rmse(yv, pred), "val_fit_pct": fit_percent(yv, pred),
                         "J": float(f["coef"][0]), "Fv": float(f["coef"][1]), "Fc": float(f["coef"][2]),
                         "offset": float(f["coef"][3])}
            fold["axes"][str(j)] = ax
        out["folds"].append(fold)
    for j in range(1, 7):
        k = str(j)
        summ = {}
        for m in models:
            vals = [f["axes"][k][m]["val_rmse_N_m"] for f in out["folds"] if m in f["axes"][k]]
            if not vals:
                continue
            summ[m] = {"mean_val_rmse_N_m": float(np.mean(vals)),
                       "mean_val_fit_pct": float(np.mean([f["axes"][k][m]["val_fit_pct"] for f in out["folds"]])),
                       "Fv_mean": float(np.mean([f["axes"][k][m]["Fv"] for f in out["folds"]])),
                       "Fc_mean": float(np.mean([f["axes"][k][m]["Fc"] for f in out["folds"]]))}
        base = summ["friction"]["mean_val_rmse_N_m"]
        best = min(summ, key=lambda m: summ[m]["mean_val_rmse_N_m"])
        summ["best_model"] = best
        summ["gain_best_vs_friction"] = float(1 - summ[best]["mean_val_rmse_N_m"] / base)
        if "f_vis" in params:
            summ["benchmark_Fv"] = float(params["f_vis"][j - 1])
            # saturated Coulomb level of the benchmark model: f_coul + f_a (f_a saturates at high speed)
            summ["benchmark_Fc_plus_Fa"] = float(params["f_coul"][j - 1] + params.get("f_a", np.zeros(6))[j - 1])
        out["per_axis"][k] = summ
    return out


def deflection(log, j: int) -> np.ndarray:
    """Gearbox deflection of axis j: motor-encoder minus link-encoder position [rad]."""
    return log.q[:, log.col(j)] - log.channels[f"q_link{j}"]


def _compliance_cols(log, j, hysteresis=True):
    tau = log.tau[:, log.col(j)]
    cols = [np.ones_like(tau), tau]
    if hysteresis:
        cols.append(np.sign(log.dq[:, log.col(j)]))
    return np.column_stack(cols)


def compliance_study(logs: dict) -> dict:
    """Deflection vs torque on axes 1-3: linear compliance (+ hysteresis), fit on two trajectories,
    validated on the third against the constant model."""
    out = {}
    for j in LINK_ENCODER_AXES:
        folds = []
        for val in logs:
            train = [logs[k] for k in logs if k != val]
            y = np.concatenate([deflection(lg, j) for lg in train])
            yv = deflection(logs[val], j)
            res = {"validate": val, "const_rmse_deg": float(np.rad2deg(rmse(yv, np.full_like(yv, y.mean()))))}
            for name, hyst in (("linear", False), ("linear+hysteresis", True)):
                A = np.vstack([_compliance_cols(lg, j, hyst) for lg in train])
                coef, *_ = np.linalg.lstsq(A, y, rcond=None)
                pred = _compliance_cols(logs[val], j, hyst) @ coef
                res[name] = {"rmse_deg": float(np.rad2deg(rmse(yv, pred))),
                             "compliance_rad_per_N_m": float(coef[1]),
                             "stiffness_N_m_per_rad": float(1.0 / coef[1]) if coef[1] != 0 else float("inf")}
                if hyst:
                    res[name]["hysteresis_deg"] = float(np.rad2deg(coef[2]))
            # offset of the deflection in this trajectory relative to the training ones
            res["offset_shift_deg"] = float(np.rad2deg(yv.mean() - y.mean()))
            folds.append(res)
        c = [f["linear+hysteresis"]["compliance_rad_per_N_m"] for f in folds]
        red = [1 - f["linear+hysteresis"]["rmse_deg"] / f["const_rmse_deg"] for f in folds]
        dmin = min(deflection(lg, j).min() for lg in logs.values())
        dmax = max(deflection(lg, j).max() for lg in logs.values())
        out[str(j)] = {"folds": folds, "compliance_mean_rad_per_N_m": float(np.mean(c)),
                       "stiffness_mean_N_m_per_rad": float(1.0 / np.mean(c)),
                       "deflection_range_deg": [float(np.rad2deg(dmin)), float(np.rad2deg(dmax))],
                       "mean_rmse_reduction_vs_constant": float(np.mean(red)),
                       "min_rmse_reduction_vs_constant": float(np.min(red))}
    return out


def diagnose_axes(logs: dict, seed: int = 0, gear=None) -> dict:
    """``diagnose --robot generic`` on every axis of every trajectory (its own held-out split inside
    each trajectory); an effect counts as repeatable when it is found in all trajectories."""
    from drake_est.diagnose import diagnose
    if gear is None:
        gear = next(iter(logs.values())).meta.get("gear_ratios", [1.0] * 6)
    out = {}
    for j in range(1, 7):
        per = {}
        for k, lg in logs.items():
            try:
                d = diagnose(lg, robot="generic", joints=[j], seed=seed, simulate=False,
                             source=f"KUKA {k} axis {j}").to_dict()
                rip = [f["evidence"]["frequency_per_arm_rad"] for f in d["findings"]
                       if f["effect"] == "motor_position_ripple" and "frequency_per_arm_rad" in f["evidence"]]
                per[k] = {"effects": [f["effect"] for f in d["findings"]],
                          "ripple_cycles_per_link_rad": rip,
                          "ripple_cycles_per_motor_rev": [fr * 2 * np.pi / gear[j - 1] for fr in rip],
                          "nominal_heldout_rmse_N_m": d["nominal"]["validation"]["rmse"],
                          "final_heldout_rmse_N_m": d["final"]["validation"]["rmse"],
                          "gain_rmse_ratio": d["final"]["gain"]["rmse_ratio"]}
            except Exception as err:  # noqa: BLE001 - report, never hide, a failure
                per[k] = {"error": f"{err.__class__.__name__}: {err}", "effects": []}
        sets = [set(v["effects"]) for v in per.values()]
        out[str(j)] = {"per_trajectory": per, "found_in_all": sorted(set.intersection(*sets)) if sets else []}
    return out


def ripple_transfer(logs: dict, diag: dict, fg: dict) -> dict:
    """Held-out check of the motor-position ripple that ``diagnose`` found: for each fold, the
    frequency is the mean of those found on the two *training* trajectories; [cos, sin] columns at
    that frequency are added to the axis' best model, fitted on the training trajectories and
    evaluated on the third."""
    out = {}
    for j in range(1, 7):
        per = diag[str(j)]["per_trajectory"]
        m = fg["per_axis"][str(j)]["best_model"]
        folds = []
        for val in logs:
            tr = [k for k in logs if k != val]
            freqs = [f for k in tr for f in per[k].get("ripple_cycles_per_link_rad", [])[:1]]
            if not freqs:
                continue
            f = float(np.mean(freqs))
            fit0 = fit_axis([logs[k] for k in tr], j, m)
            s = fit0["sign_q3"]

            def cols(lg, ripple):
                A = axis_columns(lg, j, m, s)
                if not ripple:
                    return A
                w = 2 * np.pi * f * lg.q[:, j - 1]
                return np.hstack([A, np.column_stack([np.cos(w), np.sin(w)])])

            res = {"validate": val, "frequency_cycles_per_link_rad": f}
            for name, rip in (("without", False), ("with", True)):
                A = np.vstack([cols(logs[k], rip) for k in tr])
                y = np.concatenate([logs[k].tau[:, j - 1] for k in tr])
                coef, *_ = np.linalg.lstsq(A, y, rcond=None)
                res[f"val_rmse_{name}_ripple_N_m"] = rmse(logs[val].tau[:, j - 1], cols(logs[val], rip) @ coef)
                if rip:
                    res["amplitude_N_m"] = float(np.hypot(coef[-2], coef[-1]))
            res["rmse_reduction"] = 1 - res["val_rmse_with_ripple_N_m"] / res["val_rmse_without_ripple_N_m"]
            folds.append(res)
        if folds:
            out[str(j)] = {"model": m, "folds": folds,
                           "mean_rmse_reduction": float(np.mean([f["rmse_reduction"] for f in folds]))}
    return out


def kuka_case_study(data_dir=None, out_dir=None, seed: int = 0, run_diagnose: bool = True) -> dict:
    """The ``real-kuka`` case study; returns the numbers and (with ``out_dir``) writes figures."""
    params = load_kuka_parameters(data_dir)
    logs = {k: load_kuka(k, data_dir, gear_ratios=params["u"]) for k in TRAJECTORIES}
    for k, lg in logs.items():
        if not np.all(np.isfinite(lg.tau)):
            raise DataError(f"KUKA trajectory {k}: non-finite torques")
    out = {"data": {k: {"file": lg.meta["file"], "samples": lg.n_samples, "duration_s": lg.duration,
                        "sample_rate_hz": lg.sample_rate} for k, lg in logs.items()},
           "gear_ratios": params["u"].tolist(),
           "friction_gravity": friction_gravity_study(logs, params),
           "compliance": compliance_study(logs)}
    if run_diagnose:
        out["diagnose"] = diagnose_axes(logs, seed, gear=params["u"])
        out["ripple_transfer"] = ripple_transfer(logs, out["diagnose"], out["friction_gravity"])
    if out_dir is not None:
        out["figures"] = _figures(Path(out_dir), logs, out)
    return out


def _figures(out: Path, logs, res) -> list:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    out.mkdir(parents=True, exist_ok=True)
    files = []
    # deflection vs torque, axes 1-3
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    for ax, j in zip(axes, LINK_ENCODER_AXES):
        for k, lg in logs.items():
            ax.plot(lg.tau[:, j - 1] / 1e3, np.rad2deg(deflection(lg, j)), ".", ms=1, alpha=0.5,
                    label=f"trajectory {k}")
        c = res["compliance"][str(j)]
        ax.set_title(f"axis {j}: k = {c['stiffness_mean_N_m_per_rad'] / 1e6:.2f} MN m/rad")
        ax.set_xlabel("link-side torque [kN m]")
        ax.set_ylabel("motor - link encoder [deg]")
        ax.grid(alpha=0.3)
    axes[0].legend(markerscale=8, fontsize=8)
    fig.suptitle("KUKA KR300: gearbox deflection vs torque (compliance C_j(tau), Eq. (14.3))")
    fig.tight_layout()
    f = out / "kuka_deflection_vs_torque.png"
    fig.savefig(f, dpi=110)
    plt.close(fig)
    files.append(f.name)
    # held-out RMSE per axis and model
    fg = res["friction_gravity"]["per_axis"]
    fig, ax = plt.subplots(figsize=(9, 4))
    models = ["friction", "friction+gravity", "friction+gravity+coupling"]
    w = 0.27
    for i, m in enumerate(models):
        vals = [fg[str(j)][m]["mean_val_rmse_N_m"] if m in fg[str(j)] else np.nan for j in range(1, 7)]
        ax.bar(np.arange(1, 7) + (i - 1) * w, vals, w, label=m)
    ax.set_xlabel("axis")
    ax.set_ylabel("held-out RMSE [N m, link side]")
    ax.set_title("KUKA KR300: fit on two trajectories, validate on the third (mean of 3 folds)")
    ax.set_yscale("log")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    f = out / "kuka_heldout_rmse.png"
    fig.savefig(f, dpi=110)
    plt.close(fig)
    files.append(f.name)
    return files
