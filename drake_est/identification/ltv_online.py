"""Causal (online) parameter Kalman filter of the LTV model (7.2), shared by the ``LtvIdentifier`` Drake
system; each step is the project's Kalman prediction and Joseph-form correction.

Split out of :mod:`drake_est.identification.ltv`, which re-exports every name."""
from __future__ import annotations

import numpy as np

from drake_est.errors import DataError
from drake_est.identification.ltv_common import _Lambda, _as_state_space, _check_lam, _to_ltv


# =============================================================================================
# causal (online) parameter Kalman filter, shared by the LtvIdentifier Drake system
# =============================================================================================
def ltv_filter_init(n, m, k0=None, p0=1e4):
    """Initial (k (p, n), P (p, p)) of the online parameter filter; k0 an (n, n+m) [A0 B0] or None."""
    p = n + m
    k = np.zeros((p, n)) if k0 is None else np.asarray(k0, float).reshape(n, p).T.copy()
    return k, float(p0) * np.eye(p)


def ltv_filter_step(k, P, x, u, x_next, lam, sigma_e=1.0, Lambda=None):
    """One step of the Kalman filter on the parameter random walk (7.2), H = I, shared row covariance.

    Time update P += sigma_e^2 / lam^2 Lambda^{-1} (the drift of k between steps), then the measurement
    update with the regression x_next = [A B] [x; u] + e in Joseph form.  ``k`` is (p, n) = [A B]^T,
    ``P`` (p, p) the covariance of each row of [A B].  Returns (k_{t|t}, P_{t|t}, innovation)."""
    from drake_est.estimation.kalman import kalman_correct, kalman_predict

    phi = np.concatenate([np.atleast_1d(x), np.atleast_1d(u)])
    s2 = float(sigma_e) ** 2
    p = P.shape[0]
    # the project's Kalman steps: random-walk prediction (A = I), then the Joseph-form correction with the
    # regression row phi^T as a 1 x p measurement matrix and the n state components as r = n columns
    k, P = kalman_predict(k, P, np.eye(p), s2 / float(lam) ** 2 * np.linalg.solve(_Lambda(Lambda, p), np.eye(p)))
    e = np.atleast_1d(x_next) - k.T @ phi
    k, P, _ = kalman_correct(k, P, np.atleast_1d(x_next)[None, :], phi[None, :], np.array([[s2]]))
    return k, P, e


def ltv_filter(x, u, lam, sigma_e=1.0, Lambda=None, k0=None, p0=1e4, y=None):
    """Causal (filtering) estimates A_{t|t}, B_{t|t} over a whole log: what :class:`LtvIdentifier`
    outputs online.  Returns an :class:`LtvResult` whose ``cov_row`` is the filter covariance."""
    phi, Yn, n, m, _ = _as_state_space(x, u, y)
    lam = _check_lam(lam)
    if lam <= 0:
        raise DataError("the online filter needs lam > 0")
    T, p = phi.shape
    k, P = ltv_filter_init(n, m, k0, p0)
    ks = np.empty((T, p, n))
    Ps = np.empty((T, p, p))
    for t in range(T):
        k, P, _ = ltv_filter_step(k, P, phi[t, :n], phi[t, n:], Yn[t], lam, sigma_e, Lambda)
        ks[t], Ps[t] = k, P
    return _to_ltv(ks, Ps, n, m, float("nan"), lam)
