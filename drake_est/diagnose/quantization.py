"""Quantization of measured torques (a coarse ADC leaves a deterministic error below one step).

:func:`torque_step` finds the step of a torque on a grid; :func:`interval_fit` and :func:`interval_loglik` fit and
score a linear model by the likelihood of the quantized samples themselves (each reading says only that the torque
lay within half a step of it), where least squares on the rounded values is biased: a coarse ADC whose input
barely moves between steps flattens the slope of the torque over a range of speeds (closed-loop spec 1627 at
1000 Hz: least squares gives a viscous kv of 0.38 N m s/rad against the generator's 0.56, the interval fit 0.556).
"""
from __future__ import annotations

import numpy as np
import scipy.optimize
from scipy.special import log_ndtr

_LOG_SQRT_2PI = 0.5 * np.log(2.0 * np.pi)


def torque_step(y) -> float:
    """The quantization step of a torque signal (0 when it is not on a grid): the smallest gap between
    distinct values, when at least 99 % of the values sit on that grid."""
    u = np.unique(np.asarray(y, float))
    if u.size < 3 or u.size > 0.5 * y.size:
        return 0.0
    d = np.diff(u)
    step = float(np.min(d[d > 1e-12 * max(np.ptp(u), 1e-300)])) if np.any(d > 0) else 0.0
    if step <= 0:
        return 0.0
    k = (u - u[0]) / step
    return step if np.mean(np.abs(k - np.round(k)) < 0.05) > 0.99 else 0.0


def _log_prob_between(a, c):
    """log(Phi(c) - Phi(a)) for a < c, elementwise, without cancellation in either tail."""
    a = np.asarray(a, float)
    c = np.asarray(c, float)
    out = np.empty(np.broadcast(a, c).shape)
    up = a > 0     # both in the upper tail: Phi(c) - Phi(a) = Phi(-a) - Phi(-c)
    hi, lo = np.where(up, -a, c), np.where(up, -c, a)
    lh, ll = log_ndtr(hi), log_ndtr(lo)
    with np.errstate(divide="ignore"):
        out[...] = lh + np.log1p(-np.exp(np.minimum(ll - lh, -1e-300)))
    # an interval narrow against the noise: the midpoint rule, phi(m) (c - a), exact to O((c - a)^2) relative, where
    # the difference of the two probabilities cancels
    w = c - a
    narrow = w < 1e-3
    if np.any(narrow):
        m = 0.5 * (a + c)
        out[narrow] = (-0.5 * m * m - _LOG_SQRT_2PI + np.log(np.maximum(w, 1e-300)))[narrow]
    return out


def interval_loglik(X, coef, sigma: float, lo, hi) -> np.ndarray:
    """Per-sample log-likelihood of interval readings: the latent value ``X @ coef + e``, e ~ N(0, sigma^2), lay in
    ``[lo, hi]`` (a torque read by an ADC of step s: ``lo, hi = reading -/+ s / 2``)."""
    mu = np.asarray(X, float) @ np.asarray(coef, float)
    s = max(float(sigma), 1e-300)
    return _log_prob_between((np.asarray(lo, float) - mu) / s, (np.asarray(hi, float) - mu) / s)


def interval_nll_at(X, coef, sigma: float, lo, hi) -> float:
    """The negative log-likelihood of interval readings ``[lo, hi]`` under ``X @ coef`` and noise ``sigma`` (the sum of
    :func:`interval_loglik`, what :func:`interval_fit` minimizes)."""
    return -float(np.sum(interval_loglik(X, coef, sigma, lo, hi)))


def _nll_and_grad(theta, X, lo, hi, ridge=None):
    """Negative log-likelihood of :func:`interval_loglik` and its gradient in (coef, log sigma); ``ridge``: per-column
    weights w of a penalty sum(w coef^2) / (2 sigma^2) (the least-squares ridge as a Gaussian prior)."""
    b, log_s = theta[:-1], theta[-1]
    s = np.exp(log_s)
    mu = X @ b
    a, c = (lo - mu) / s, (hi - mu) / s
    lp = _log_prob_between(a, c)
    # phi(x) / P, from logs (P: the probability of the interval); the exponent is at most 0 up to rounding, clipped
    # so that a trial point of the line search far off cannot overflow
    pa = np.exp(np.minimum(-0.5 * a * a - _LOG_SQRT_2PI - lp, 700.0))
    pc = np.exp(np.minimum(-0.5 * c * c - _LOG_SQRT_2PI - lp, 700.0))
    d_mu = (pc - pa) / s                 # -(d lp / d mu)
    d_logs = c * pc - a * pa             # -(d lp / d log s)
    f, g_b, g_s = -float(lp.sum()), X.T @ d_mu, float(d_logs.sum())
    if ridge is not None:
        pen = float(ridge @ (b * b))
        f += 0.5 * pen / (s * s)
        g_b = g_b + ridge * b / (s * s)
        g_s -= pen / (s * s)
    return f, np.concatenate([g_b, [g_s]])


def interval_fit(X, lo, hi, coef0=None, nonneg=(), sigma0=None, ridge=None, max_iter: int = 1000):
    """Maximum-likelihood fit of ``X @ coef`` with Gaussian noise of unknown standard deviation to interval readings
    ``[lo, hi]`` (interval regression, an ordered probit with known cut points).  With the intervals of a quantized
    signal it uses what the readings hold, and no more: least squares on the rounded values treats the rounding
    error as noise, which it is not when the noise before the ADC is small against its step.  ``coef0``: start
    (default: least squares on the interval midpoints, with the bounds), ``sigma0`` its noise level; ``nonneg``: columns
    whose coefficients are kept >= 0; ``ridge``: per-column weights w of a penalty sum(w coef^2) / (2 sigma^2) (a
    least-squares ridge, :func:`drake_est.regression.ridge_solve`, carried over as a Gaussian prior).  A nested model
    started from the smaller one's optimum (its coefficients, zeros for the new columns) cannot end with a lower
    likelihood than it (the optimizer only descends from there).  Returns ``(coef, sigma)``; raises ValueError on empty or inverted intervals."""
    X = np.asarray(X, float)
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    if X.ndim != 2 or X.shape[0] != lo.size or lo.size != hi.size:
        raise ValueError(f"interval_fit: X is {X.shape}, lo {lo.shape}, hi {hi.shape}: one row per interval")
    if X.shape[0] <= X.shape[1]:
        raise ValueError(f"interval_fit: {X.shape[0]} intervals for {X.shape[1]} coefficients")
    if not np.all(hi > lo):
        raise ValueError("interval_fit: every interval needs hi > lo")
    # unit-RMS columns for the optimizer (constant columns keep their scale)
    scale = np.sqrt(np.mean(X * X, axis=0))
    scale[scale <= 0] = 1.0
    Xs = X / scale
    mid = 0.5 * (lo + hi)
    nonneg = sorted({int(i) for i in nonneg})
    if coef0 is None:
        # least squares on the midpoints with the same bounds
        lb = np.full(X.shape[1], -np.inf)
        lb[nonneg] = 0.0
        b0 = scipy.optimize.lsq_linear(Xs, mid, bounds=(lb, np.inf)).x if nonneg else \
            np.linalg.lstsq(Xs, mid, rcond=None)[0]
    else:
        b0 = np.asarray(coef0, float) * scale
        b0[nonneg] = np.maximum(b0[nonneg], 0.0)
    # the noise level between a millionth of the mean interval width and a thousand times the midpoints' spread
    # (the optimizer's line search stays where the likelihood is computed accurately)
    width = float(np.mean(hi - lo))
    log_s_bounds = (np.log(1e-6 * width), np.log(1e3 * max(float(np.std(mid)), width)))
    bounds = [(0.0, None) if i in nonneg else (None, None) for i in range(X.shape[1])] + [log_s_bounds]
    r0 = mid - Xs @ b0
    # the start's sigma: the midpoints' residual, at least a tenth of the mean interval width (or ``sigma0``)
    s0 = max(float(np.std(r0)), 0.1 * width, 1e-12) if sigma0 is None else float(sigma0)
    s0 = float(np.clip(s0, *np.exp(log_s_bounds)))
    # the ridge weights w of sum(w coef^2) in the scaled coefficients b = coef * scale
    rw = None if ridge is None else np.asarray(ridge, float) / (scale * scale)
    res = scipy.optimize.minimize(_nll_and_grad, np.concatenate([b0, [np.log(s0)]]), args=(Xs, lo, hi, rw),
                                  jac=True, method="L-BFGS-B", bounds=bounds, options={"maxiter": max_iter})
    return res.x[:-1] / scale, float(np.exp(res.x[-1]))


def interval_loglik_profiled(X, coef, lo, hi) -> tuple[float, float]:
    """The log-likelihood of interval readings ``[lo, hi]`` under ``X @ coef`` at the noise level they favour most:
    ``(max over sigma of sum interval_loglik, that sigma)``.  Two fitted models scored on the same held-out readings
    each at its own best noise level are compared by their predictions alone, not by the noise level one of them was
    given (one level for both favours the model it was fitted for).  The level is searched between a millionth of the
    mean interval width and ten widths, in log-sigma (bounded Brent search)."""
    X = np.asarray(X, float)
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    if X.shape[0] != lo.size or lo.size != hi.size or lo.size == 0:
        raise ValueError(f"interval_loglik_profiled: X is {X.shape}, lo {lo.shape}, hi {hi.shape}: one row per interval")
    if not np.all(hi > lo):
        raise ValueError("interval_loglik_profiled: every interval needs hi > lo")
    width = float(np.mean(hi - lo))
    # the prediction once, as the single column of interval_loglik's design (the search only moves sigma)
    mu = (X @ np.asarray(coef, float))[:, None]
    res = scipy.optimize.minimize_scalar(lambda ls: -float(np.sum(interval_loglik(mu, [1.0], np.exp(ls), lo, hi))),
                                         bounds=(np.log(1e-6 * width), np.log(10.0 * width)), method="bounded",
                                         options={"xatol": 1e-4})
    return -float(res.fun), float(np.exp(res.x))
