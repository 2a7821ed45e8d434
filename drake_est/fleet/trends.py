"""Parameter time series across a fleet's logs, change detection and ranked early warnings.

For each robot x joint x parameter (the ``parameters`` table of the store: Coulomb and viscous
levels, ripple amplitude, energy time constant, payload mass) the values of successive logs form a
series y_1..y_T at log times t_1..t_T [days].  :func:`detect_change` looks for one change in it with
the methods of thesis Ch. 7:

* **change point by dynamic programming**, problem (7.8) with one switch
  (:func:`drake_est.identification.ltv.tv_regression_segments`, Algorithm 3): once with a constant
  per segment (a *step*: payload mounted, a part replaced) and once with an affine function of time
  per segment (an *onset of a trend*: wear, a growing ripple);
* **trend filtering**, problem (7.5) (second-order differences,
  :func:`drake_est.identification.ltv.tv_regression_smoother` with ``order=2``): the smooth trend drawn
  in the report.

A change is reported when (i) the one-switch fit lowers the residual sum of squares by at least
``MIN_SNR`` noise variances (noise from the median absolute first difference, robust to the change
itself; isolated outlying logs are left out first by a Hampel filter and counted), (ii) the change is physically relevant (``PARAMETERS``: relative or absolute size) and (iii) it
persists: at least 80 % of the logs after the change lie on the new side of the midpoint between the
levels (one odd log does not make a warning).  Warnings are ranked by the signal-to-noise ratio
sqrt(delta RSS) / sigma.  A payload change on a robot explains simultaneous (+-3 days) changes of its
joints' friction estimates; those are listed under ``explained_by`` instead of as warnings.
"""
from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass

import numpy as np

from drake_est.errors import DataError

#: name -> (cause if it grew, cause if it fell, min relative change, min absolute change, unit, label)
PARAMETERS = {
    "coulomb_nm": ("coulomb_wear", "coulomb_drop", 0.15, 0.0, "N m", "Coulomb friction"),
    "viscous_nms": ("viscous_increase", "viscous_drop", 0.25, 0.0, "N m s/rad", "viscous friction"),
    "ripple_amplitude_nm": ("motor_position_ripple", "motor_position_ripple_fell", 0.0, 0.05, "N m",
                            "motor-position ripple"),
    "energy_time_constant_s": ("energy_time_constant_change", "energy_time_constant_change", 0.5, 0.0, "s",
                               "energy time constant"),
    "payload_mass_kg": ("payload", "payload", 0.0, 0.3, "kg", "payload"),
}
#: parameters recorded as 0 when the diagnosis did not find the effect
PRESENCE = ("ripple_amplitude_nm", "payload_mass_kg")
MIN_SNR2 = 30.0          # minimum RSS reduction of the one-switch fit, in noise variances
TREND_EXTRA_SNR2 = 15.0  # the affine-segment model must beat the step model by this much to be chosen
MIN_POINTS = 8
MIN_SEGMENT = 3
PERSIST = 0.8
EXPLAIN_DAYS = 3.0


def robust_sigma(y) -> float:
    """Noise standard deviation from the median absolute first difference (robust to one change)."""
    d = np.diff(np.asarray(y, float))
    if d.size == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(2.0))


def outlier_mask(y, half: int = 3, k: float = 6.0) -> np.ndarray:
    """True for isolated outlying logs (Hampel filter): more than ``k`` noise standard deviations
    (robust, from second differences) from the running median of 2 ``half`` + 1 logs.  A step lasting more than ``half`` logs and a
    trend are followed by the running median and are not outliers."""
    y = np.asarray(y, float)
    T = y.size
    if T < 2 * half + 1:
        return np.zeros(T, bool)
    # point reflection at the ends keeps a linear trend linear (edge padding would flag its last logs)
    pad = np.concatenate([2 * y[0] - y[half:0:-1], y, 2 * y[-1] - y[-2:-half - 2:-1]])
    med = np.median(np.lib.stride_tricks.sliding_window_view(pad, 2 * half + 1), axis=1)
    r = y - med
    # noise level from second differences: zero for a step (but at 2 points) and for a trend
    d2 = np.diff(y, 2)
    s = 1.4826 * float(np.median(np.abs(d2 - np.median(d2)))) / np.sqrt(6.0)
    s = max(s, 1e-6 * max(float(np.median(np.abs(y))), 1e-12))
    return np.abs(r) > k * s


def trend_filter(t, y, lam: float = 3.0) -> np.ndarray:
    """Smooth trend of a series by trend filtering (7.5): second-order differences penalized by
    ``lam`` on the series scaled by its robust noise level."""
    from drake_est.identification.ltv import tv_regression_smoother
    y = np.asarray(y, float)
    if y.size < 3 or np.ptp(y) == 0:
        return y.copy()
    s = max(robust_sigma(y), 1e-9 * max(1.0, float(np.max(np.abs(y)))))
    res = tv_regression_smoother(np.ones((y.size, 1)), (y - y.mean()) / s, lam, order=2, sigma_e=1.0,
                                  want_cov=False)
    return res.k[:, 0] * s + y.mean()


@dataclass
class Change:
    """One detected change of a series (indices into the series; see :func:`detect_change`)."""
    index: int            # first log of the new segment
    kind: str             # "step" or "trend"
    snr: float            # sqrt(RSS reduction) / sigma
    before: float         # level of the old segment at its end
    after_start: float    # fitted level at the first log of the new segment
    after_end: float      # fitted level at the last log
    fit: np.ndarray       # the piecewise fit (T,)
    sigma: float
    n_outliers: int = 0   # isolated odd logs left out (:func:`outlier_mask`)


def _segments(Phi, y):
    from drake_est.identification.ltv import tv_regression_segments
    return tv_regression_segments(Phi, y, 1, min_length=MIN_SEGMENT)


def detect_appearance(t, y, min_abs: float = 0.0) -> Change | None:
    """Change of a series that is 0 when the diagnosis did not find the effect (ripple amplitude,
    payload mass): the switch of the presence indicator 1[y > 0] by the dynamic program (7.8)
    with one switch; the effect must be absent in >= 80 % of the logs before and present in >= 80 %
    after (at least ``MIN_SEGMENT`` logs).  The size after is an affine fit in time on the logs after."""
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    T = y.size
    z = (y > 0).astype(float)
    if T < MIN_POINTS or z.min() == z.max():
        return None
    st = _segments(np.ones((T, 1)), z)
    idx = int(st.change_times[0])
    pre, post = z[:idx], z[idx:]
    if post.mean() < PERSIST or pre.mean() > 1.0 - PERSIST or post.sum() < MIN_SEGMENT:
        return None   # an effect that disappeared, or one that comes and goes: no warning
    before = float(np.mean(y[:idx]))
    tp = t[idx:]
    A = np.column_stack([np.ones(tp.size), tp - tp[0]])
    coef = np.linalg.lstsq(A, y[idx:], rcond=None)[0]
    fit = np.r_[np.full(idx, before), A @ coef]
    resid = y[idx:] - fit[idx:]
    sigma = max(float(1.4826 * np.median(np.abs(resid - np.median(resid)))), 1e-3 * float(np.mean(y[idx:])), 1e-12)
    snr2 = float(np.sum((y - y.mean()) ** 2) - np.sum((y - fit) ** 2)) / sigma ** 2
    if snr2 < MIN_SNR2 or float(fit[-1]) - before < min_abs:
        return None
    kind = "trend" if abs(coef[1]) * (tp[-1] - tp[0]) > 3 * sigma else "step"
    return Change(idx, kind, float(np.sqrt(snr2)), before, float(fit[idx]), float(fit[-1]), fit, sigma)


def detect_change(t, y, min_rel: float = 0.0, min_abs: float = 0.0, presence: bool = False) -> Change | None:
    """The most significant single change of the series ``y`` at times ``t`` [days], or None.

    Dynamic program of (7.8) with one switch on a constant (step) and an affine (trend) model per
    segment; see the module doc for the three acceptance rules.  ``presence``: the series is 0 where
    the effect was not found (:func:`detect_appearance` when it has zeros)."""
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    T = y.size
    if T < MIN_POINTS or not np.all(np.isfinite(y)):
        return None
    if presence and np.any(y == 0):
        return detect_appearance(t, y, min_abs=min_abs)
    out = outlier_mask(y)
    if out.any():        # isolated odd logs (e.g. a poorly excited log) are left out, and counted
        keep = np.flatnonzero(~out)
        ch = detect_change(t[keep], y[keep], min_rel=min_rel, min_abs=min_abs)
        if ch is None:
            return None
        fit = np.interp(np.arange(T), keep, ch.fit)
        ch = Change(int(keep[ch.index]), ch.kind, ch.snr, ch.before, ch.after_start, ch.after_end, fit, ch.sigma,
                    int(out.sum()))
        return ch
    scale = max(float(np.max(np.abs(y))), 1e-12)
    sigma = max(robust_sigma(y), 1e-3 * float(np.median(np.abs(y))), 1e-9 * scale)
    rss0 = float(np.sum((y - y.mean()) ** 2))
    if rss0 <= 0.0:
        return None
    ones = np.ones((T, 1))
    step = _segments(ones, y)
    tc = (t - t.mean()) / max(float(np.ptp(t)), 1e-12)
    trend = _segments(np.column_stack([np.ones(T), tc]), y)
    rss_step = float(np.sum((y - step.k[:, 0]) ** 2))
    fit_trend = np.sum(np.column_stack([np.ones(T), tc]) * trend.k, axis=1)
    rss_trend = float(np.sum((y - fit_trend) ** 2))
    # a single straight line without a switch is not a change of the kind we warn about
    A = np.column_stack([np.ones(T), tc])
    line = np.linalg.lstsq(A, y, rcond=None)[0]
    rss_line = float(np.sum((y - A @ line) ** 2))
    if (rss_step - rss_trend) / sigma ** 2 > TREND_EXTRA_SNR2:
        kind, idx, fit, rss = "trend", int(trend.change_times[0]), fit_trend, min(rss_trend, rss0)
        if (rss_line - rss_trend) / sigma ** 2 < MIN_SNR2 and rss_line < rss_step:
            return None
    else:
        kind, idx, fit, rss = "step", int(step.change_times[0]), step.k[:, 0], rss_step
    snr2 = (rss0 - rss) / sigma ** 2
    if snr2 < MIN_SNR2:
        return None
    before, after_start, after_end = float(fit[idx - 1]), float(fit[idx]), float(fit[-1])
    after = after_end if abs(after_end - before) >= abs(after_start - before) else after_start
    delta = after - before
    if abs(delta) < min_abs or abs(delta) < min_rel * max(abs(before), 1e-12):
        return None
    mid = before + 0.5 * (after_start - before) if abs(after_start - before) > 0.25 * abs(delta) else before + 0.5 * delta
    side = np.sign(delta)
    post = y[idx:]
    if kind == "trend":   # compare each point with the fitted old level, half way to the fitted new one
        post_ok = np.mean(side * (post - (before + 0.5 * (fit[idx:] - before))) >= 0)
    else:
        post_ok = np.mean(side * (post - mid) > 0)
    pre_ok = np.mean(side * (y[:idx] - (before + 0.5 * delta)) < 0)
    if post_ok < PERSIST or pre_ok < PERSIST:
        return None
    return Change(idx, kind, float(np.sqrt(snr2)), before, after_start, after_end, fit, sigma)


def load_series(store, settings_hash: str | None = None) -> dict:
    """{(robot_id, joint, name): (times [ISO], values)} of the ``ok`` logs (latest run's settings by default)."""
    if settings_hash is None:
        row = store.query("SELECT settings_hash FROM runs ORDER BY run_id DESC LIMIT 1")
        if not row:
            row = store.query("SELECT settings_hash FROM logs LIMIT 1")
        settings_hash = row[0][0] if row else ""
    rows = store.query("SELECT l.robot_id, p.joint, p.name, l.log_time, p.value FROM parameters p "
                       "JOIN logs l ON l.log_id = p.log_id WHERE l.status = 'ok' AND l.settings_hash = ? "
                       "ORDER BY l.robot_id, p.joint, p.name, l.log_time", (settings_hash,))
    series = {}
    for rid, j, name, tt, v in rows:
        series.setdefault((rid, int(j), name), ([], []))
        series[(rid, int(j), name)][0].append(tt)
        series[(rid, int(j), name)][1].append(float(v))
    return series


def days_since(times, origin=None) -> np.ndarray:
    ts = [_dt.datetime.fromisoformat(s) for s in times]
    o = _dt.datetime.fromisoformat(origin) if origin else min(ts)
    return np.array([(x - o).total_seconds() / 86400.0 for x in ts])


def _robot_label(rid: str) -> str:
    tail = rid.rsplit("_", 1)[-1]
    return f"robot {int(tail)}" if tail.isdigit() else rid


def _text(w, freq=None) -> str:
    who = _robot_label(w["robot_id"]) + ("" if w["joint"] == 0 else f", joint {w['joint']}")
    unit = w["unit"]
    if w["parameter"] == "payload_mass_kg":
        return f"{who}: payload changed from {w['before']:.3g} to {w['after']:.3g} kg on {w['date']}"
    if w["parameter"] == "ripple_amplitude_nm":
        at = f" at {freq:.3g} per rev" if freq else ""
        if abs(w["before"]) < 0.25 * abs(w["after_start"]) and w["after_start"] > 0:
            grow = w["after_end"] / w["after_start"]
            return (f"{who}: motor-position ripple{at} appeared on {w['date']} ({w['after_start']:.3g} {unit} rms)"
                    + (f" and grew {grow:.2g}x since" if abs(grow - 1) > 0.2 else "")
                    + f" (now {w['after_end']:.3g} {unit})")
        return f"{who}: motor-position ripple{at} changed {w['after'] / max(w['before'], 1e-12):.2g}x since {w['date']}"
    ratio = w["after"] / w["before"] if w["before"] else float("inf")
    if not 0.0 < ratio < 3.0:
        return (f"{who}: {PARAMETERS[w['parameter']][5]} changed from {w['before']:.3g} to {w['after']:.3g} {unit} "
                f"{'gradually since' if w['kind'] == 'trend' else 'on'} {w['date']}")
    verb = "grew" if w["after"] > w["before"] else "fell"
    how = "gradually since" if w["kind"] == "trend" else "on"
    return (f"{who}: {PARAMETERS[w['parameter']][5]} {verb} {abs(ratio - 1) * 100:.0f} % {how} {w['date']} "
            f"({w['before']:.3g} -> {w['after']:.3g} {unit})")


def fleet_trends(store, settings_hash: str | None = None) -> dict:
    """Series, detected changes and the ranked warnings of a fleet store (read through its schema).

    Returns ``{"series": [...], "warnings": [...], "explained": [...]}``; each warning has robot_id,
    joint (1-based, 0 = whole robot), parameter, cause, kind (step/trend), date, before, after, snr,
    text, rank."""
    series = load_series(store, settings_hash)
    out, warns = [], []
    freqs = {}
    for (rid, j, name), (times, vals) in series.items():
        if name == "ripple_frequency_per_rev":
            freqs[(rid, j)] = float(np.median(vals))
    for (rid, j, name), (times, vals) in sorted(series.items()):
        if name not in PARAMETERS:
            out.append({"robot_id": rid, "joint": j, "parameter": name, "times": times, "values": vals})
            continue
        grow, fall, min_rel, min_abs, unit, _label = PARAMETERS[name]
        t = days_since(times)
        y = np.asarray(vals)
        entry = {"robot_id": rid, "joint": j, "parameter": name, "times": times, "values": vals}
        if len(y) >= 3:
            entry["trend"] = trend_filter(t, y).tolist()
        ch = detect_change(t, y, min_rel=min_rel, min_abs=min_abs, presence=name in PRESENCE)
        if ch is not None:
            after = ch.after_end if abs(ch.after_end - ch.before) >= abs(ch.after_start - ch.before) else ch.after_start
            w = {"robot_id": rid, "joint": j, "parameter": name, "cause": grow if after > ch.before else fall,
                 "kind": ch.kind, "date": times[ch.index][:10], "time": times[ch.index], "before": ch.before,
                 "after": after, "after_start": ch.after_start, "after_end": ch.after_end, "snr": ch.snr,
                 "noise_sigma": ch.sigma, "unit": unit, "n_logs": int(len(y)), "outlier_logs": ch.n_outliers}
            w["text"] = _text(w, freqs.get((rid, j)))
            entry["change"] = {k: w[k] for k in ("date", "time", "kind", "before", "after", "snr")}
            entry["fit"] = ch.fit.tolist()
            warns.append(w)
        out.append(entry)
    # a payload change explains simultaneous friction changes of the same robot
    explained = []
    payload = [w for w in warns if w["parameter"] == "payload_mass_kg"]
    keep = []
    for w in warns:
        why = None
        if w["parameter"] != "payload_mass_kg":
            for p in payload:
                if p["robot_id"] == w["robot_id"] and abs(days_since([w["time"]], p["time"])[0]) <= EXPLAIN_DAYS:
                    why = f"payload change on {p['date']}"
        if why:
            explained.append(dict(w, explained_by=why))
        else:
            keep.append(w)
    keep.sort(key=lambda w: -w["snr"])
    for k, w in enumerate(keep, start=1):
        w["rank"] = k
    return {"series": out, "warnings": keep, "explained": explained}


def check_against_truth(trends: dict, truth: dict, date_tol_days: float = 2.0) -> dict:
    """Compare warnings with a synthetic fleet's truth (:mod:`drake_est.fleet.synth_fleet`): each
    planted change must be among the top len(planted) + 2 warnings with the right robot, joint
    (any joint for the payload), cause and date (+- ``date_tol_days``); healthy robots raise none."""
    if "changes" not in truth:
        raise DataError("truth file has no 'changes' (not made by drake-est synth-fleet?)")
    warns = trends["warnings"]
    top = len(truth["changes"]) + 2
    planted_robots = {c["robot"] for c in truth["changes"]}
    found = []
    for c in truth["changes"]:
        hit = None
        for w in warns[:top]:
            if w["robot_id"] != c["robot"] or w["cause"] != c["cause"]:
                continue
            if c["joint"] is not None and w["joint"] != c["joint"]:
                continue
            dd = abs(days_since([w["date"]], c["date"])[0])
            if dd <= date_tol_days:
                hit = {"rank": w["rank"], "date_error_days": dd, "text": w["text"]}
                break
        found.append({"planted": c, "found": hit})
    healthy_warn = [w for w in warns if w["robot_id"] not in planted_robots]
    other_warn = [w for w in warns if w["robot_id"] in planted_robots and not any(
        f["found"] and f["found"]["rank"] == w["rank"] for f in found)]
    return {"planted": len(truth["changes"]), "found": sum(f["found"] is not None for f in found),
            "warnings": len(warns), "healthy_robot_warnings": len(healthy_warn),
            "extra_warnings_on_planted_robots": len(other_warn),
            "healthy_robots": len(truth["robots"]) - len(planted_robots), "details": found,
            "false_alarms": [w["text"] for w in healthy_warn + other_warn]}
