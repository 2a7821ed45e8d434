"""The diagnosis report: ``report.json`` (fixed keys), ``report.md`` and the PNG plots it links."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from drake_est.data import torque_unit
from drake_est.diagnose.competition import ambiguous_rivals
from drake_est.diagnose.nominal import BEYOND_POSITIONS_MARGIN, EXTRAPOLATION_FACTOR, OUTLIER_MAX_SHARE, n_blocks_for
from drake_est.diagnose.multilog import across_logs_evidence, per_log_table

EFFECT_TEXT = {
    "position_dependent_friction": "friction that depends on the arm position (Eq. 9.16): a basis-function expansion in "
                                   "arm angle times sign(velocity)",
    "motor_position_ripple": "a torque ripple periodic in the motor angle whose amplitude depends on the velocity "
                             "(LPV spectral method, Ch. 10)",
    "energy_dependent_friction": "a slow drift of the Coulomb level driven by the dissipated friction power "
                                 "(Eqs. 9.21-9.24, Algorithm 6)",
    "asymmetric_coulomb": "a Coulomb level that depends on the direction of motion (Eq. 9.3)",
    "gear_coupling": "friction of coupled wrist motors: the velocities of the coupled joints enter the torque "
                     "(Eq. 9.12)",
    "payload": "an unmodeled mass at the flange (gravity and inertia regressors from Drake)",
    "abrupt_change": "friction parameters that change at an instant (piecewise-constant parameters, Ch. 7)",
    "stribeck": "friction that rises towards standstill beyond Coulomb + viscous: kc + ks exp(-|qd/vs|^delta) "
                "(Stribeck effect, Sec. 9.1)",
    "time_periodic_disturbance": "a torque periodic in time whose frequency in Hz does not scale with the speed "
                                 "(a pump, a fan, a neighbouring machine), not a position ripple",
    "position_dependent_load": "a direction-independent torque that depends on position (gravity, springs, "
                               "cables), which the generic axis model lacks",
}


def _r(x, nd=6):
    if isinstance(x, dict):
        return {str(k): _r(v, nd) for k, v in x.items() if not str(k).startswith("_")}
    if isinstance(x, (list, tuple)):
        return [_r(v, nd) for v in x]
    if isinstance(x, (np.floating, float)):
        x = float(x)
        return x if not np.isfinite(x) else float(f"{x:.{nd}g}")
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.ndarray):
        return _r(x.tolist(), nd)
    if isinstance(x, (np.bool_,)):
        return bool(x)
    return x


def effect_parameters(result, ext, model, fit) -> dict:
    """Physical parameters of one accepted extension from the fit where it was accepted."""
    prep = result.prep
    if ext.effect == "payload":
        from drake_est.diagnose.simulate import _payload_of
        pl = _payload_of(result, fit)
        coef = fit.shared["payload"]
        d = {"coefficients_kg": coef, "com_candidates_m": ext.spec["coms_m"]}
        if pl is not None:
            d["mass_kg"] = pl[0]
            d["com_in_flange_m"] = pl[1]
        return d
    sl = model.coef_slices(fit, ext.joint)
    kv, kc = sl["nominal"]["kv"], sl["nominal"]["kc"]
    c = sl[ext.effect]
    d = {}
    if ext.effect == "asymmetric_coulomb":
        d = {"kc_pos": kc, "kc_neg": kc - c[0], "kv": kv}
    elif ext.effect == "position_dependent_friction":
        jd = prep.joints[ext.joint]
        qq = np.linspace(*ext.evidence["range_rad"], 200)
        from drake_est.diagnose.detectors import gaussian_features
        level = gaussian_features(qq, np.asarray(ext.spec["centers"]), ext.spec["width"]) @ c
        d = {"n_kernels": ext.evidence["n_kernels"], "kernel_width_rad": ext.spec["width"],
             "centers_rad": ext.spec["centers"], "weights_nm": c,
             "coulomb_level_range_nm": [kc + float(level.min()), kc + float(level.max())],
             "position_of_max_deviation_rad": float(qq[int(np.argmax(np.abs(level)))])}
        _ = jd
    elif ext.effect == "motor_position_ripple":
        d = {k: ext.evidence[k] for k in ("frequency_per_arm_rad", "frequency_per_arm_rev", "frequencies_per_arm_rad",
                                          "rms_amplitude", "amplitude_slope_vs_speed") if k in ext.evidence}
        if "frequency_per_motor_rev" in ext.evidence:
            d["frequency_per_motor_rev"] = ext.evidence["frequency_per_motor_rev"]
        d["n_coefficients"] = int(c.size)
    elif ext.effect == "energy_dependent_friction":
        d = {"time_constant_s": ext.spec["tau_e"], "gain_k_e": float(c[0]), "kc": kc, "kv": kv}
        if c.size > 1:    # (9.29): the viscous level drifts with E as well
            d["gain_k_e_viscous"] = float(c[1])
    elif ext.effect == "abrupt_change":
        d = {"t_change_s": ext.spec["t_change"], "kv_before": kv, "kc_before": kc, "kv_after": kv + c[0],
             "kc_after": kc + c[1]}
    elif ext.effect == "stribeck":
        # ks: the excess at standstill; vs: the speed where it has fallen to ks / e (the law's vs, or of the basis)
        from drake_est.diagnose.detectors import stribeck_ks_vs
        ks, vs = stribeck_ks_vs(ext.spec, c)
        d = {"kc": kc, "ks": ks, "vs": vs, "delta": ext.spec.get("delta"), "kv": kv}
        if ext.spec.get("basis_speeds"):
            d.update({"shape": "basis expansion in |qd|", "basis_speeds": list(ext.spec["basis_speeds"]),
                      "basis_kernel": ext.spec.get("basis_kernel", "exp"),
                      "basis_coefficients": [float(x) for x in c]})
    elif ext.effect == "time_periodic_disturbance":
        fr = list(ext.spec["frequencies_hz"])
        n = len(fr)       # columns [cos f1..fn, sin f1..fn] (extensions.columns_at)
        d = {"frequency_hz": fr[0], "amplitude": float(np.hypot(c[0], c[n]))}
        if n > 1:
            d["harmonics"] = [{"frequency_hz": fr[i], "amplitude": float(np.hypot(c[i], c[n + i]))} for i in range(1, n)]
    elif ext.effect == "position_dependent_load":
        from drake_est.diagnose.detectors import gaussian_features
        qq = np.linspace(*ext.evidence["range_rad"], 200)
        G = gaussian_features(qq, np.asarray(ext.spec["centers"]), ext.spec["width"])
        if ext.spec.get("gravity_harmonic"):      # [sin q, cos q] first (detectors.position_load)
            G = np.hstack([np.column_stack([np.sin(qq), np.cos(qq)]), G])
        load = G @ c
        d = {"n_kernels": ext.evidence["n_kernels"], "kernel_width_rad": ext.spec["width"],
             "load_range_nm": [float(load.min()), float(load.max())]}
    elif ext.effect == "gear_coupling":
        for k, i in enumerate(ext.spec["coupled_joints"]):
            d[f"joint{i}"] = {"kv": c[2 * k], "kc": c[2 * k + 1]}
    return d


@dataclass
class DiagnosisReport:
    """What :func:`drake_est.diagnose.diagnose` returns: the numbers (``to_dict()`` is report.json),
    the fitted models, and ``write(out_dir)`` for report.json, report.md and the plots."""

    result: object
    source: str = "<log>"
    robot: str = "generic"
    simulation: dict = None
    files: list = field(default_factory=list)

    # ----------------------------------------------------------------- accessors
    @property
    def findings(self) -> list:
        return self.to_dict()["findings"]

    @property
    def effects(self) -> list:
        return [s.ext.effect for s in self.result.steps]

    @property
    def top(self):
        f = self.findings
        return f[0] if f else None

    def to_dict(self) -> dict:
        res = self.result
        prep = res.prep
        log = prep.log
        data = {"file": self.source, "samples": int(log.n_samples), "joints": [int(j) for j in prep.joints],
                "duration_s": float(log.duration), "sample_rate_hz": float(log.sample_rate), "robot": self.robot,
                "skipped_joints": {str(j): r for j, r in prep.skipped.items()},
                "excluded": {str(j): {k: v for k, v in jd.counts.items()
                                     if k not in ("thresholds", "inertia", "inertia_before_backfit",
                                                  "inertia_backfit_withheld")}
                             for j, jd in prep.joints.items()},
                "selection": {str(j): jd.counts["thresholds"] for j, jd in prep.joints.items()},
                "split": (f"whole logs ({int(log.meta.get('n_logs', 0))}): odd-numbered logs (1, 3, ...) train, even-numbered "
                          "ones validate; per-log Coulomb/viscous offsets" if "log_index" in (log.channels or {}) else
                          f"alternating time blocks ({n_blocks_for(log.duration)}): even blocks train, odd blocks validate"),
                "validation_samples": {str(j): int(jd.val.sum()) for j, jd in prep.joints.items()},
                "torque_unit": torque_unit(log)}
        if prep.meta.get("joints_held_at_zero"):
            data["robot_joints_not_in_log_held_at_zero"] = prep.meta["joints_held_at_zero"]
        from drake_est.diagnose.core import Model
        nom_params = {}
        for j, jd in prep.joints.items():
            p = Model(prep).coef_slices(res.nominal_fit, j)["nominal"]
            if "inertia" in jd.counts:
                p["J"] = jd.counts["inertia"]
            if "inertia_before_backfit" in jd.counts:
                # J identified before the findings (prepare) and moved by backfit_inertia: closed-loop bias
                p["J_before_backfit"] = jd.counts["inertia_before_backfit"]
            if "inertia_backfit_withheld" in jd.counts:
                # a large move that the fit beside a free friction curve of the speed contradicts (kept at J)
                p["J_backfit_withheld"] = jd.counts["inertia_backfit_withheld"]
            nom_params[str(j)] = p
        nominal = {"validation": res.nominal_validation,
                   "per_joint": {str(j): m for j, m in res.nominal_validation_joint.items()},
                   "parameters": nom_params,
                   "model": "rigid body (Drake MultibodyPlant inverse dynamics) + Coulomb/viscous (9.2)"
                   if prep.robot is not None else "J qdd + Coulomb/viscous (9.2) per axis"}
        findings = []
        prev = {}
        for k, s in enumerate(res.steps):
            from drake_est.diagnose.core import Model as M
            model_k = M(prep, [st.ext for st in res.steps[:k + 1]])
            js = list(s.ext.cols)
            nom_rmse = float(np.sqrt(sum(res.nominal_validation_joint[j]["rmse"] ** 2 * prep.joints[j].val.sum()
                                         for j in js) / sum(prep.joints[j].val.sum() for j in js)))
            ev = {"test": "F-test on held-out residual", "p_value": s.test["p_value"], "F": s.test["F"],
                  "dof": s.test["dof"], "heldout_rmse_reduction": s.test["rmse_reduction"]}
            ev.update({k2: v for k2, v in s.ext.evidence.items() if k2 != "segment_params_train"})
            if "state_law_test" in s.test:
                # a disturbance at a line of the motion: its test given a free function of the state, and its
                # held-out gains from one half of the log to the other
                ev["given_state_function"] = s.test["state_law_test"]
                if "half_gains" in s.test:
                    ev["gains_across_halves"] = s.test["half_gains"]
            if "significant_beside" in s.test:
                # held back alone by the paired block test, let through with a second law of its joint
                # (core.pair_rescue): both tests given each other, and the paired test of the pair
                b = s.test["significant_beside"]
                ev["entered_with"] = {
                    "partner": b["partner"], "paired_p_value_alone": s.test.get("paired_p_value"),
                    "paired_p_value_of_both": b["paired_p_value_of_both"], "groups": b["groups"],
                    "groups_both_better": b["groups_both_better"],
                    **{f"{key}_{k2}": b[key][k2] for key in ("test_given_partner", "partner_test_given_this")
                       for k2 in ("p_value", "rmse_reduction", "paired_p_value") if k2 in b[key]}}
            f = {"effect": s.ext.effect, "joint": int(s.ext.joint), "score": s.test["score"], "evidence": ev,
                 "parameters": effect_parameters(res, s.ext, model_k, s.fit),
                 "validation": s.validation,
                 "competition": s.competition,
                 "status": "ambiguous" if s.competition.get("ambiguous") else "named",
                 "gain": {"rmse_ratio": nom_rmse / s.validation["rmse"],
                          "rmse_ratio_vs_previous_step": (prev.get(tuple(js), nom_rmse)) / s.validation["rmse"]}}
            if s.competition.get("ambiguous"):
                f["ambiguous_between"] = [s.ext.effect] + ambiguous_rivals(s.competition)
            if s.ext.shared:
                f["joints"] = [int(j) for j in js]
            across = across_logs_evidence(prep, s.ext)
            if across is not None:
                f["across_logs"] = across
            prev[tuple(js)] = s.validation["rmse"]
            findings.append(f)
        final = {"effects": self.effects, "validation": res.final_fit and _final_val(res),
                 "per_joint": {str(j): v for j, v in _final_joint(res).items()},
                 "gain": {"rmse_ratio": res.nominal_validation["rmse"] / _final_val(res)["rmse"]},
                 "n_params": int(res.final_fit.n_params),
                 "noise_estimate_nm": {str(j): float(np.sqrt(res.final_fit.rss_val[j] / prep.joints[j].val.sum()))
                                       for j in prep.joints}}
        from drake_est.diagnose.unexplained import next_experiments
        out = {"data": data, "nominal": nominal, "findings": findings, "final": final,
               "unexplained": res.unexplained,
               "next_experiment": next_experiments(prep, res.steps, float(log.duration), res.rejected),
               "not_found": sorted([{k: v for k, v in r.items()} for r in res.rejected],
                                   key=lambda r: -r["score"])[:8],
               "logs": per_log_table(prep, res),
               # findings of an earlier pass that were no longer the best explanation given the others
               # (core.finding_to_set_aside); the search was run again without them
               "set_aside": list(prep.meta.get("set_aside", [])),
               "settings": {"alpha": res.timing.get("alpha"), "min_rmse_reduction": res.timing.get("min_gain")},
               "timing_s": {k: v for k, v in res.timing.items() if k.endswith("_s")}}
        if self.simulation is not None:
            out["simulation"] = {k: v for k, v in self.simulation.items() if not k.startswith("_")}
        if self.files:
            out["files"] = list(self.files)
        return _r(out)

    # ----------------------------------------------------------------- writing
    def write(self, out_dir) -> Path:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        from drake_est.diagnose.plots import write_plots
        self.files = write_plots(self, out)
        d = self.to_dict()
        from drake_est.jsonutil import dump_json, nonfinite_to_null

        d, undefined = nonfinite_to_null(d)   # strict JSON: undefined numbers are null, and listed
        if undefined:
            d["undefined_numbers"] = undefined
        dump_json(d, out / "report.json")
        (out / "report.md").write_text(markdown(d))
        return out

    def summary(self) -> str:
        d = self.to_dict()
        u = d["data"].get("torque_unit", "N m")
        lines = [f"{d['data']['file']}: {d['data']['samples']} samples, {d['data']['duration_s']:.0f} s, "
                 f"joints {d['data']['joints']} ({d['data']['robot']})"]
        for j, r in d["data"]["skipped_joints"].items():
            lines.append(f"  joint {j} skipped: {r}")
        nv = d["nominal"]["validation"]
        lines.append(f"nominal model: held-out RMSE {_num(nv['rmse'], '.4g')} {u}, Fit {_num(nv['fit'], '.1f')} %")
        aside = d.get("set_aside") or []
        if not d["findings"]:
            lines.append(("no finding: no extension passed the test" if not aside else
                          f"no finding: {len(aside)} set aside after the search (below)") + (
                "" if d.get("unexplained") else "; the nominal model explains the held-out data"))
        for f in d["findings"]:
            ev = f["evidence"]
            extra = ""
            if "frequency_per_arm_rad" in ev:
                extra = f", {ev['frequency_per_arm_rad']:.4g} cycles/rad"
            if "t_change_s" in ev:
                extra = f", at t = {ev['t_change_s']:.4g} s"
            if "frequency_hz" in ev:
                extra = f", {ev['frequency_hz']:.4g} Hz"
            if "stribeck_velocity" in ev:
                extra = f", vs = {ev['stribeck_velocity']:.3g}"
            elif f["effect"] == "stribeck" and (f.get("parameters") or {}).get("vs") is not None:
                extra = f", vs = {f['parameters']['vs']:.3g} (basis expansion in |qd|)"
            if f.get("ambiguous_between"):
                extra += f"; AMBIGUOUS between {' and '.join(f['ambiguous_between'])}"
            if "time_constant_s" in ev:
                extra = f", tau_e = {ev['time_constant_s']:.4g} s"
            lines.append(f"FOUND {f['effect']} (joint {f['joint']}{extra}): p = {ev['p_value']:.2g}, held-out RMSE "
                         f"{f['validation']['rmse']:.4g} {u}, gain x{f['gain']['rmse_ratio']:.3g}")
        for lg in d.get("logs", []):
            lines.append(f"  log {lg['log']} ({lg['role']}, joint {lg['joint']}) {lg['file']}: RMSE {lg['nominal_rmse']:.4g} -> "
                         f"{lg['final_rmse']:.4g} {u} ({100 * lg['rmse_reduction']:.0f} % lower)")
        for x in aside:
            # the reason's first clause (the whole reason is in report.md)
            why = str(x.get("reason", "")).split(": ")[0]
            why = why if len(why) <= 160 else why[:157] + "..."
            where = f" (joint {x['joint']})" if x.get("joint") is not None else ""
            lines.append(f"SET ASIDE {x['effect']}{where}: {why}; not named (report.md, Findings set aside)")
        fv = d["final"]["validation"]
        named = ", ".join(f"{f['effect']} (joint {f['joint']})" for f in d["findings"]) or "(nominal)"
        lines.append(f"final model {named}: held-out RMSE {fv['rmse']:.4g} {u}, "
                     f"Fit {fv['fit']:.1f} %, gain x{d['final']['gain']['rmse_ratio']:.3g}")
        # what the final model leaves: structure no vocabulary entry explains (no cause named), and the experiments
        # that would decide what this log cannot
        for x in d.get("unexplained", []):
            lines.append(f"UNEXPLAINED joint {x['joint']}: structure in {x['variable']} "
                         f"({100 * x['share_of_residual_variance']:.1f} % of the residual variance, "
                         f"p = {x['p_value']:.2g}); no cause named")
        if d.get("next_experiment"):
            n = len(d["next_experiment"])
            lines.append(f"next experiment: {n} suggestion{'s' if n > 1 else ''} in report.md (## Next experiment)")
        return "\n".join(lines)


def _final_val(res):
    from drake_est.diagnose.core import _val_metrics
    return _val_metrics(res.prep, res.final_fit)


def _final_joint(res):
    from drake_est.diagnose.core import _val_metrics
    return {j: _val_metrics(res.prep, res.final_fit, [j]) for j in res.prep.joints}


def _fmt(x):
    if isinstance(x, float):
        return f"{x:.4g}"
    return str(x)


def _inertia_backfit_lines(p: dict) -> list:
    """Sentences on the inertia backfit of a generic axis (core.backfit_inertia) for report.md, from the nominal
    parameters of one joint: J moved once the findings were in the model, or a move withheld (a large one the speed
    curve contradicts, core.inertia_move_contradicted; one through zero, core.inertia_move_through_zero)."""
    out = []
    if "J_before_backfit" in p:
        out.append(f"J was identified as {_fmt(float(p['J_before_backfit']))} before the findings and re-estimated "
                   f"beside them as {_fmt(float(p['J']))} (an unmodeled torque biases the first fit of "
                   "closed-loop data)")
    w = p.get("J_backfit_withheld")
    if not isinstance(w, dict):
        return out
    kept = f"J kept at {_fmt(float(p['J']))}: re-estimating it beside the findings gave {_fmt(float(w['J_moved']))}"
    if w.get("reason") == "nonpositive":
        out.append(f"{kept} +- {_fmt(float(w['standard_error']))}, not a positive inertia (the "
                   "acceleration column then fits something else, e.g. a friction law that falls steeply with the "
                   "speed, seen through a speed estimate that lags at a low sample rate)")
    else:
        out.append(f"{kept}, but the same fit with a free friction curve of the speed gives "
                   f"{_fmt(float(w['J_speed_curve']))} +- {_fmt(float(w['standard_error']))}, which contradicts "
                   "the move (a friction law of the speed that no finding holds is then taken for inertia)")
    return out


def _num(x, spec):
    """A number of the report as text; None (undefined, written as null) as 'undefined'."""
    return "undefined" if x is None else format(x, spec)


def markdown(d: dict) -> str:
    """Human-readable account of a report dict."""
    L = ["# Model-discrepancy diagnosis", ""]
    da = d["data"]
    u = da.get("torque_unit", "N m")
    L.append(f"Log `{da['file']}`: {da['samples']} samples, {da['duration_s']:.1f} s at {da['sample_rate_hz']:.4g} Hz; "
             f"diagnosed joints {da['joints']} with the `{da['robot']}` model.")
    for j, r in da["skipped_joints"].items():
        L.append(f"- joint {j} skipped: {r}")
    for j, c in da["excluded"].items():
        L.append(f"- joint {j}: {c.get('selected', 0)} samples selected by (9.9); excluded {c.get('near_zero_velocity', 0)} "
                 f"near zero velocity, {c.get('accelerating', 0)} accelerating, {c.get('outliers', 0)} outliers (> 6 MAD)"
                 + (f", {c['thinned']} thinned" if c.get("thinned") else "")
                 + (f", {c['beyond_training_speeds']} held-out samples faster than {EXTRAPOLATION_FACTOR:g} times the "
                    "fastest training sample (not judged: the training samples see one speed level, and every model "
                    "extrapolates there)"
                    if c.get("beyond_training_speeds") else "")
                 + (f", {c['beyond_training_positions']} held-out samples beyond the training positions by more than "
                    f"{BEYOND_POSITIONS_MARGIN:.3g} of their span (not judged: no law of the position is fitted there)"
                    if c.get("beyond_training_positions") else "")
                 + "".join(f" (the {when} screen was not applied: it flagged {c[key]} samples, more than "
                           f"{100 * OUTLIER_MAX_SHARE:g} % of the rows, so the tails are misfit, not outliers)"
                           for when, key in (("nominal", "outlier_screen_skipped"),
                                             ("final", "outlier_screen_after_extension_skipped")) if c.get(key)))
    L += ["", f"Validation: {da['split']}.", "", "## What the simulation gets wrong", ""]
    nv = d["nominal"]["validation"]
    L.append(f"The nominal model ({d['nominal']['model']}) leaves a held-out RMSE of **{_num(nv['rmse'], '.4g')} {u}** "
             f"(MAE {nv['mae']:.4g}, Fit {_num(nv['fit'], '.1f')} %, FPE {nv['fpe']:.4g}).")
    for j, p in d["nominal"]["parameters"].items():
        L.append(f"- joint {j}: " + ", ".join(f"{k} = {_fmt(v)}" for k, v in p.items()
                                               if k not in ("J_before_backfit", "J_backfit_withheld")))
        L += [f"  - {s}" for s in _inertia_backfit_lines(p)]
    files = d.get("files", [])
    for f in files:
        if f.startswith("residual"):
            L.append(f"\n![{f}]({f})")
    L += ["", "## Causes found", ""]
    if not d["findings"]:
        L.append("No extension improved the held-out error significantly: the nominal model explains the data to "
                 "the noise level.")
    for k, f in enumerate(d["findings"], 1):
        ev = f["evidence"]
        L.append(f"### {k}. `{f['effect']}` on joint {f['joint']}")
        L.append(f"Cause: {EFFECT_TEXT.get(f['effect'], f['effect'])}.")
        L.append(f"Evidence: {ev['test']}, F = {ev['F']:.4g} with {ev['dof']} degrees of freedom, p = {ev['p_value']:.3g}; "
                 f"held-out RMSE reduced by {100 * ev['heldout_rmse_reduction']:.1f} % (score {f['score']:.4g}).")
        if ev.get("at_motion_line_hz") is not None and ev.get("given_state_function"):
            g = ev["given_state_function"]
            L.append(f"At a line of the motion ({ev['at_motion_line_hz']:.4g} Hz), where any misfit of position, speed "
                     "and acceleration repeats too: given a free function of them (and of the reversals) it still "
                     f"lowers the held-out RMSE by {100 * g['rmse_reduction']:.1f} % (p = {g['p_value']:.3g})"
                     + (", and fitted on either half of the log it lowers that of the other half by "
                        + " and ".join(f"{100 * x:.1f} %" for x in ev["gains_across_halves"])
                        if ev.get("gains_across_halves") else "") + ".")
        if ev.get("entered_with"):
            w = ev["entered_with"]
            alone = w.get("paired_p_value_alone")
            L.append(f"Entered together with `{w['partner']}` on the same joint: alone, its held-out gain did not hold "
                     "across the held-out blocks" + (f" (paired p = {alone:.2g})" if alone is not None else "")
                     + f"; the two together predict {w['groups_both_better']} of {w['groups']} block groups better "
                     f"(paired p = {w['paired_p_value_of_both']:.2g}), and given `{w['partner']}` it lowers the "
                     f"held-out RMSE by {100 * w['test_given_partner_rmse_reduction']:.1f} % (paired p = "
                     f"{w['test_given_partner_paired_p_value']:.2g}).")
        c = f.get("competition") or {}
        if c.get("runner_up"):
            m = c.get("margin")
            how = (f"beaten by {m:.4g} in held-out score" if m is not None and m >= 0 else
                   "not tested" if m is None else f"ahead by {-m:.4g} in held-out score")
            L.append(f"Competing explanation: runner-up `{c['runner_up']}` (joint {c['runner_up_joint']}), {how}"
                     + (" -- **ambiguous between "
                     + " and ".join(f"`{a}`" for a in (f.get("ambiguous_between") or [f["effect"], c["runner_up"]]))
                     + "**: the evidence does not separate them." if c.get("ambiguous") else "."))
            if c.get("reason"):
                L.append(f"Why ambiguous: {c['reason']}.")
            for a in c.get("explained_by_periodic_residual", []):
                if a.get("explained_by") == "dither":
                    L.append(f"Set aside: `{a['effect']}` (joint {a['joint']}) only absorbed the time-periodic "
                             "disturbance's dither of the Coulomb friction (partial held-out F-test given "
                             f"(2/pi) arcsin(qd/A) - sign(qd): p = {a['p_value']:.3g}).")
                    continue
                if a.get("explained_by") == "uneven_residual":
                    L.append(f"Set aside: `{a['effect']}` (joint {a['joint']}) won only through the time windows "
                             "with bursts of misfit (held-out F-test weighted by each window's residual level: "
                             f"p = {a['p_value']:.3g}, RMSE reduction {100 * a['rmse_reduction']:.2g} %).")
                    continue
                if a.get("explained_by") == "one_speed_change":
                    L.append(f"Set aside: `{a['effect']}` (joint {a['joint']}) holds only where the joint speeds up out "
                             "of a standstill or a reversal: a transient there (breakaway, presliding), not a law of "
                             "the sliding speed (its curve on the samples slowing down, with a scale of its own: "
                             f"scale {a.get('scale', float('nan')):.3g}, held-out F-test p = {a['p_value']:.3g}).")
                    continue
                if a.get("explained_by") == "speed_law":
                    L.append(f"Set aside: `{a['effect']}` (joint {a['joint']}) only absorbed a misfit of the friction "
                             f"curve (partial held-out F-test given a free friction curve of each direction: "
                             f"p = {a['p_value']:.3g}).")
                    continue
                L.append(f"Set aside: `{a['effect']}` (joint {a['joint']}) only absorbed the periodic residual (partial "
                         f"held-out F-test given the periodic structure: p = {a['p_value']:.3g}).")
        if f.get("across_logs"):
            a = f["across_logs"]
            L.append(f"Across logs: speed-level ratio {a['speed_level_ratio_all_logs']:.3g} over all logs, at most "
                     f"{max(a['speed_level_ratio_per_log'] or [1.0]):.3g} within one log; identifiable in a single log: "
                     f"{a['identifiable_in_a_single_log']}, across the logs: {a['identifiable_across_logs']}.")
        L.append("Parameters: " + ", ".join(f"{a} = {_fmt(b)}" for a, b in f["parameters"].items()
                                            if not isinstance(b, list) or len(b) <= 4))
        v = f["validation"]
        L.append(f"Held-out after this step: RMSE {v['rmse']:.4g} {u}, MAE {v['mae']:.4g}, Fit {v['fit']:.1f} %, "
                 f"FPE {v['fpe']:.4g}; gain x{f['gain']['rmse_ratio']:.3g} over the nominal model.")
        L.append("")
    fv = d["final"]["validation"]
    L += ["## The extended model", "",
          f"Effects: {', '.join(d['final']['effects']) or 'none (nominal)'}; held-out RMSE **{fv['rmse']:.4g} {u}** "
          f"(nominal {_num(nv['rmse'], '.4g')}), gain x{d['final']['gain']['rmse_ratio']:.3g}."]
    if d.get("logs"):
        held = [str(lg["log"]) for lg in d["logs"] if lg["role"] == "validate"]
        L += ["", "## Logs", "", f"Held out (not used for fitting): log {', '.join(dict.fromkeys(held))}; their RMSE is "
              "held-out RMSE. Offsets: each log's own viscous/Coulomb offsets [dkv, dkc] on top of the common friction.",
              "", "| log | file | role | joint | samples | nominal RMSE | final RMSE | reduction | offsets [dkv, dkc] |",
              "|---|---|---|---|---|---|---|---|---|"]
        for lg in d["logs"]:
            o = lg.get("offsets_dkv_dkc")
            off = "-" if not o else f"[{_num(o[0], '.3g')}, {_num(o[1], '.3g')}]"
            L.append(f"| {lg['log']} | {lg['file']} | {lg['role']} | {lg['joint']} | {lg['samples']} | "
                     f"{_num(lg['nominal_rmse'], '.4g')} | {_num(lg['final_rmse'], '.4g')} | "
                     f"{_num(100 * lg['rmse_reduction'] if lg['rmse_reduction'] is not None else None, '.1f')} % | {off} |")
    L += ["", "## Unexplained", ""]
    if not d.get("unexplained"):
        L.append("The final held-out residual shows no remaining structure (dependence on position, velocity, "
                 "acceleration, time, or correlation in time) at the fixed false-alarm rate.")
    for u in d.get("unexplained", []):
        L.append(f"- joint {u['joint']}: structure in **{u['variable']}** ({u['test']}, p = {u['p_value']:.3g}), "
                 f"{100 * u['share_of_residual_variance']:.1f} % of the residual variance; no cause named.")
    if "unexplained.png" in files:
        L.append("\n![unexplained](unexplained.png)")
    if d.get("next_experiment"):
        L += ["", "## Next experiment", ""]
        for e in d["next_experiment"]:
            L.append(f"- {e['reason']}: {e['experiment']}")
        if "next_experiment.png" in files:
            L.append("\n![where the held-out gains lie](next_experiment.png)")
    if "simulation" in d:
        s = d["simulation"]
        L += ["", "## Simulation error (Sec. 3.1)", "",
              f"{s['method']}; {s['n_windows']} windows of {s['window_s']} s from the measured state, driven by the "
              f"measured torque. Velocity RMS error [rad/s]:"]
        for j in s.get("joints", []):
            a = s.get("velocity_rmse_nominal", {}).get(str(j))
            b = s.get("velocity_rmse_extended", {}).get(str(j))
            if a is not None:
                L.append(f"- joint {j}: nominal {a:.4g}, extended {b:.4g}")
        if "simulation.png" in files:
            L.append("\n![simulation](simulation.png)")
    if d.get("set_aside"):
        L += ["", "## Findings set aside"]
        groups = (("Each finding is checked against the others (and a disturbance in time, or a friction law in time "
                   "beside a law of the state, against a function of its joint's state; a position friction or a "
                   "friction law in time beside Stribeck against a free friction curve of the speed): these were "
                   "explained by them or not separated from a simpler rival.",
                   [r for r in d["set_aside"] if not r.get("not_confirmed") and not r.get("gain_in_few_samples")
                    and not r.get("within_rounding")]),
                  ("Small findings are not confirmed while the final residual still holds structure:",
                   [r for r in d["set_aside"] if r.get("not_confirmed")]),
                  ("A later finding, or the only finding of a joint whose final residual still holds structure, "
                   "whose held-out gain sits in a few large errors must also lower the absolute errors "
                   "(heavy-tailed noise):",
                   [r for r in d["set_aside"] if r.get("gain_in_few_samples")]),
                  ("A finding on a joint whose torque a coarse ADC rounds must also show on the likelihood of the "
                   "quantized readings (each one within half a step of the torque):",
                   [r for r in d["set_aside"] if r.get("within_rounding")]))
        for intro, rows in groups:
            if rows:
                L += ["", intro, ""]
                for r in rows:
                    where = f" (joint {r['joint']})" if r.get("joint") is not None else ""
                    L.append(f"- {r['effect']}{where}: {r['reason']}; the search was run again without it")
    if d.get("not_found"):
        L += ["", "## Candidates rejected in the last round", ""]
        alpha, min_gain = (d.get("settings") or {}).get("alpha"), (d.get("settings") or {}).get("min_rmse_reduction")
        for r in d["not_found"][:6]:
            why = rejection_reason(r, alpha, min_gain)
            L.append(f"- {r['effect']} (joint {r['joint']}): held-out RMSE reduction {100 * r['rmse_reduction']:.2f} %, "
                     f"p = {r['p_value']:.3g}" + (f" -- {why}" if why else ""))
    return "\n".join(L) + "\n"


#: why a candidate of the last round was not accepted, by the flag its test carries (the first that applies)
REJECTION_REASONS = (
    ("negative_friction", "it would leave a friction below zero at some speed"),
    ("rescue_explained_by_filter_slope", "its change of the prediction stays within the torque ADC's rounding, and "
                                         "the derivative filter's error through the Stribeck law's slope explains it"),
    ("below_quantization_step", "its change of the prediction stays within the torque ADC's rounding"),
    ("not_separated_on_held_out_blocks", "its gain does not hold across the held-out blocks (paired test)"),
    ("explained_by_speed_law", "a free friction curve explains it"),
    ("explained_by_state_law", "it lies at a line of the motion, and a free function of position, speed and "
                               "acceleration explains it as well"),
    ("not_held_across_halves", "it lies at a line of the motion and does not keep its phase from one half of the "
                               "log to the other"),
    ("explained_by_uneven_residual", "it won only through the time windows with bursts of misfit"),
    ("explained_by_periodic_residual", "the periodic residual explains it"),
    ("explained_by_dither", "a disturbance's dither of the Coulomb friction explains it"),
    ("explained_by_one_speed_change", "only the samples speeding up out of a standstill or a reversal show it"),
)


def rejection_reason(r: dict, alpha=None, min_gain=None) -> str:
    """One phrase saying why the candidate ``r`` (an entry of ``not_found``) was rejected: the first flag of
    :data:`REJECTION_REASONS` it carries, else not significant at ``alpha`` or below the ``min_gain``; "" when none
    applies (a significant candidate that lost its round to a better one)."""
    for key, text in REJECTION_REASONS:
        if r.get(key):
            return text
    if alpha is not None and r.get("p_value", 0.0) >= alpha:
        return f"not significant (p >= {alpha:g})"
    if min_gain is not None and r.get("rmse_reduction", 1.0) < min_gain:
        return f"gain below {100 * min_gain:g} %"
    return ""
