"""ODrive cogging case study, the LPV spectral half (thesis Ch. 10 on real data; the diagnosis half is
:mod:`drake_est.cases.cogging`). Data: :mod:`drake_est.datasets.odrive`."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from drake_est.datasets.odrive import load_cogging_map, load_odrive_log


def coulomb_viscous_regressors(v) -> np.ndarray:
    """``[1, sign(v), v]``: current offset, Coulomb and viscous friction columns."""
    v = np.asarray(v, dtype=float)
    return np.column_stack([np.ones_like(v), np.sign(v), v])


def _rms(e) -> float:
    return float(np.sqrt(np.mean(np.square(e))))


def cogging_case_study(data_dir=None, out_dir=None, fit_log: str = "slow2/nocomp_0.npy",
                       val_logs=("slow_goodgains_2/nocomp_0.npy", "slow2_slower/nocomp_0.npy"),
                       comp_logs=("slow2/comp_0.npy", "slow_goodgains_2/comp_0.npy"),
                       map_name: str = "cogging_measure_final_a_4_interp.npy", n_components: int = 6,
                       n_basis: int = 6, f_max_per_rev: float = 100.0) -> dict:
    """LPV spectral analysis of the ODrive cogging logs (thesis Ch. 10 on real data).

    1. ``find_periodic_components`` on the motor current of ``fit_log`` vs motor angle, schedule = velocity,
       Coulomb + viscous + offset removed jointly; frequencies in cycles per revolution (no gear).
    2. Held-out: Coulomb + viscous alone vs Coulomb + viscous + the found harmonics (coefficients fitted on
       ``fit_log``), RMS current error on each of ``val_logs``.
    3. Compensated logs: the velocity ripple at the harmonics found (the anti-cogging feed-forward removes
       it) and the current harmonics (which remain, since the feed-forward current is logged).
    4. The estimated ripple (at the median velocity) against the measured cogging map: correlation, RMS.

    Writes PNGs into ``out_dir`` (if given) and returns the numbers."""
    from drake_est.spectral import find_periodic_components, lssa

    res = {"source": "gchenfc/ODrive analysis/cogging_torque (MIT)", "fit_log": fit_log, "val_logs": list(val_logs),
           "comp_logs": list(comp_logs), "cogging_map": map_name}
    log = load_odrive_log(fit_log, data_dir)
    q, v, cur = log.q[:, 0], log.dq[:, 0], log.tau[:, 0]
    B = coulomb_viscous_regressors(v)
    cv_coef, *_ = np.linalg.lstsq(B, cur, rcond=None)
    res["fit_coulomb_viscous_rms_A"] = _rms(cur - B @ cv_coef)
    pc = find_periodic_components(q, cur, schedule=v, base=B, n_components=n_components, n_basis=n_basis,
                                  f_max=f_max_per_rev / (2 * np.pi))
    per_rev = pc.per_revolution()
    res["harmonics_per_rev"] = per_rev
    res["harmonics_explained_fraction"] = pc.explained_fraction
    res["harmonics_rms_amplitude_A"] = pc.amplitudes
    res["total_explained_fraction_of_cv_residual"] = pc.total_explained_fraction
    expected = np.array([7.0, 14.0, 28.0, 36.0])
    res["expected_per_rev"] = expected
    res["expected_found_within_0.5_per_rev"] = {f"{e:g}": bool(np.any(np.abs(per_rev - e) < 0.5)) for e in expected}

    # ---- held-out: fit Coulomb + viscous (+ harmonics) on the fit log, evaluate on others
    R_fit = np.hstack([B, pc.regressors(q, v)])
    th_full, *_ = np.linalg.lstsq(R_fit, cur, rcond=None)
    res["fit_full_rms_A"] = _rms(cur - R_fit @ th_full)
    held = {}
    for name in val_logs:
        lv = load_odrive_log(name, data_dir)
        qv, vv, cv = lv.q[:, 0], lv.dq[:, 0], lv.tau[:, 0]
        Bv = coulomb_viscous_regressors(vv)
        e_cv = cv - Bv @ cv_coef
        e_full = cv - np.hstack([Bv, pc.regressors(qv, vv)]) @ th_full
        held[name] = {"coulomb_viscous_rms_A": _rms(e_cv), "with_harmonics_rms_A": _rms(e_full),
                      "explained_fraction_of_cv_residual": 1.0 - _rms(e_full) ** 2 / _rms(e_cv) ** 2,
                      "n_samples": int(cv.size)}
    res["held_out"] = held

    # ---- compensated vs uncompensated: velocity ripple and current harmonics at the found frequencies
    freqs = pc.freqs

    def harmonic_content(name):
        lg = load_odrive_log(name, data_dir)
        qq, vv, cc = lg.q[:, 0], lg.dq[:, 0], lg.tau[:, 0]
        vr = vv - np.mean(vv)
        mv = lssa(qq, vr, freqs)
        Bc = coulomb_viscous_regressors(vv)
        cr = cc - Bc @ np.linalg.lstsq(Bc, cc, rcond=None)[0]
        mc = lssa(qq, cr, freqs)
        return {"velocity_std_rad_s": float(np.std(vv)),
                "velocity_ripple_explained_fraction": mv.explained_fraction(),
                "velocity_ripple_amplitudes_rad_s": np.abs(mv.coef[:, 0]),
                "current_harmonics_explained_fraction": mc.explained_fraction(),
                "current_harmonic_amplitudes_A": np.abs(mc.coef[:, 0])}

    res["uncompensated"] = {name: harmonic_content(name) for name in [fit_log, *val_logs]}
    res["compensated"] = {name: harmonic_content(name) for name in comp_logs}
    vr_nc = np.mean([d["velocity_ripple_explained_fraction"] for d in res["uncompensated"].values()])
    vr_c = np.mean([d["velocity_ripple_explained_fraction"] for d in res["compensated"].values()])
    ra_nc = np.mean([np.sqrt(np.sum(d["velocity_ripple_amplitudes_rad_s"] ** 2) / 2)
                     for d in res["uncompensated"].values()])
    ra_c = np.mean([np.sqrt(np.sum(d["velocity_ripple_amplitudes_rad_s"] ** 2) / 2)
                    for d in res["compensated"].values()])
    res["velocity_ripple_summary"] = {"uncompensated_mean_explained_fraction": float(vr_nc),
                                      "compensated_mean_explained_fraction": float(vr_c),
                                      "uncompensated_mean_ripple_rms_rad_s": float(ra_nc),
                                      "compensated_mean_ripple_rms_rad_s": float(ra_c)}

    # ---- estimated ripple vs measured cogging map
    ang, cmap = load_cogging_map(map_name, data_dir)
    v_med = float(np.median(v))
    est = pc.predict(ang, np.full(ang.size, v_med))
    cm = cmap - np.mean(cmap)
    es = est - np.mean(est)
    corr = float(np.corrcoef(es, cm)[0, 1])
    res["map_comparison"] = {"schedule_velocity_rad_s": v_med, "correlation": corr,
                             "rms_difference_A": _rms(es - cm), "map_rms_A": _rms(cm), "estimate_rms_A": _rms(es),
                             "rms_difference_over_map_rms": _rms(es - cm) / _rms(cm)}
    # map spectrum at the same frequencies for reference (map is sampled on a uniform angle grid)
    mm = lssa(ang, cm, freqs)
    res["map_harmonic_amplitudes_A"] = np.abs(mm.coef[:, 0])

    if out_dir is not None:
        _case_figures(Path(out_dir), pc, ang, cm, es, res, log)
        res["figures"] = ["cogging_spectrum.png", "cogging_ripple_vs_map.png", "cogging_amplitude.png",
                          "cogging_velocity_ripple.png"]
    return res


def _case_figures(out: Path, pc, ang, cm, es, res, log):
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from drake_est.spectral.plots import plot_amplitude_functions, plot_scan

    out.mkdir(parents=True, exist_ok=True)
    plot_scan(pc, out / "cogging_spectrum.png", unit_scale=2 * np.pi, unit_label="cycles per motor revolution",
              title="ODrive slow nocomp log: LPV spectrum of the current (Coulomb + viscous removed)")
    labels = [f"{f:.2f} /rev" for f in pc.per_revolution()]
    plot_amplitude_functions(pc.model, log.dq[:, 0], out / "cogging_amplitude.png", labels=labels,
                             v_label="motor velocity [rad/s]", amp_label="current amplitude [A]",
                             title="Cogging harmonics: amplitude vs velocity, 95 % bands")
    fig, ax = plt.subplots(figsize=(9, 4))
    deg = np.degrees(ang)
    ax.plot(deg, cm, lw=0.8, label="measured cogging map (mean removed)")
    ax.plot(deg, es, lw=1.2, label="LPV spectral estimate (harmonics, median velocity)")
    ax.set_xlabel("motor angle [deg]")
    ax.set_ylabel("current [A]")
    ax.set_title(f"Cogging ripple vs map: correlation {res['map_comparison']['correlation']:.2f}")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "cogging_ripple_vs_map.png", dpi=120)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(9, 4))
    f = pc.per_revolution()
    w = 0.35
    nc = np.mean([d["velocity_ripple_amplitudes_rad_s"] for d in res["uncompensated"].values()], axis=0)
    c = np.mean([d["velocity_ripple_amplitudes_rad_s"] for d in res["compensated"].values()], axis=0)
    xs = np.arange(f.size)
    ax.bar(xs - w / 2, nc, w, label="without anti-cogging (nocomp)")
    ax.bar(xs + w / 2, c, w, label="with anti-cogging (comp)")
    ax.set_xticks(xs, [f"{v:.1f}" for v in f])
    ax.set_xlabel("harmonic [cycles per motor revolution]")
    ax.set_ylabel("velocity ripple amplitude [rad/s]")
    ax.set_title("Velocity ripple at the cogging harmonics (mean over logs)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "cogging_velocity_ripple.png", dpi=120)
    plt.close(fig)
