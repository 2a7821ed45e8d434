"""Energy-dependent friction (thesis Sec. 9.4): F = F_n + sign(v) E, E = G(s) W,
W = |F v|, estimated by the fixed-point iteration of Algorithm 6.

Algorithm 6, as implemented by :func:`fit_energy`::

    given an initial H(z) (gain k_e, time constant tau_e)
    repeat n_iter times
        E  <- H(z) W                              filter the friction power
        fit F_n by least squares to  y - sign(v) E        (9.26)
        E^ <- (y - F_n) sign(v)                          (9.25)
        update H(z) by an output-error fit of E^ ~ H(z) W (9.24)

The output-error step minimizes sum (E^[k] - E(k; k_e, tau_e))^2 over the
selected samples; for a fixed time constant the optimal gain is a scalar least
squares, so the search is a bounded 1-D minimization over log(tau_e) (variable
projection). The initial guess comes from the torque envelope (Eq. (9.27)):
:func:`initial_guess`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.optimize
import scipy.signal

from drake_est.errors import DataError, DrakeEstError, IdentifiabilityError
from drake_est.identification.friction.model import JointFriction
from drake_est.identification.friction.terms import EnergyDynamics, _cols


def friction_power(y, v) -> np.ndarray:
    """W = |F v| (Eq. (9.21)) from the friction torque y [N m] and velocity v [rad/s]."""
    return np.abs(np.asarray(y, float).ravel() * np.asarray(v, float).ravel())


def _unit_response(W, a: float) -> np.ndarray:
    """Response of (1 - a) / (z - a) to W (unit static gain), E[0] = 0."""
    return scipy.signal.lfilter([0.0, 1.0 - a], [1.0, -a], W)


def oe_fit(W, E_hat, h: float, tau0: float, mask=None, tau_bounds=None):
    """Output-error fit of E_hat ~ k_e (1 - a)/(z - a) W, a = exp(-h / tau_e) (Eq. (9.24)).

    Returns (k_e, tau_e, sse). ``tau_bounds`` defaults to [h, 20 x duration]."""
    W = np.asarray(W, float).ravel()
    E_hat = np.asarray(E_hat, float).ravel()
    m = np.ones(W.size, bool) if mask is None else np.asarray(mask)
    lo, hi = tau_bounds if tau_bounds is not None else (h, 20.0 * h * W.size)

    def profile(log_tau):
        a = np.exp(-h / np.exp(log_tau))
        u = _unit_response(W, a)[m]
        uu = float(u @ u)
        k = float(u @ E_hat[m]) / uu if uu > 0 else 0.0
        r = E_hat[m] - k * u
        return float(r @ r), k

    # coarse log grid then a bounded Brent refinement around the best cell (robust to local minima)
    grid = np.linspace(np.log(lo), np.log(hi), 41)
    sse = np.array([profile(g)[0] for g in grid])
    i = int(np.argmin(sse))
    a_lo, a_hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    if a_hi > a_lo:
        res = scipy.optimize.minimize_scalar(lambda g: profile(g)[0], bounds=(a_lo, a_hi), method="bounded",
                                             options={"xatol": 1e-6})
        best = res.x if res.fun <= sse[i] else grid[i]
    else:
        best = grid[i]
    s, k = profile(best)
    return k, float(np.exp(best)), s


def initial_guess(t, v, y, nominal: JointFriction | None = None, mask=None, window_frac: float = 0.05):
    """Gain and time constant of G(s) from the torque envelope (Sec. 9.4, Eq. (9.27), Fig. 9.3).

    The Coulomb level sign(v) (y - k_v v) = k_c + E + noise is smoothed by a running
    median; its change from the start to the end is E_inf; tau_e is the time the
    smoothed level takes to cover 63 % (1 - 1/e) of that change, and
    k_e = E_inf / mean(W). ``nominal`` (fitted on ``mask``) provides k_v; without
    it a Coulomb + viscous model is fitted here."""
    t = np.asarray(t, float).ravel()
    v = np.asarray(v, float).ravel()
    y = np.asarray(y, float).ravel()
    m = np.ones(t.size, bool) if mask is None else np.asarray(mask, bool)
    if nominal is None:
        A = np.stack([v, np.sign(v)], axis=1)[m]
        kv = float(np.linalg.lstsq(A, y[m], rcond=None)[0][0])
    else:
        kv = float(nominal.params().get("kv", 0.0))
    lev = (np.sign(v) * (y - kv * v))[m]
    tm = t[m]
    if lev.size < 20:
        raise IdentifiabilityError(f"only {lev.size} moving samples; too few to read the torque envelope")
    w = max(5, int(window_frac * lev.size)) | 1
    pad = w // 2
    padded = np.pad(lev, pad, mode="edge")
    smooth = np.array([np.median(padded[i:i + w]) for i in range(lev.size)])
    start, end = smooth[0], smooth[-1]
    E_inf = end - start
    W = friction_power(y, v)
    duration = t[-1] - t[0]
    noise = float(np.median(np.abs(lev - smooth))) * 1.4826
    if abs(E_inf) < 2 * noise / np.sqrt(w) or not np.isfinite(E_inf):
        return {"gain": 0.0, "time_constant": duration / 5.0, "E_inf": float(E_inf), "kv": kv,
                "note": "no envelope change detected"}
    target = start + (1 - np.exp(-1.0)) * E_inf
    crossed = np.flatnonzero((smooth - target) * np.sign(E_inf) >= 0)
    tau = float(tm[crossed[0]] - t[0]) if crossed.size else duration
    tau = max(tau, 2 * float(np.median(np.diff(t))))
    gain = float(E_inf / np.mean(W))
    return {"gain": gain, "time_constant": tau, "E_inf": float(E_inf), "kv": kv}


@dataclass
class EnergyFit:
    """Result of :func:`fit_energy`."""

    model: JointFriction
    E: np.ndarray
    history: list = field(default_factory=list)  # per iteration: dict of params + rmse
    initial: dict = field(default_factory=dict)


def fit_energy(model: JointFriction, t, Q, DQ, y, mask=None, gain0: float | None = None, tau0: float | None = None,
               n_iter: int = 50, tol: float = 0.0, power: str = "measured", accelerate: str | None = "anderson",
               depth: int = 3, max_step: float = 3.0, callback=None) -> EnergyFit:
    """Algorithm 6: estimate the nominal model F_n (the linear terms of ``model``)
    and H(z) jointly by fixed-point iteration.

    Parameters
    ----------
    model : a :class:`JointFriction` whose ``energy`` is set (see ``build_model(..., "energy")``);
        its terms form F_n (any nominal, position, motor... terms).
    t : (N,) uniformly sampled time [s]; the log must be contiguous (E is a state).
    Q, DQ : (N,) or (N, n) positions and velocities; y : (N,) friction torque [N m].
    mask : samples used in the least-squares and OE fits (e.g. :func:`select_steady`);
        the filter always runs over all samples.
    gain0, tau0 : initial G(s); default from the torque envelope (9.27).
    power : "measured" (the only option): W = |y v| on the selected samples and |F0 v| from a
        Coulomb + viscous fit elsewhere (driving E by the model's own power, W = |F^ v|, closes a
        feedback loop through E that made the iteration diverge in tests).
    tol : stop early when the relative change of (k_e, tau_e) falls below tol (0: run all n_iter).
    accelerate : "anderson" (default) extrapolates the fixed-point map over the last ``depth``
        iterates (Anderson mixing on (k_e, log tau_e)), safeguarded: the extrapolated step is at
        most ``max_step`` times the plain fixed-point step and keeps the sign of the gain;
        None runs the plain iteration of
        Algorithm 6, which converges to the same fixed point but slowly (the Coulomb level and
        the mean of E trade off; about 3 % of the error is removed per iteration in the
        Table 9.1 simulation).
    """
    t = np.asarray(t, float).ravel()
    Q, DQ = _cols(Q, "q"), _cols(DQ, "dq")
    y = np.asarray(y, float).ravel()
    N = t.size
    if Q.shape[0] != N or y.size != N:
        raise DataError(f"t has {N} samples, q has {Q.shape[0]}, torque has {y.size}")
    dt = np.diff(t)
    h = float(np.median(dt))
    if h <= 0 or np.max(np.abs(dt - h)) > 0.01 * h:
        raise DataError("the energy model needs a contiguous, uniformly sampled log (E is a state); "
                        "resample it or fit on a contiguous segment")
    if model.energy is None:
        raise DrakeEstError("model has no energy dynamics; build it with model='energy' or 'position+energy'")
    m = np.ones(N, bool) if mask is None else np.asarray(mask, bool)
    v = DQ[:, model.index]
    s = np.sign(v)
    W = friction_power(y, v)
    if not np.all(m):
        # samples dropped by (9.9) (near-zero or changing velocity) carry inertial torque: their power comes
        # from a Coulomb + viscous fit on the selected samples instead of the measured torque
        A0 = np.stack([v, s], axis=1)
        c0 = np.linalg.lstsq(A0[m], y[m], rcond=None)[0]
        W = np.where(m, W, friction_power(A0 @ c0, v))
    init = {}
    if gain0 is None or tau0 is None:
        init = initial_guess(t, v, y, mask=m)
        gain0 = init["gain"] if gain0 is None else gain0
        tau0 = init["time_constant"] if tau0 is None else tau0
    if power != "measured":
        raise DrakeEstError(f"unknown power option '{power}' (use 'measured')")
    if tau0 <= 0:
        raise DrakeEstError(f"initial time constant must be positive, got {tau0}")
    init.update({"gain0": float(gain0), "tau0": float(tau0)})
    lam_fixed = [None]

    def sweep(gain, tau):
        """One pass of Algorithm 6 from H(z; gain, tau); returns the updated (gain, tau) and the fit."""
        dyn = EnergyDynamics(gain=float(gain), time_constant=float(tau), h=h)
        E = dyn.filter(W)                                 # E <- H(z) W
        model.energy = None
        if lam_fixed[0] is not None:
            model.lam = lam_fixed[0]
        model.fit(Q, DQ, y - s * E, mask=m, solver="cholesky")   # (9.26)
        if model.has_bfe and lam_fixed[0] is None:
            lam_fixed[0] = model.info["lam"]              # CV once, then keep the penalty fixed
        Fn = model.predict_nominal(Q, DQ)
        E_hat = (y - Fn) * s                              # (9.25)
        Wk = W
        k_new, tau_new, _ = oe_fit(Wk, E_hat, h, tau, mask=m)   # (9.24), output error
        return k_new, tau_new, model.coef.copy(), Wk

    def output_rmse(gain, tau, coef, Wk):
        E = EnergyDynamics(gain=gain, time_constant=tau, h=h).filter(Wk)
        model.coef = coef
        pred = model.predict_nominal(Q, DQ) + s * E
        return float(np.sqrt(np.mean((y[m] - pred[m]) ** 2)))

    x = np.array([float(gain0), np.log(float(tau0))])
    scale = np.array([max(abs(float(gain0)), 1e-6), 1.0])
    X_hist, F_hist = [], []
    hist = []
    best = None   # (rmse, gain, tau) of the best iterate, reported in model.info
    for it in range(n_iter):
        k1, t1, coef1, Wk = sweep(x[0], np.exp(x[1]))
        fx = np.array([k1, np.log(t1)]) - x                 # fixed-point residual T(x) - x
        x_plain = x + fx
        model.energy = EnergyDynamics(gain=k1, time_constant=t1, h=h)
        rec = dict(model.params())
        rec["iteration"] = it + 1
        rec["rmse"] = output_rmse(k1, t1, coef1, Wk)
        hist.append(rec)
        if callback is not None:
            callback(it, model, rec)
        if best is None or rec["rmse"] < best[0]:
            best = (rec["rmse"], k1, t1)
        x_next = x_plain
        if accelerate == "anderson" and X_hist:
            dX = np.stack([x - xp for xp in X_hist[-depth:]], axis=1) / scale[:, None]
            dF = np.stack([fx - fp for fp in F_hist[-depth:]], axis=1) / scale[:, None]
            gamma = np.linalg.lstsq(dF, fx / scale, rcond=None)[0]
            cand = x_plain - scale * ((dX + dF) @ gamma)
            # safeguard: keep the sign of the gain and limit the extrapolated step to max_step x the plain step
            step_plain = float(np.linalg.norm(fx / scale))
            step = float(np.linalg.norm((cand - x) / scale))
            if np.all(np.isfinite(cand)) and np.sign(cand[0]) == np.sign(x_plain[0]):
                if step > max_step * step_plain and step > 0:
                    cand = x + (cand - x) * (max_step * step_plain / step)
                x_next = cand
        X_hist.append(x.copy())
        F_hist.append(fx.copy())
        X_hist, F_hist = X_hist[-depth:], F_hist[-depth:]
        change = float(np.max(np.abs(x_next - x) / scale))
        x = x_next
        if tol > 0 and change < tol:
            break
    # final: nominal refit with the last H(z) so that coef and energy are consistent
    k_last, t_last = hist[-1]["ke"], hist[-1]["tau_e"]
    model.info["energy_best_rmse"] = best[0]
    dyn = EnergyDynamics(gain=k_last, time_constant=t_last, h=h)
    model.energy = None
    model.fit(Q, DQ, y - s * dyn.filter(W), mask=m)
    model.energy = dyn
    model.info["energy_iterations"] = len(hist)
    model.info["power"] = power
    model.info["accelerate"] = accelerate
    return EnergyFit(model=model, E=dyn.filter(W), history=hist, initial=init)


def simulate_energy_system(t, v, kv: float, kc: float, gain: float, time_constant: float, noise_std: float = 0.0,
                           rng=None):
    """Simulate (9.22)-(9.23) with a viscous nominal model (Sec. 9.5): returns
    (tau measured, F true, E true, W true). ZOH sampling of G(s)."""
    t = np.asarray(t, float).ravel()
    v = np.asarray(v, float).ravel()
    h = float(np.median(np.diff(t)))
    a = np.exp(-h / time_constant)
    b = gain * (1 - a)
    N = t.size
    E = np.zeros(N)
    F = np.zeros(N)
    W = np.zeros(N)
    e = 0.0
    s = np.sign(v)
    for k in range(N):
        E[k] = e
        F[k] = kv * v[k] + kc * s[k] + s[k] * e
        W[k] = abs(F[k] * v[k])
        e = a * e + b * W[k]
    rng = np.random.default_rng(rng)
    tau = F + noise_std * rng.standard_normal(N)
    return tau, F, E, W
