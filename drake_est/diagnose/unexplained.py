"""What the final model leaves: the "unexplained" verdict and the next experiment.

:func:`residual_structure` tests the final *held-out* residual of every joint for remaining structure at
a fixed family-wise false-alarm rate (Bonferroni over the tests):

* dependence on a variable x in {q, qd, qdd, t} (and motor position q * gear ratio mod 1 rev when the gear
  ratio is known): one-way analysis of variance of the residual over ``N_BINS`` quantile bins of x,
  F = (SS_between / (B - 1)) / (SS_within / (n - B));
* whiteness over time: regression of the residual on its ``N_LAGS`` previous held-out samples
  (consecutive samples of the same validation block only), F-test of the lag coefficients.
* on the moving but accelerating samples that the selection (9.9) leaves out (generic axes): ANOVA over
  jerk of the residual after an offset, the inertia and the derivative-filter error (snap) are regressed
  out (a delay between torque and position samples, backlash).

A structure is reported when its p-value is below ``ALPHA_UNEXPLAINED / n_tests`` *and* it holds at least
``MIN_SHARE`` of the residual variance (between-bin or predictable share).  No cause is named for it.

:func:`next_experiments` says which experiment would decide between candidates the log cannot separate
or cannot test (too few low speeds, one speed only, too short for a thermal drift).
"""
from __future__ import annotations

import numpy as np
import scipy.stats

ALPHA_UNEXPLAINED = 1e-3
MIN_SHARE = 0.03
#: on the accelerating samples left out by (9.9) the accelerations themselves are less accurate (derivative
#: filter lag at jerks): a structure there must hold this much of the residual variance
MIN_SHARE_EXCLUDED = 0.08
N_BINS = 20
#: fewest accelerating samples for the left-out-sample tests (10 per ANOVA bin)
MIN_EXCLUDED_SAMPLES = 200
#: [s] the left-out-sample tests (jerk, time shift) judge torque at accelerating samples through the smoothed
#: qdd; a derivative window longer than this (e.g. 7 samples at 10 Hz) smooths acceleration phases of a few
#: tenths of a second away, and its error would be taken for structure
MAX_DERIV_WINDOW_S = 0.2
N_LAGS = 5
#: a thermal (energy) drift with a time constant of about an hour needs a log this long [s] to be testable
THERMAL_MIN_DURATION_S = 3600.0


def _anova(x, e, n_bins=N_BINS):
    edges = np.unique(np.quantile(x, np.linspace(0, 1, n_bins + 1)))
    if edges.size < 3:
        return None
    b = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, edges.size - 2)
    B = int(b.max()) + 1
    cnt = np.bincount(b, minlength=B).astype(float)
    ok = cnt > 0
    means = np.bincount(b, weights=e, minlength=B)[ok] / cnt[ok]
    m = e.mean()
    ss_b = float(np.sum(cnt[ok] * (means - m) ** 2))
    ss_t = float(np.sum((e - m) ** 2))
    ss_w = max(ss_t - ss_b, 1e-300)
    k = int(ok.sum())
    n = e.size
    if n - k < 10 or k < 2:
        return None
    F = (ss_b / (k - 1)) / (ss_w / (n - k))
    where = edges[1:][ok][int(np.argmax(np.abs(means - m)))]
    return float(scipy.stats.f.sf(F, k - 1, n - k)), ss_b / max(ss_t, 1e-300), float(where)


def _whiteness(e, block, n_lags=N_LAGS):
    n = e.size
    if n < 10 * n_lags:
        return None
    X = np.column_stack([np.roll(e, k) for k in range(1, n_lags + 1)])
    same = np.ones(n, bool)
    for k in range(1, n_lags + 1):
        same &= np.roll(block, k) == block
    same[:n_lags] = False
    if same.sum() < 10 * n_lags:
        return None
    X, y = X[same], e[same]
    c, *_ = np.linalg.lstsq(X, y, rcond=None)
    rss1 = float(np.sum((y - X @ c) ** 2))
    rss0 = float(y @ y)
    m = y.size
    F = ((rss0 - rss1) / n_lags) / (rss1 / max(m - n_lags, 1))
    p = float(scipy.stats.f.sf(F, n_lags, m - n_lags)) if F > 0 else 1.0
    return p, 1.0 - rss1 / max(rss0, 1e-300), float(c[0])


def _friction_at(model, fit, jd, j, idx):
    """The final model's friction (nominal + own extensions) at samples ``idx`` of joint j (None when an
    extension cannot be evaluated there)."""
    from drake_est.identification.friction.extensions import columns_at
    q, v, t = jd.q[idx], jd.v[idx], jd.t[idx]
    blocks = [np.column_stack([v, np.sign(v)])]
    for e in model.own(j):
        if e.effect in ("gear_coupling", "payload"):
            return None
        E = None if e.obj is None or e.effect != "energy_dependent_friction" else np.asarray(e.obj)[idx]
        blocks.append(columns_at(e.spec, q, v, t, E_unit=E))
    return np.hstack(blocks) @ fit.coef[j]


def _time_shift(prep, fit, j, n_max=20000, max_shift_s=0.1):
    """Is the measured torque the model's torque at another time?  On all moving samples, the residual
    e = tau - M is regressed on the odd difference D_k = (M(t - k h) - M(t + k h)) / 2 ~ -k h dM/dt for
    shifts k = 1 .. K (K h <= ``max_shift_s``), after an offset, the inertia (qdd) and the derivative-filter
    error (snap) are regressed out.  A delay d between torque and position samples leaves
    e = M(t - d) - M(t), i.e. mostly the k = d/h column; a zero-phase derivative filter leaves an even error
    that the odd difference does not pick up.  Returns (p, share, shift_s, var_e) for the best k (p
    Bonferroni-corrected over the K shifts tried) or None; generic axes only."""
    jd = prep.joints[j]
    if prep.robot is not None:
        return None
    model = getattr(fit, "_model", None)
    if model is None or model.shared_exts():
        return None
    N = jd.t.size
    h = float(np.median(np.diff(jd.t)))
    K = int(max(1, min(20, round(max_shift_s / h))))
    thr = jd.counts["thresholds"]
    idx = np.flatnonzero(np.abs(jd.v) > thr["v_min"])
    idx = idx[(idx >= K) & (idx < N - K)]
    if idx.size < MIN_EXCLUDED_SAMPLES:
        return None
    idx = idx[:: max(1, idx.size // n_max)]
    allk = np.unique(np.concatenate([idx + k for k in range(-K, K + 1)]))
    Mf = _friction_at(model, fit, jd, j, allk)
    if Mf is None:
        return None
    M = np.full(N, np.nan)
    M[allk] = jd.rb[allk] + Mf
    e = jd.tau[idx] - M[idx]
    jerk = np.gradient(jd.a, jd.t)
    snap = np.gradient(jerk, jd.t)[idx]
    Nu = np.column_stack([np.ones(idx.size), jd.a[idx], snap])
    P = lambda x: x - Nu @ np.linalg.lstsq(Nu, x, rcond=None)[0]   # noqa: E731
    e = P(e)
    ss = float(e @ e)
    best = None
    for k in range(1, K + 1):
        D = P(0.5 * (M[idx - k] - M[idx + k]))
        dd = float(D @ D)
        if dd <= 0:
            continue
        gain = float(D @ e) ** 2 / dd
        if best is None or gain > best[0]:
            best = (gain, k)
    if best is None or ss <= 0:
        return None
    gain, k = best
    n = idx.size
    F = gain / max((ss - gain) / max(n - 4, 1), 1e-300)
    p = min(1.0, K * float(scipy.stats.f.sf(F, 1, max(n - 4, 1))))
    return p, gain / ss, k * h, float(ss / n)


def _excluded_moving(prep, fit, j, n_max=20000):
    """ANOVA over jerk of the final model's residual on the *moving but accelerating* samples that
    the data selection (9.9) left out (a delay between torque and position, backlash or an inertia error
    shows there first).  The final model is evaluated at those samples through the same columns
    (:func:`~drake_est.identification.friction.extensions.columns_at`); None when an extension cannot be
    evaluated there (gear coupling, payload), for robot models (inverse dynamics only at the selected rows)
    or when too few such samples exist; else {variable: (p, share, where) or None}."""
    from drake_est.identification.friction.extensions import columns_at
    jd = prep.joints[j]
    if prep.robot is not None:
        return None       # the rigid-body torque is only computed at the selected rows
    model = getattr(fit, "_model", None)
    if model is None or model.shared_exts():
        return None
    thr = jd.counts["thresholds"]
    idx = np.flatnonzero((np.abs(jd.v) > thr["v_min"]) & (np.abs(jd.a) > thr["a_max"]))
    if idx.size < MIN_EXCLUDED_SAMPLES:
        return None
    idx = idx[:: max(1, idx.size // n_max)]
    pred = _friction_at(model, fit, jd, j, idx)
    if pred is None:
        return None
    e = (jd.tau - jd.rb)[idx] - pred
    jerk_all = np.gradient(jd.a, jd.t)
    snap = np.gradient(jerk_all, jd.t)[idx]
    jerk = jerk_all[idx]
    # nuisance, not evidence: an offset, an error of the identified inertia (qdd) and the error of the
    # smoothed second derivative (a Savitzky-Golay qdd errs by about c h^2 d^4q/dt^4, i.e. the snap)
    N = np.column_stack([np.ones(idx.size), jd.a[idx], snap])
    e = e - N @ np.linalg.lstsq(N, e, rcond=None)[0]
    # jerk: a delay d between torque and position samples leaves -d dtau/dt = -d (J jerk + kv qdd + ...);
    # its qdd part is absorbed by the inertia, the jerk part is not (no axis model depends on jerk); backlash
    # (torque missing while the motor crosses the dead band after a reversal) shows there too
    r = _anova(jerk, e)
    # the quantization guard compares with the variance of this residual (not of the selected samples')
    return {"jerk_excluded_samples": None if r is None else (*r, float(np.var(e)))}


def residual_structure(prep, fit, alpha=ALPHA_UNEXPLAINED, min_share=MIN_SHARE) -> list:
    """Remaining structure of the final held-out residual (list of dicts; empty when none)."""
    from drake_est.diagnose.nominal import block_index
    out = []
    tests = []
    for j, jd in prep.joints.items():
        rows = jd.rows[jd.val]
        e = (jd.y - fit.pred[j])[jd.val]
        e = e - e.mean()
        variables = {"position": jd.q[rows], "velocity": jd.v[rows], "acceleration": jd.a[rows], "time": jd.t[rows]}
        if jd.gear_ratio:
            variables["motor_position"] = np.mod(jd.q[rows] * jd.gear_ratio, 2 * np.pi)
        for name, x in variables.items():
            r = _anova(x, e)
            if r is not None:
                tests.append((j, name, r))
        r = _whiteness(e, block_index(jd.t, rows))
        if r is not None:
            tests.append((j, "time_correlation", r))
        win = (prep.log.meta.get("derivatives") or {}).get("window_s")
        if win is None or win <= MAX_DERIV_WINDOW_S:
            for name, r in (_excluded_moving(prep, fit, j) or {}).items():
                if r is not None:
                    tests.append((j, name, r))
            r = _time_shift(prep, fit, j)
            if r is not None:
                tests.append((j, "time_shift_torque_vs_position", r))
    n_tests = max(len(tests), 1)
    from drake_est.diagnose.quantization import torque_step
    steps = {j: prep.meta.get("tau_step", {}).get(j, None) for j in prep.joints}
    steps = {j: (torque_step(prep.joints[j].tau) if s is None else s) for j, s in steps.items()}
    var = {j: float(np.var((jd.y - fit.pred[j])[jd.val])) for j, jd in prep.joints.items()}
    for j, name, r in tests:
        p, share, where = r[:3]
        v_e = r[3] if len(r) > 3 else var[j]
        # a quantized torque leaves a deterministic error below one step that follows the torque level
        if steps[j] > 0 and np.sqrt(share * v_e) < steps[j]:
            continue
        need = max(min_share, MIN_SHARE_EXCLUDED) if name.endswith(("_excluded_samples", "_vs_position")) else min_share
        if p < alpha / n_tests and share >= need:
            d = {"joint": int(j), "variable": name, "p_value": p, "share_of_residual_variance": float(share),
                 "samples": "accelerating samples left out by (9.9)" if name.endswith("_excluded_samples")
                 else "held-out samples",
                 "test": "autocorrelation F-test" if name == "time_correlation" else "ANOVA over 20 quantile bins"}
            if name == "time_correlation":
                d["lag1_coefficient"] = where
            elif name == "time_shift_torque_vs_position":
                d["test"] = "F-test of the odd model-torque difference (torque = model at a shifted time)"
                d["samples"] = "all moving samples"
                d["best_shift_s"] = where
            else:
                d["largest_deviation_bin_upper_edge"] = where
            out.append(d)
    return sorted(out, key=lambda d: -d["share_of_residual_variance"])


def next_experiments(prep, steps, duration) -> list:
    """Experiments that would decide what this log cannot: ambiguous findings and untestable candidates."""
    from drake_est.diagnose.detectors import stribeck_speeds
    out = []
    for s in steps:
        c = s.competition or {}
        if c.get("ambiguous"):
            j = int(s.ext.joint)
            jd = prep.joints.get(j)
            pair = {s.ext.effect, c["runner_up"]}
            exp = {"reason": f"ambiguous between {s.ext.effect} and {c['runner_up']}", "joint": j}
            if pair == {"motor_position_ripple", "time_periodic_disturbance"} and jd is not None:
                v = float(np.median(np.abs(jd.v[jd.rows])))
                exp["experiment"] = (f"constant-speed sweeps of joint {j} at two more speeds, about "
                                     f"{0.4 * v:.3g} and {2.0 * v:.3g} per s, over the same positions: a position "
                                     "ripple keeps its cycles per rad, a time-periodic disturbance its Hz")
                exp["speeds"] = [0.4 * v, 2.0 * v]
            else:
                exp["experiment"] = (f"a longer log of joint {j} with several constant speeds and both directions "
                                     "over the full position range")
            out.append(exp)
    for j, jd in prep.joints.items():
        v = np.abs(jd.v[jd.rows])
        if stribeck_speeds(jd.v[jd.rows]).size == 0:
            vmax = float(np.quantile(v, 0.95))
            out.append({"reason": "stribeck untestable: too few low-speed samples", "joint": int(j),
                        "speed_range": [0.01 * vmax, 0.3 * vmax],
                        "experiment": f"constant-speed sweeps of joint {j} at 8 speeds from {0.01 * vmax:.3g} "
                                      f"to {0.3 * vmax:.3g} per s (log spaced), 10 s each, both directions"})
        lo, hi = np.quantile(v, [0.1, 0.9])
        if hi < 1.3 * lo and not any(e.get("joint") == j and "ripple" in e.get("experiment", "") for e in out):
            out.append({"reason": "one speed only: position-periodic and time-periodic cannot be told apart",
                        "joint": int(j), "speeds": [float(0.4 * np.median(v)), float(2.0 * np.median(v))],
                        "experiment": f"sweeps of joint {j} at {0.4 * np.median(v):.3g} and "
                                      f"{2.0 * np.median(v):.3g} per s over the same positions"})
    if duration < THERMAL_MIN_DURATION_S:
        out.append({"reason": f"log too short ({duration:.0f} s) for an hour-long thermal drift",
                    "duration_s": THERMAL_MIN_DURATION_S,
                    "experiment": f"{THERMAL_MIN_DURATION_S / 60:.0f} min of continuous motion from a cold start"})
    return out
