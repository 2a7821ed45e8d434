"""Case studies on real measured data (``../shared/data``, or ``--data DIR``):

* ``real-emps``: EMPS prismatic drive, nominal + position-dependent friction, fit on one recording,
  validate on the other (both directions), ``diagnose --robot generic`` on each;
* ``real-kuka``: KUKA KR300 per-axis friction + gravity (fit on two trajectories, validate on the
  third), gearbox deflection vs torque on axes 1-3, ``diagnose`` on each axis;
* ``real-cogging``: ODrive cogging torque: LPV spectral analysis (:func:`cogging_case_study` of
  :mod:`drake_est.cases.cogging_spectral`) and ``diagnose`` fitted on one log, validated on others.
"""
from __future__ import annotations

from pathlib import Path


def real_emps(out_dir, quick: bool = False, seed: int = 0, data_dir=None, **kw) -> dict:
    """EMPS drive: nominal vs position-dependent friction, cross-validated between recordings."""
    from drake_est.cases.emps import emps_case_study
    res = emps_case_study(data_dir=data_dir, out_dir=Path(out_dir), seed=seed, quick=quick)
    _print_emps(res)
    return res


def _print_emps(res):
    for d in res["directions"]:
        p = d["nominal_params"]
        line = (f"fit {d['train']} -> validate {d['validate']}: M {p['M']:.1f} kg, Fv {p['Fv']:.1f} N s/m, "
                f"Fc {p['Fc']:.2f} N, offset {p['offset']:.2f} N; held-out RMSE {d['val_rmse_nominal_N']:.3f} N "
                f"-> {d['val_rmse_position_friction_N']:.3f} N with position friction "
                f"({100 * d['rmse_reduction']:.1f} % lower)")
        if "rmse_reduction_with_ripple" in d:
            line += (f"; + {d['ripple_period_mm_from_training_diagnosis']:.3f} mm ripple: "
                     f"{d['val_rmse_position_friction_ripple_N']:.3f} N "
                     f"({100 * d['rmse_reduction_with_ripple']:.1f} %)")
        print(line)
    for k, v in res.get("diagnose", {}).items():
        if "error" in v:
            print(f"diagnose {k}: failed: {v['error']}")
            continue
        eff = ", ".join(f["effect"] for f in v["findings"]) or "nothing"
        print(f"diagnose {k}: found {eff}; held-out RMSE {v['nominal_heldout_rmse_N']:.3f} -> "
              f"{v['final_heldout_rmse_N']:.3f} N")


def real_kuka(out_dir, quick: bool = False, seed: int = 0, data_dir=None, **kw) -> dict:
    """KUKA KR300: per-axis friction + gravity (2 trajectories fit, 1 validate), gearbox compliance, diagnose."""
    from drake_est.cases.kuka import kuka_case_study
    res = kuka_case_study(data_dir=data_dir, out_dir=Path(out_dir), seed=seed)
    for j, v in res["friction_gravity"]["per_axis"].items():
        f, g = v["friction"], v["friction+gravity"]
        print(f"axis {j}: held-out RMSE friction {f['mean_val_rmse_N_m']:.1f} N m, +gravity "
              f"{g['mean_val_rmse_N_m']:.1f} N m; best {v['best_model']}; Fv {f['Fv_mean']:.0f} "
              f"(benchmark {v.get('benchmark_Fv', float('nan')):.0f}) N m s/rad, Fc {f['Fc_mean']:.0f} "
              f"(benchmark f_coul+f_a {v.get('benchmark_Fc_plus_Fa', float('nan')):.0f}) N m")
    for j, c in res["compliance"].items():
        print(f"axis {j}: stiffness {c['stiffness_mean_N_m_per_rad'] / 1e6:.2f} MN m/rad, held-out deflection RMSE "
              f"{100 * c['mean_rmse_reduction_vs_constant']:.0f} % below the constant model")
    for j, d in res.get("diagnose", {}).items():
        rip = {k: [round(float(f), 3) for f in v.get("ripple_cycles_per_motor_rev", [])]
               for k, v in d["per_trajectory"].items()}
        line = f"axis {j}: diagnose found in all trajectories: {', '.join(d['found_in_all']) or 'nothing'}"
        if any(rip.values()):
            line += f"; ripple [cycles per motor revolution] {rip}"
        rt = res.get("ripple_transfer", {}).get(j)
        if rt:
            line += f"; ripple held out across trajectories: {100 * rt['mean_rmse_reduction']:.1f} % lower RMSE"
        print(line)
    return res


def real_cogging(out_dir, quick: bool = False, seed: int = 0, data_dir=None, **kw) -> dict:
    """ODrive cogging: LPV spectral harmonics, cross-log validation, diagnose on nocomp/comp logs."""
    from drake_est.cases.cogging import cogging_diagnosis_study
    from drake_est.cases.cogging_spectral import cogging_case_study
    out = Path(out_dir)
    spec = cogging_case_study(data_dir=data_dir, out_dir=out)
    diag = cogging_diagnosis_study(data_dir=data_dir, out_dir=out, seed=seed, quick=quick)
    print("harmonics (cycles/rev): " + ", ".join(f"{f:.2f}" for f in spec["harmonics_per_rev"])
          + f"; explain {100 * spec['total_explained_fraction_of_cv_residual']:.1f} % of the Coulomb+viscous residual")
    for n, h in spec["held_out"].items():
        print(f"LPV harmonics, held-out {n}: {h['coulomb_viscous_rms_A']:.3f} -> {h['with_harmonics_rms_A']:.3f} A")
    for n, h in diag["held_out"].items():
        print(f"fit {diag['train']} -> {n}: nominal {h['nominal_rmse_A']:.3f} A, periodic kernels "
              f"{h['periodic_position_rmse_A']:.3f} A ({100 * h['reduction_periodic_position']:.0f} % lower), "
              f"diagnosed extensions {h['diagnosed_rmse_A']:.3f} A ({100 * h['reduction_diagnosed']:.0f} %)")
    ml = diag.get("multilog")
    if ml:
        print(f"diagnose {len(ml['logs'])} logs at once (whole logs held out): {', '.join(ml['effects'])}; ripple at "
              + ", ".join(f"{f:.1f}" for f in ml["ripple_per_rev"]) + f" per rev; held-out RMSE "
              f"{ml['nominal_heldout_rmse_A']:.3f} -> {ml['final_heldout_rmse_A']:.3f} A "
              f"({100 * ml['heldout_rmse_reduction']:.0f} % lower)")
    vr = spec["velocity_ripple_summary"]
    print(f"velocity ripple at the harmonics: nocomp {vr['uncompensated_mean_ripple_rms_rad_s']:.3f} rad/s, "
          f"comp {vr['compensated_mean_ripple_rms_rad_s']:.3f} rad/s")
    return {"spectral": spec, "diagnosis": diag}


EXPERIMENTS = {"real-emps": real_emps, "real-kuka": real_kuka, "real-cogging": real_cogging}
