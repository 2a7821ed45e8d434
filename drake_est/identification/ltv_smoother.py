"""Squared-penalty LTV identification, thesis Eqs. (7.3), (7.5), (7.13) with priors (7.15)-(7.18): the
Kalman-smoother posterior of the parameter random walk (7.2)/(7.11), banded (block cyclic reduction) or as
the project's Kalman filter + RTS smoother (``method="rts"``).

Split out of :mod:`drake_est.identification.ltv`, which re-exports every name."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_est.errors import DataError, IdentifiabilityError
from drake_est.identification.ltv_banded import block_tridiag_solve, group_blocks, ungroup
from drake_est.identification.ltv_common import (TVRegressionResult, _Lambda, _apply_D, _as_regression,
                                                 _as_state_space, _check_lam, _finite, _gram, _poly, _reg_bands,
                                                 _to_ltv, check_identifiable)

_LOG2PI = np.log(2.0 * np.pi)


# =============================================================================================
# squared penalties: Kalman smoother (7.3), (7.5), (7.13), priors (7.15)-(7.18)
# =============================================================================================
def _prior_arrays(prior_mean, prior_cov, T, p, r, Phi_stats):
    """Evaluate the Gaussian prior N(mu_t, Sigma0_t) on k_t.  Returns (Pi (T,p,p), Pi mu (T,p,r), mu, S0).

    ``prior_mean`` (p, r) / (T, p, r) array or a callable t -> (mu_t, Sigma0_t); ``prior_cov``
    (p, p) / (T, p, p) (ignored for callables)."""
    if prior_mean is None:
        return None
    if callable(prior_mean):
        mus, covs = [], []
        for t in range(T):
            mu, S = prior_mean(t)
            mus.append(np.asarray(mu, float).reshape(p, r))
            covs.append(np.asarray(S, float).reshape(p, p))
        mu, S0 = np.array(mus), np.array(covs)
    else:
        mu = np.asarray(prior_mean, float)
        mu = np.broadcast_to(mu.reshape((-1, p, r) if mu.ndim == 3 or mu.size == T * p * r else (p, r)), (T, p, r))
        if prior_cov is None:
            raise DataError("prior_mean given without prior_cov")
        S0 = np.asarray(prior_cov, float)
        S0 = np.broadcast_to(S0 if S0.ndim == 3 else S0.reshape(p, p), (T, p, p))
    mu, S0 = _finite(mu, "prior mean"), _finite(S0, "prior covariance")
    try:
        Pi = np.linalg.solve(S0, np.broadcast_to(np.eye(p), (T, p, p)))
        np.linalg.cholesky(0.5 * (S0 + np.swapaxes(S0, 1, 2)))
    except np.linalg.LinAlgError:
        raise DataError("prior covariance must be positive definite at every time step") from None
    Pi = 0.5 * (Pi + np.swapaxes(Pi, 1, 2))
    return Pi, Pi @ mu, mu, S0


def _smooth_core(G, Bt, yy, N, lam, c, Lam, prior=None, sigma_e=None, want_cov=True,
                 want_loglik=True):
    """Posterior of k for min sum ||Y_t - Phi_t k_t||^2 + lam^2 sum ||P(z)k_t||^2_Lam (+ prior).

    G (T,p,p) = Phi^T Phi, Bt (T,p,r) = Phi^T Y, yy = ||Y||^2, N = number of scalar observations."""
    T, p, r = Bt.shape
    d = c.size - 1 if lam > 0 else 0
    s2_fixed = None if sigma_e is None else float(sigma_e) ** 2
    if prior is not None and s2_fixed is None:
        s2_fixed = 1.0
    Hb = [G.copy()] + [np.zeros((T, p, p)) for _ in range(d)]
    if d:
        bands = _reg_bands(c, T, Lam, lam ** 2)
        for o in range(d + 1):
            Hb[o] += bands[o]
    R = Bt.copy()
    if prior is not None:
        Pi, Pimu = prior[0], prior[1]
        Hb[0] = Hb[0] + s2_fixed * Pi
        R = R + s2_fixed * Pimu
    g = max(d, 1)
    D, L, Rg, _ = group_blocks(Hb, R, g)
    try:
        xg, Sg, _, logdet = block_tridiag_solve(D, L, Rg, want_cov=want_cov, want_logdet=want_loglik)
    except np.linalg.LinAlgError:
        raise IdentifiabilityError("the regularized normal equations are singular: some parameter is not "
                                   "excited at any time (see Sec. 7.3)") from None
    k, S = ungroup(xg, Sg, T, p)
    # objective value J = ||Y - Phi k||^2 + lam^2 sum ||P(z) k||^2_Lam  (+ prior term)
    fit = yy - 2.0 * np.sum(Bt * k) + np.sum(k * (G @ k))
    reg = 0.0
    if d:
        Dk = _apply_D(c, k)
        reg = lam ** 2 * float(np.sum(Dk * (Lam @ Dk)))
    J = float(fit + reg)
    pr = 0.0
    if prior is not None:
        e = k - prior[2]
        pr = float(np.sum(e * (prior[0] @ e)))
    loglik = None
    if s2_fixed is not None:
        s2 = s2_fixed
    else:
        s2 = J / max(N - d * p * r, 1)
    if want_loglik and prior is None and d > 0 and logdet is not None and not s2 > 0:
        loglik = float("nan")   # an exact fit (J = 0, too few samples): the likelihood is unbounded, undefined
    elif want_loglik and prior is None and d > 0 and logdet is not None:
        # increments w_t = P(z)k_t ~ N(0, s2/lam^2 Lam^{-1}); k -> (k_0..k_{d-1}, w) has Jacobian c_d^((T-d)p)
        ld_reg = (T - d) * float(np.linalg.slogdet(Lam)[1]) + 2.0 * (T - d) * p * np.log(abs(c[-1]))
        loglik = (-(N - d * p * r) / 2.0 * (_LOG2PI + np.log(s2)) - J / (2.0 * s2)
                  + r * ((T * p - d * p) / 2.0 * np.log(lam ** 2) + 0.5 * ld_reg - 0.5 * logdet))
    cov = s2 * S if S is not None else None
    return k, cov, J + s2_fixed * pr if prior is not None else J, loglik, s2


def _smooth_rts(Phi, Y, lam, c, Lam, prior=None, sigma_e=None, p0=None):
    """Kalman filter + RTS smoother on the parameter-state model (7.2)/(7.11) (per-step loop)."""
    from drake_est.estimation.kalman import KalmanFilter, rts_smooth, FilterResult

    T, m, p = Phi.shape
    r = Y.shape[2]
    d = c.size - 1
    s2 = 1.0 if sigma_e is None else float(sigma_e) ** 2
    q = d * p
    # companion realization of P(z)^{-1}: s_t = [k_t, ..., k_{t+d-1}]
    F = np.zeros((q, q))
    for i in range(d - 1):
        F[i * p:(i + 1) * p, (i + 1) * p:(i + 2) * p] = np.eye(p)
    for j in range(d):
        F[(d - 1) * p:, j * p:(j + 1) * p] = -c[j] / c[d] * np.eye(p)
    Q = np.zeros((q, q))
    Q[(d - 1) * p:, (d - 1) * p:] = s2 / (lam ** 2 * c[d] ** 2) * np.linalg.solve(Lam, np.eye(p))
    C = np.zeros((T, m, q))
    C[:, :, :p] = Phi
    if p0 is None:
        gs = np.einsum("tmi,tmi->", Phi, Phi) / (T * p)
        p0 = 1e9 * s2 / max(gs, 1e-300)
    kf = KalmanFilter(F, C, Q, s2 * np.eye(m), np.zeros((q, r)), p0 * np.eye(q))
    Csel = np.zeros((p, q))
    Csel[:, :p] = np.eye(p)
    x, P = kf.x0.copy(), kf.P0.copy()
    xf = np.empty((T, q, r)); Pf = np.empty((T, q, q))
    xp = np.empty((T + 1, q, r)); Pp = np.empty((T + 1, q, q))
    ll = 0.0
    for t in range(T):
        xp[t], Pp[t] = x, P
        x, P, l = kf.correct(x, P, Y[t], None, t)
        ll += l
        if prior is not None:       # Eqs. (7.16)-(7.18): a second "measurement" mu_0(z_t)
            x, P, _ = kf.correct(x, P, prior[2][t], None, t, C=Csel, R2=prior[3][t])
        xf[t], Pf[t] = x, P
        x, P = kf.predict(x, P, None, t)
    xp[T], Pp[T] = x, P
    xs, Ps = rts_smooth(FilterResult(xf, Pf, xp, Pp, ll), F)
    return xs[:, :p, :], Ps[:, :p, :p], ll


def tv_regression_smoother(Phi, y, lam, order=1, P=None, Lambda=None, prior_mean=None, prior_cov=None,
                           sigma_e=None, method="banded", check=True, names=None, want_cov=True):
    """Solve min_k sum_t ||y_t - Phi_t k_t||^2 + lam^2 sum_t ||P(z) k_t||^2_Lambda.

    Eq. (7.3) for ``order=1``, (7.5) for ``order=2``, the general operator (7.13) for ``P=[c_0..c_d]``
    (P(z) = sum c_j z^j).  ``Lambda`` (p x p, positive definite, or a length-p vector) weights the
    parameters individually (Sec. 7.9).  A Gaussian prior k_t ~ N(mu_t, Sigma0_t) (Eqs. (7.15)-(7.18))
    is given by ``prior_mean`` (p,) or (T, p) with ``prior_cov`` (p, p) or (T, p, p), or by a callable
    ``prior_mean(t) -> (mu_t, Sigma0_t)``; the prior covariance is absolute, so the measurement noise
    ``sigma_e`` (default 1) sets the scale of the data term.

    Phi: (T, p) for scalar y or (T, m, p); y: (T,) or (T, m).  Returns :class:`TVRegressionResult`
    with the smoothed mean ``k`` (T, p), covariance ``cov`` (T, p, p) and, without prior, the
    diffuse log-likelihood used by :func:`tv_select_lambda_ml` (noise variance profiled out unless
    ``sigma_e`` is given)."""
    Phi, Y = _as_regression(Phi, y)
    res = _tv_smooth(Phi, Y, lam, order, P, Lambda, prior_mean, prior_cov, sigma_e, method, check, names,
                     want_cov)
    k = res.k[:, :, 0]
    return TVRegressionResult(k, res.cov, res.cost, res.lam, res.loglik, res.sigma2, res.info)


def _tv_smooth(Phi, Y, lam, order, P, Lambda, prior_mean, prior_cov, sigma_e, method, check, names,
               want_cov=True, want_loglik=True, what=None):
    lam = _check_lam(lam)
    T, m, p = Phi.shape
    r = Y.shape[2]
    c = _poly(order, P)
    Lam = _Lambda(Lambda, p)
    prior = _prior_arrays(prior_mean, prior_cov, T, p, r, None)
    if lam == 0 and prior is None:
        if T * m < T * p or np.min(np.linalg.eigvalsh(np.einsum("tmi,tmj->tij", Phi, Phi))) <= 0:
            raise IdentifiabilityError(
                f"lam = 0 (no regularization) leaves {T * p} parameters for {T * m} equations: "
                f"every time step would need its own full-rank regression; use lam > 0")
    G = _gram(Phi)
    if check and prior is None and lam > 0:
        check_identifiable(Phi, c, names, G=G,
                           what=what or f"time-varying regression (order-{c.size - 1} penalty)")
    if method == "banded":
        Bt = np.matmul(np.swapaxes(Phi, 1, 2), Y)
        k, cov, J, ll, s2 = _smooth_core(G, Bt, float(np.sum(Y * Y)), T * m * r, lam, c, Lam, prior, sigma_e,
                                         want_cov=want_cov, want_loglik=want_loglik)
    elif method == "rts":
        if lam == 0:
            raise DataError("method='rts' needs lam > 0 (a parameter random walk)")
        k, cov, ll = _smooth_rts(Phi, Y, lam, c, Lam, prior, sigma_e)
        res = Phi @ k - Y
        J = float(np.sum(res ** 2) + lam ** 2 * np.sum(_apply_D(c, k) * (Lam @ _apply_D(c, k))))
        s2 = 1.0 if sigma_e is None else float(sigma_e) ** 2
        if sigma_e is None and prior is None:       # profile the noise variance as the banded path does
            s2 = J / max(T * m * r - (c.size - 1) * p * r, 1)
            cov = s2 * cov
    else:
        raise DataError(f"method must be 'banded' or 'rts', got {method!r}")
    return _Raw(k, cov, J, lam, ll, s2, {"method": method, "order": c.size - 1, "P": c.tolist()})


@dataclass
class _Raw:
    k: np.ndarray
    cov: np.ndarray | None
    cost: float
    lam: float
    loglik: float | None
    sigma2: float | None
    info: dict


def ltv_smoother(x, u, lam, order=1, P=None, Lambda=None, prior=None, prior_cov=None, sigma_e=None,
                 y=None, method="banded", check=True):
    """LTV identification by the Kalman smoother, Eqs. (7.3)/(7.5)/(7.13) on the model (7.1)-(7.2).

    x: (T+1, n) states and u: (T, m) inputs (or x, u, y of equal length with y the measured next
    state).  ``Lambda`` (p x p, p = n+m) weights the parameters of each row of [A B] (Sec. 7.9).
    ``prior``: dynamics prior (7.15): an (n, n+m) matrix [A0 B0] or (T, n, n+m) array with
    ``prior_cov`` (p, p) (shared by the rows), or a callable ``prior(t, x_t, u_t) -> ([A0 B0], cov)``,
    e.g. the Jacobian of a learned model.  Returns :class:`LtvResult` with A_t, B_t, the
    covariance of k_t and the log-likelihood."""
    phi, Yn, n, m, names = _as_state_space(x, u, y)
    T, p = phi.shape
    Phi = phi[:, None, :]
    Y = Yn[:, None, :]
    pm, pc = None, prior_cov
    if prior is not None:
        if callable(prior):
            def pm(t):
                AB, S = prior(t, phi[t, :n], phi[t, n:])
                return np.asarray(AB, float).reshape(n, p).T, S
        else:
            AB = np.asarray(prior, float)
            pm = np.swapaxes(AB.reshape(-1, n, p), 1, 2) if AB.ndim == 3 else AB.reshape(n, p).T
    res = _tv_smooth(Phi, Y, lam, order, P, Lambda, pm, pc, sigma_e, method, check, names,
                     what=f"LTV problem ({'7.3' if order == 1 and P is None else '7.5' if order == 2 and P is None else '7.13'})")
    return _to_ltv(res.k, res.cov, n, m, res.cost, res.lam, res.loglik, res.sigma2, res.info)


# ---------------------------------------------------------------------------------------------
