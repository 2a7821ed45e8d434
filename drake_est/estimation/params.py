"""Parameter estimation with filters (thesis Sec. 4.1: the filter's log-likelihood as an objective).

Every filter of :mod:`drake_est.estimation` returns ``log p(y_{0:T-1} | u, theta)`` (exact for the Kalman
filter, a Gaussian approximation for EKF/UKF, an unbiased estimate of the likelihood for the particle filter).
Two uses, after LowLevelParticleFilters.jl:

* :func:`maximize_loglik` -- maximum likelihood with scipy.optimize.  ``make_filter(theta)`` builds the filter
  for parameters theta.  For a particle filter keep the ``seed`` fixed inside ``make_filter``: its random draws
  depend only on (seed, t), so every theta is evaluated with *common random numbers* and the estimated
  log-likelihood is a smooth-ish deterministic function of theta (Nelder-Mead is the robust default).
* :func:`pmmh` -- particle-marginal Metropolis-Hastings (Andrieu, Doucet & Holenstein 2010): a random-walk
  MH chain on theta whose acceptance ratio uses the particle filter's likelihood estimate; the chain targets
  the exact posterior p(theta | y) because the estimate is unbiased.  Each proposal uses fresh random numbers
  (``make_filter(theta, seed)``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from drake_est.errors import DataError
from drake_est.progress import progress


def loglik_function(make_filter, u, y):
    """theta -> log-likelihood of (u, y) under ``make_filter(theta)``; -inf for parameters the filter
    refuses (e.g. a covariance that is not positive definite)."""
    def ll(theta):
        try:
            val = make_filter(np.asarray(theta, dtype=float)).loglik(u, y)
        except DataError:
            return -np.inf
        return float(val) if np.isfinite(val) else -np.inf
    return ll


@dataclass
class MLResult:
    """theta maximizing the log-likelihood, the maximum, and scipy's OptimizeResult."""
    theta: np.ndarray
    loglik: float
    n_evaluations: int
    optimizer: object


def maximize_loglik(make_filter, theta0, u, y, method: str = "Nelder-Mead", bounds=None,
                    options: dict | None = None) -> MLResult:
    """Maximum-likelihood parameters: argmax_theta log p(y | u, theta) with ``scipy.optimize.minimize``."""
    theta0 = np.atleast_1d(np.asarray(theta0, dtype=float))
    if not np.all(np.isfinite(theta0)):
        raise DataError("theta0 contains NaN/Inf")
    ll = loglik_function(make_filter, u, y)
    if not np.isfinite(ll(theta0)):
        raise DataError("the log-likelihood at theta0 is not finite: start from parameters the model accepts")

    def cost(th):
        v = ll(th)
        return 1e300 if not np.isfinite(v) else -v

    opts = {"xatol": 1e-4, "fatol": 1e-4, "maxiter": 400} if method == "Nelder-Mead" else {}
    opts.update(options or {})
    res = minimize(cost, theta0, method=method, bounds=bounds, options=opts)
    return MLResult(np.asarray(res.x), float(-res.fun), int(res.nfev), res)


@dataclass
class PMMHResult:
    """The chain (n_iter, d), the log-likelihood estimate of each state, and the acceptance rate."""
    chain: np.ndarray
    loglik: np.ndarray
    acceptance_rate: float

    def posterior_mean(self, burn_in: int = 0) -> np.ndarray:
        return self.chain[burn_in:].mean(axis=0)


def pmmh(make_filter, log_prior, theta0, u, y, n_iter: int, step_cov, seed: int = 0,
         show_progress: bool = True) -> PMMHResult:
    """Particle-marginal Metropolis-Hastings with a Gaussian random walk ``theta' = theta + N(0, step_cov)``.

    ``make_filter(theta, seed)`` builds a particle filter (a new seed per proposal keeps the likelihood
    estimates independent); ``log_prior(theta)`` returns -inf outside the support.  Accept with
    probability min(1, exp(ll' + lp' - ll - lp))."""
    theta = np.atleast_1d(np.asarray(theta0, dtype=float))
    d = theta.shape[0]
    step_cov = np.atleast_2d(np.asarray(step_cov, dtype=float))
    if step_cov.shape != (d, d):
        raise DataError(f"step_cov has shape {step_cov.shape}, expected ({d}, {d})")
    try:
        Ls = np.linalg.cholesky(step_cov)
    except np.linalg.LinAlgError:
        raise DataError("step_cov is not positive definite") from None
    if int(n_iter) < 1:
        raise DataError(f"n_iter must be >= 1, got {n_iter}")
    rng = np.random.default_rng([int(seed), 7])

    def evaluate(th, k):
        lp = float(log_prior(th))
        if not np.isfinite(lp):
            return -np.inf, -np.inf
        try:
            ll = float(make_filter(th, int(seed) * 1_000_003 + k).loglik(u, y))
        except DataError:
            return lp, -np.inf
        return lp, (ll if np.isfinite(ll) else -np.inf)

    lp, ll = evaluate(theta, 0)
    if not np.isfinite(lp + ll):
        raise DataError("theta0 has zero prior density or zero likelihood")
    chain = np.empty((int(n_iter), d))
    lls = np.empty(int(n_iter))
    acc = 0
    it = range(int(n_iter))
    for k in (progress(it, desc="PMMH", total=int(n_iter)) if show_progress else it):
        prop = theta + Ls @ rng.standard_normal(d)
        lp_p, ll_p = evaluate(prop, k + 1)
        if np.isfinite(lp_p + ll_p) and np.log(rng.random()) < (lp_p + ll_p) - (lp + ll):
            theta, lp, ll = prop, lp_p, ll_p
            acc += 1
        chain[k], lls[k] = theta, ll
    return PMMHResult(chain, lls, acc / int(n_iter))
