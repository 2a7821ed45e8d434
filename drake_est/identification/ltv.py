"""Identification of linear time-varying (LTV) models, thesis Ch. 7.

Two layers:

* **Time-varying linear regression** ``y_t = Phi_t k_t + e_t`` with ``Phi_t`` (m x p) per time step
  (``tv_regression_*``): the general form of (7.2), also used for e.g. friction
  ``Phi_t = [v_t, sign(v_t)]``.
* **State-space LTV models** ``x_{t+1} = A_t x_t + B_t u_t + v_t`` with
  ``k_t = vec([A_t B_t]^T)`` (Eq. (7.1), ``ltv_*``).  Every row of ``[A B]`` shares the regressor
  ``phi_t = [x_t; u_t]``, so the rows are solved together with one shared (p x p) covariance,
  p = n + m (the Kronecker structure of (7.2)).

Problems (Table 7.1):

===========================  ======================================  ======================================
problem                      regression                              state space
===========================  ======================================  ======================================
(7.3)/(7.5)/(7.13) squared   :func:`tv_regression_smoother`          :func:`ltv_smoother`
(7.6)/(7.9) group lasso      :func:`tv_regression_group_lasso`       :func:`ltv_group_lasso`
(7.8) known # of switches    :func:`tv_regression_segments`          :func:`ltv_segments`
(7.10) two-step refinement   :func:`refine_with_knots`               :func:`ltv_refine_with_knots`
lambda by max. likelihood    :func:`tv_select_lambda_ml`             :func:`ltv_select_lambda_ml`
===========================  ======================================  ======================================

The squared problems are the negative log-likelihood of the parameter random walk (7.2)
(or (7.11) for (7.5)), so the solution is the Kalman-smoother posterior mean, with the
posterior covariance.  ``method="banded"`` (default) computes that posterior from the
block-banded information form by block cyclic reduction (vectorized, O(T) work,
see :mod:`drake_est.identification.ltv_banded`); ``method="rts"`` runs the textbook
Kalman filter + RTS smoother of :mod:`drake_est.estimation.kalman` on the
parameter-state model (a per-step Python loop; identical results up to the
approximately diffuse initial covariance).  The convex nonsmooth problems are solved by a
working-set primal-dual Newton method with a duality-gap certificate (first differences, (7.6))
or by ADMM (:func:`tv_regression_group_lasso`); :func:`tv_regression_qp_reference` /
:func:`tv_regression_group_lasso_reference` write the same problems as Drake
``MathematicalProgram`` s (the reference the tests compare against).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from itertools import combinations

import numpy as np

from drake_est.errors import DataError, IdentifiabilityError
from drake_est.identification.ltv_banded import (banded_lower, block_tridiag_solve, group_blocks,
                                                  ungroup)

_LOG2PI = np.log(2.0 * np.pi)


# =============================================================================================
# input handling
# =============================================================================================
def _finite(a, name):
    a = np.asarray(a, dtype=float)
    if a.size and not np.all(np.isfinite(a)):
        bad = np.argwhere(~np.isfinite(a))[0]
        raise DataError(f"{name} contains NaN/Inf (first at index {tuple(int(i) for i in bad)})")
    return a


def _as_regression(Phi, y):
    """Phi (T, p) or (T, m, p); y (T,) or (T, m) -> Phi (T, m, p), Y (T, m, 1)."""
    Phi = _finite(Phi, "Phi")
    y = _finite(y, "y")
    if Phi.ndim == 2:
        Phi = Phi[:, None, :]
    if Phi.ndim != 3:
        raise DataError(f"Phi must be (T, p) or (T, m, p), got shape {Phi.shape}")
    if y.ndim == 1:
        y = y[:, None]
    if y.ndim != 2:
        raise DataError(f"y must be (T,) or (T, m), got shape {y.shape}")
    if y.shape[0] != Phi.shape[0]:
        raise DataError(f"Phi has {Phi.shape[0]} time steps but y has {y.shape[0]}")
    if y.shape[1] != Phi.shape[1]:
        raise DataError(f"Phi has {Phi.shape[1]} outputs per step but y has {y.shape[1]}")
    if Phi.shape[0] < 2:
        raise DataError(f"need at least 2 time steps, got {Phi.shape[0]}")
    return Phi, y[:, :, None]


def _as_state_space(x, u, y=None):
    """Return (phi (T, p), Y (T, n), n, m, names) for x_{t+1} = A_t x_t + B_t u_t.

    With ``y=None``, x has one more row than u (x_0..x_T, u_0..u_{T-1}); otherwise y holds the
    measured next states and x, u, y have equal length."""
    x = _finite(x, "x")
    if x.ndim == 1:
        x = x[:, None]
    if u is None:
        u = np.zeros((x.shape[0] - (1 if y is None else 0), 0))
    u = _finite(u, "u")
    if u.ndim == 1:
        u = u[:, None]
    if y is None:
        if x.shape[0] != u.shape[0] + 1:
            raise DataError(f"x must have one more sample than u (x_0..x_T, u_0..u_(T-1)); "
                            f"got {x.shape[0]} states and {u.shape[0]} inputs")
        Y = x[1:]
        X = x[:-1]
    else:
        Y = _finite(y, "y")
        if Y.ndim == 1:
            Y = Y[:, None]
        if not (x.shape[0] == u.shape[0] == Y.shape[0]):
            raise DataError(f"x, u and y must have equal length when y is given; got {x.shape[0]}, "
                            f"{u.shape[0]}, {Y.shape[0]}")
        if Y.shape[1] != x.shape[1]:
            raise DataError(f"y has {Y.shape[1]} columns but the state has {x.shape[1]}")
        X = x
    n, m = X.shape[1], u.shape[1]
    if X.shape[0] < 2:
        raise DataError(f"need at least 2 transitions, got {X.shape[0]}")
    phi = np.hstack([X, u])
    names = [f"x{i + 1}" for i in range(n)] + [f"u{j + 1}" for j in range(m)]
    return phi, Y, n, m, names


def _poly(order=1, P=None):
    """Coefficients c_0..c_d of P(z) = sum_j c_j z^j (Eq. (7.13)); default (z - 1)^order."""
    if P is not None:
        c = np.atleast_1d(np.asarray(P, dtype=float))
        if c.ndim != 1 or c.size < 2 or c[-1] == 0 or not np.all(np.isfinite(c)):
            raise DataError("P must list the coefficients c_0..c_d of P(z) = sum c_j z^j with c_d != 0 and d >= 1")
        return c
    if order not in (1, 2, 3):
        raise DataError(f"order must be 1 (first differences) or 2 (second differences), got {order}")
    return np.array({1: [-1.0, 1.0], 2: [1.0, -2.0, 1.0], 3: [-1.0, 3.0, -3.0, 1.0]}[order])


def _Lambda(Lambda, p):
    if Lambda is None:
        return np.eye(p)
    L = np.asarray(Lambda, dtype=float)
    if L.ndim == 1:
        L = np.diag(L)
    if L.shape != (p, p) or not np.all(np.isfinite(L)):
        raise DataError(f"Lambda must be a positive-definite ({p}, {p}) matrix or a length-{p} vector, got shape {L.shape}")
    L = 0.5 * (L + L.T)
    if np.linalg.eigvalsh(L)[0] <= 0:
        raise DataError("Lambda must be positive definite (Sec. 7.9)")
    return L


def _check_lam(lam):
    lam = float(lam)
    if not np.isfinite(lam) or lam < 0:
        raise DataError(f"lam must be a finite number >= 0, got {lam}")
    return lam


# =============================================================================================
# regularizer, identifiability
# =============================================================================================
def _reg_bands(c, T, Lam, scale):
    """Block bands of lam^2 sum_t ||P(z) k_t||^2_Lambda: list over offset o of (T, p, p)."""
    d = c.size - 1
    p = Lam.shape[0]
    bands = []
    for o in range(d + 1):
        coef = np.zeros(T)
        for j in range(d - o + 1):
            coef[j:j + T - d] += c[j + o] * c[j]
        bands.append(scale * coef[:, None, None] * Lam)
    return bands


def _nullspace_basis(c, T):
    """Orthonormal basis (T, d) of sequences with P(z) s = 0 (the regularizer's null space).

    Each basis sequence is generated by the all-pole recursion sum_j c_j s_{t+j} = 0 from a unit
    initial condition (scipy.signal.lfilter, no Python loop over t)."""
    from scipy.signal import lfilter

    d = c.size - 1
    a = c[::-1] / c[d]                               # s_t = -sum_{j>=1} a_j s_{t-j} + in_t
    N = np.zeros((T, d))
    for i in range(d):
        init = np.zeros(d)
        init[i] = 1.0
        inp = np.zeros(T)
        for t in range(d):                           # inputs that reproduce the initial values
            inp[t] = init[t] + sum(a[j] * init[t - j] for j in range(1, t + 1))
        with np.errstate(all="ignore"):
            N[:, i] = lfilter([1.0], a, inp)
    if not np.all(np.isfinite(N)) or np.abs(N).max() > 1e150:
        return None
    q, _ = np.linalg.qr(N / np.maximum(np.abs(N).max(axis=0), 1e-300))
    return q


def _gram(Phi):
    """Phi_t^T Phi_t for all t: (T, p, p)."""
    return np.matmul(np.swapaxes(Phi, 1, 2), Phi)


def check_identifiable(Phi, c, names=None, rtol=1e-10, what="problem", G=None):
    """Props. 1-2 of Sec. 7.3: the regularized problem has a unique minimum iff no parameter
    trajectory in the null space of the regularizer is invisible in the data.

    For first differences this is the LTI condition sum_t Phi_t^T Phi_t > 0 (Prop. 1), for second
    differences the condition of Prop. 2.  Raises :class:`IdentifiabilityError` naming the
    regressor direction that is not excited."""
    T, m, p = Phi.shape
    names = names or [f"k{i + 1}" for i in range(p)]
    G = _gram(Phi) if G is None else G
    Nb = _nullspace_basis(c, T)
    if Nb is None:
        return
    d = Nb.shape[1]
    NN = (Nb[:, :, None] * Nb[:, None, :]).reshape(T, d * d)
    gram = (NN.T @ G.reshape(T, p * p)).reshape(d, d, p, p).transpose(0, 2, 1, 3).reshape(d * p, d * p)
    w, V = np.linalg.eigh(0.5 * (gram + gram.T))
    scale = max(w[-1], 1e-300)
    if w[0] > rtol * scale * max(1, d * p):
        return
    v = V[:, 0].reshape(d, p)
    comp = v[np.argmax(np.linalg.norm(v, axis=1))]
    comp = comp / np.abs(comp).max()
    top = np.argsort(-np.abs(comp))[:4]
    combo = " ".join(f"{comp[i]:+.2f}*{names[i]}" for i in top if abs(comp[i]) > 1e-3)
    rank = int(np.sum(w > rtol * scale * max(1, d * p)))
    raise IdentifiabilityError(
        f"{what} is not identifiable (Sec. 7.3, Prop. {1 if d == 1 else 2}): the regressor direction "
        f"[{combo}] is not excited (rank {rank} of {d * p}); add excitation, a prior, or drop that regressor")


# =============================================================================================
# results
# =============================================================================================
@dataclass
class TVRegressionResult:
    """Solution of a time-varying regression.  ``k`` (T, p) [(T, p, r) for r right-hand sides],
    ``cov`` (T, p, p) posterior covariance of k_t (shared by the r columns) or None,
    ``cost`` the objective value, ``loglik`` the (diffuse) data log-likelihood or None,
    ``sigma2`` the noise variance used for ``cov`` (estimated when not given)."""
    k: np.ndarray
    cov: np.ndarray | None
    cost: float
    lam: float
    loglik: float | None = None
    sigma2: float | None = None
    info: dict = field(default_factory=dict)

    def change_points(self, **kw):
        return change_points(self.k, **kw)


@dataclass
class LtvResult:
    """An identified LTV model x_{t+1} = A[t] x_t + B[t] u_t.

    ``A`` (T, n, n), ``B`` (T, n, m), ``k`` (T, K) = vec([A B]^T) per step (K = n(n+m)),
    ``cov`` (T, K, K) = I_n kron ``cov_row`` (posterior covariance of k_t) or None."""
    A: np.ndarray
    B: np.ndarray
    k: np.ndarray
    cov: np.ndarray | None
    cov_row: np.ndarray | None
    cost: float
    lam: float
    loglik: float | None = None
    sigma2: float | None = None
    change_times: list = field(default_factory=list)
    info: dict = field(default_factory=dict)

    def predict(self, x, u):
        """One-step predictions x_hat_{t+1} = A_t x_t + B_t u_t for t < T."""
        x = np.asarray(x, float)[: self.A.shape[0]]
        u = np.asarray(u, float).reshape(x.shape[0], -1)[: self.A.shape[0]]
        return np.einsum("tij,tj->ti", self.A, x) + np.einsum("tij,tj->ti", self.B, u)

    def simulate(self, x0, u):
        """Simulate the model from x0 with inputs u (T, m) (open loop, no noise)."""
        u = np.asarray(u, float).reshape(min(len(u), self.A.shape[0]), -1)
        xs = np.empty((u.shape[0] + 1, self.A.shape[1]))
        xs[0] = x0
        for t in range(u.shape[0]):
            xs[t + 1] = self.A[t] @ xs[t] + self.B[t] @ u[t]
        return xs


def _to_ltv(kk, cov_row, n, m, cost, lam, loglik=None, sigma2=None, info=None):
    """kk (T, p, n) -> LtvResult."""
    AB = np.swapaxes(kk, 1, 2)                       # (T, n, p)
    T = AB.shape[0]
    cov = None
    if cov_row is not None:
        cov = np.einsum("ij,tab->tiajb", np.eye(n), cov_row).reshape(T, n * (n + m), n * (n + m))
    return LtvResult(AB[:, :, :n].copy(), AB[:, :, n:].copy(), AB.reshape(T, -1).copy(), cov, cov_row,
                     cost, lam, loglik, sigma2, info=info or {})


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
    if want_loglik and prior is None and d > 0 and logdet is not None:
        # increments w_t = P(z)k_t ~ N(0, s2/lam^2 Lam^{-1}); k -> (k_0..k_{d-1}, w) has Jacobian c_d^((T-d)p)
        ld_reg = (T - d) * float(np.linalg.slogdet(Lam)[1]) + 2.0 * (T - d) * p * np.log(abs(c[-1]))
        loglik = (-(N - d * p * r) / 2.0 * (_LOG2PI + np.log(s2)) - J / (2.0 * s2)
                  + r * ((T * p - d * p) / 2.0 * np.log(lam ** 2) + 0.5 * ld_reg - 0.5 * logdet))
    cov = s2 * S if S is not None else None
    return k, cov, J + s2_fixed * pr if prior is not None else J, loglik, s2


def _apply_D(c, k):
    """(P(z) k)_t = sum_j c_j k_{t+j}, t = 0..T-d-1."""
    d = c.size - 1
    T = k.shape[0]
    out = c[0] * k[: T - d]
    for j in range(1, d + 1):
        out = out + c[j] * k[j: T - d + j]
    return out


def _apply_DT(c, z, T):
    d = c.size - 1
    out = np.zeros((T,) + z.shape[1:])
    for j in range(d + 1):
        out[j: T - d + j] += c[j] * z
    return out


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
# lambda by maximum likelihood (Fig. 7.4)
# ---------------------------------------------------------------------------------------------
def _select(Phi, Y, lams, order, P, Lambda, sigma_e, refine):
    from scipy.optimize import minimize_scalar

    lams = np.asarray(lams if lams is not None else np.logspace(-2, 4, 25), dtype=float)
    if np.any(lams <= 0):
        raise DataError("candidate lambdas must be > 0")

    def ll(lam):
        return _tv_smooth(Phi, Y, lam, order, P, Lambda, None, None, sigma_e, "banded", False, None,
                          want_cov=False).loglik

    check_identifiable(Phi, _poly(order, P))
    lls = np.array([ll(l) for l in lams])
    i = int(np.argmax(lls))
    best = float(lams[i])
    if refine and 0 < i < len(lams) - 1:
        r = minimize_scalar(lambda s: -ll(np.exp(s)), bounds=(np.log(lams[i - 1]), np.log(lams[i + 1])),
                            method="bounded", options={"xatol": 1e-3})
        if -r.fun >= lls[i]:
            best = float(np.exp(r.x))
    return best, lams, lls


def tv_select_lambda_ml(Phi, y, lams=None, order=1, P=None, Lambda=None, sigma_e=None, refine=True):
    """Maximum-likelihood lambda for :func:`tv_regression_smoother` (Fig. 7.4).

    Evaluates the diffuse log-likelihood of the random-walk model on the grid ``lams`` (default
    logspace(-2, 4, 25)) and refines the best point by a bounded 1-D search in log(lambda).
    Returns (lam_best, lams, logliks)."""
    Phi, Y = _as_regression(Phi, y)
    return _select(Phi, Y, lams, order, P, Lambda, sigma_e, refine)


def ltv_select_lambda_ml(x, u, lams=None, order=1, P=None, Lambda=None, sigma_e=None, y=None, refine=True):
    """Maximum-likelihood lambda for :func:`ltv_smoother` (Fig. 7.4); returns (lam, lams, logliks)."""
    phi, Yn, n, m, names = _as_state_space(x, u, y)
    return _select(phi[:, None, :], Yn[:, None, :], lams, order, P, Lambda, sigma_e, refine)


# =============================================================================================
# group lasso (7.6)/(7.9) by ADMM
# =============================================================================================
@dataclass
class GroupLassoResult:
    """Solution of (7.6)/(7.9).  ``k`` (T, p[, r]); ``dk`` (T-d, p[, r]) the split variable z = P(z)k
    of ADMM, exactly sparse (zero where the solution does not change); ``cost`` the objective at k;
    ``change_times`` indices t where k_t differs from k_{t-1} (first differences) or the slope
    changes (second differences)."""
    k: np.ndarray
    dk: np.ndarray
    cost: float
    lam: float
    iterations: int
    converged: bool
    change_times: list = field(default_factory=list)
    info: dict = field(default_factory=dict)

    def change_points(self, **kw):
        return change_points(self.k, **kw)


def _group_lasso_cost(G, Bt, yy, k, c, lam):
    fit = yy - 2.0 * np.sum(Bt * k) + np.sum(k * (G @ k))
    Dk = _apply_D(c, k)
    return float(fit + lam * np.sum(np.sqrt(np.sum(Dk.reshape(Dk.shape[0], -1) ** 2, axis=1))))


def _nrm(a):
    """Euclidean norm without BLAS (threaded BLAS dot products are very slow on a loaded machine)."""
    return float(np.sqrt(np.sum(a * a)))


def _admm(G, Bt, yy, lam, c, rho=None, max_iter=5000, eps_abs=1e-6, eps_rel=1e-5, linearized=False,
          alpha=1.6, adapt=False, ftol=1e-6, gap_tol=None):
    """ADMM for min ||Y - Phi k||^2 + lam sum ||(P(z)k)_t||_2 with the split z = P(z)k.

    Standard ADMM (default) solves the k-update exactly with one banded Cholesky factorization of
    2 Phi^T Phi + rho D^T D (LAPACK pbtrf/pbtrs; refactored only when rho adapts), uses
    over-relaxation ``alpha`` and a dual warm start (the scaled dual u is initialized from the
    stationarity condition D^T u = -grad f / rho at the first iterate, projected on the balls
    ||u_t|| <= lam/rho).  ``linearized=True`` is linearized ADMM (Parikh & Boyd, as in App. 7.A):
    the k-update becomes a block-diagonal prox step of f with step mu = 1 / (rho ||D||^2).
    Stops when the primal and dual residuals fall below eps_abs*sqrt(size) + eps_rel*scale, or when
    the objective changed by less than ``ftol`` (relative) over the last 10 iterations; with ``gap_tol``
    (first differences only) instead when the relative duality gap of :func:`_gl_gap` is <= gap_tol."""
    from scipy.linalg import lapack

    T, p, r = Bt.shape
    d = c.size - 1
    Te = T - d
    nrm_c = float(np.sum(np.abs(c))) ** 2            # ||D||^2 bound
    scale = float(np.mean(np.trace(G, axis1=1, axis2=2))) / p + 1e-300
    if rho is None:
        # heuristic, tuned on the Sec. 7.6 system (lam = 10..30): ~150-250 iterations to 1e-4 in cost
        rho = 30.0 * max(lam, 1e-12) * scale
    eye = np.eye(p)

    def factor(rho):
        if linearized:
            mu = 1.0 / (rho * nrm_c)
            return ("diag", np.linalg.cholesky(2.0 * G + eye / mu), mu)
        bands = _reg_bands(c, T, eye, rho)
        cb, info = lapack.dpbtrf(banded_lower([2.0 * G + bands[0]] + bands[1:]), lower=1)
        if info != 0:
            raise IdentifiabilityError("the ADMM system 2 Phi^T Phi + rho D^T D is singular: the LTI problem "
                                       "is not identifiable (Sec. 7.3)")
        return ("band", cb, None)

    def kupdate(fac, k, z, u):
        if fac[0] == "band":
            rhs = 2.0 * Bt + rho * _apply_DT(c, z - u, T)
            sol, _ = lapack.dpbtrs(fac[1], rhs.reshape(T * p, r), lower=1)
            return sol.reshape(T, p, r)
        mu = fac[2]
        v = k - (mu * rho) * _apply_DT(c, _apply_D(c, k) - z + u, T)
        w = np.linalg.solve(fac[1], 2.0 * Bt + v / mu)
        return np.linalg.solve(np.swapaxes(fac[1], 1, 2), w)

    def project(u, thr):
        nu = np.sqrt(np.einsum("tpr,tpr->t", u, u))
        return u * np.minimum(1.0, thr / np.maximum(nu, 1e-300))[:, None, None]

    fac = factor(rho)
    zero = np.zeros((Te, p, r))
    if linearized:
        k = np.linalg.solve(G + 1e-6 * scale * eye, Bt)
    else:
        k = kupdate(fac, None, zero, zero)
    z = _apply_D(c, k)
    thr = lam / rho
    # dual warm start: D^T u = -grad f(k) / rho  (least squares via the banded D D^T)
    g = 2.0 * (G @ k - Bt)
    ac = np.array([np.dot(c[o:], c[:c.size - o]) for o in range(d + 1)])
    cbd, _ = lapack.dpbtrf(np.repeat(ac[:, None], Te, axis=1), lower=1)
    u0, _ = lapack.dpbtrs(cbd, (-_apply_D(c, g) / rho).reshape(Te, -1), lower=1)
    u = project(u0.reshape(Te, p, r), thr)
    converged = False
    it = 0
    f_prev = np.inf
    nz = np.sqrt(z.size)
    for it in range(1, max_iter + 1):
        k = kupdate(fac, k, z, u)
        Dk = _apply_D(c, k)
        Dh = alpha * Dk + (1.0 - alpha) * z
        v = Dh + u
        nv = np.sqrt(np.einsum("tpr,tpr->t", v, v))
        z_old = z
        z = v * np.maximum(0.0, 1.0 - thr / np.maximum(nv, 1e-300))[:, None, None]
        u = v - z
        if gap_tol is not None and (it % 10 == 0 or it == max_iter):
            # first differences: stop on the duality-gap certificate alone (see _gl_gap)
            ks, gap = _gl_gap(G, Bt, yy, k, lam * abs(float(c[1])))
            if gap <= gap_tol:
                k, converged = ks, True
                break
        elif it % 10 == 0 or it == max_iter:
            r_norm = _nrm(Dk - z)
            s_norm = rho * _nrm(_apply_DT(c, z - z_old, T))
            e_pri = nz * eps_abs + eps_rel * max(_nrm(Dk), _nrm(z))
            e_dual = np.sqrt(k.size) * eps_abs + eps_rel * rho * _nrm(_apply_DT(c, u, T))
            fval = _group_lasso_cost(G, Bt, yy, k, c, lam)
            if (r_norm <= e_pri and s_norm <= e_dual) or abs(fval - f_prev) <= ftol * abs(fval):
                converged = True
                break
            f_prev = fval
            if adapt and not linearized and it % 50 == 0:
                if r_norm * e_dual > 10 * s_norm * e_pri:
                    rho *= 2.0; u /= 2.0
                    fac = factor(rho); thr = lam / rho
                elif s_norm * e_pri > 10 * r_norm * e_dual:
                    rho /= 2.0; u *= 2.0
                    fac = factor(rho); thr = lam / rho
    return k, z, it, converged


def _gl_gap(G, Bt, yy, k, lam, Gk=None):
    """Relative duality gap of k for the first-difference group lasso (7.6) (see :func:`_gl_active_set`),
    after the exact minimization along a common shift of all k_t (which makes sum_t g_t = 0).
    Returns (shifted k, gap)."""
    Gk = G @ k if Gk is None else Gk
    try:
        delta = np.linalg.solve(G.sum(axis=0), (Gk - Bt).sum(axis=0))
    except np.linalg.LinAlgError:
        return k, np.inf
    k = k - delta[None]
    Gk = Gk - G @ np.broadcast_to(delta, k.shape)
    nu = np.cumsum(2.0 * (Gk[:-1] - Bt[:-1]), axis=0)
    nmax = float(np.sqrt(np.einsum("tpr,tpr->t", nu, nu)).max()) if nu.size else 0.0
    dk = k[1:] - k[:-1]
    tv = float(np.sum(np.sqrt(np.sum(dk.reshape(dk.shape[0], -1) ** 2, axis=1))))
    return k, _gl_rel_gap(yy, float(np.sum(k * Bt)), float(np.sum(k * Gk)), tv, nmax, lam)


def _gl_rel_gap(yy, kB, kGk, tv, nmax, lam):
    """Relative duality gap (P - D) / |P| of (7.6) from <k, Phi^T Y>, <k, Phi^T Phi k>, sum ||k_{t+1} - k_t||
    and max_t ||nu_t||, for a k with sum_t g_t = 0.  Primal P = ||Y - Phi k||^2 + lam tv; dual point
    (theta mu, theta nu) with mu = 2 (Phi k - Y), D^T nu = -Phi^T mu, theta in [0, lam / max ||nu_t||]
    maximizing D(theta) = -h*(theta mu) = theta a - theta^2 ||Y - Phi k||^2, a = 2 (||Y||^2 - <k, Phi^T Y>)."""
    fit = yy - 2.0 * kB + kGk
    P = fit + lam * tv
    a = 2.0 * (yy - kB)
    th = min(1.0, lam / max(nmax, 1e-300))
    th = min(th, max(0.0, a / (2.0 * fit))) if fit > 0 else th
    return (P - (th * a - th * th * fit)) / max(abs(P), 1e-300)


@lru_cache(maxsize=32)
def _gl_band_pattern(S, q):
    """Index arrays that scatter the diagonal blocks (lower triangles) and the sub-diagonal blocks
    H[j+1, j] of a block-tridiagonal (S q x S q) matrix into LAPACK lower band storage (kd = 2q - 1)."""
    a = np.repeat(np.arange(q), q)                   # row-major entries (a, b) of a q x q block
    b = np.tile(np.arange(q), q)
    low = a >= b
    js = np.arange(S)[:, None] * q
    diag = (np.broadcast_to((a - b)[low], (S, int(low.sum()))).ravel(), (js + b[low]).ravel())
    off = (np.broadcast_to(q + a - b, (max(S - 1, 0), q * q)).ravel(), (js[:-1] + b).ravel())
    return 2 * q - 1, diag, low.reshape(q, q), off


def _gl_reduced_newton(Gs, Bs, yy, lam, beta, w, eps, dec_tol, max_newton):
    """Primal-dual Newton (Chan, Golub & Mulet 1999) for the reduced, smoothed problem

        min_beta  sum_j tr(beta_j^T Gs_j beta_j) - 2 tr(Bs_j^T beta_j) + lam sum_j sqrt(||beta_{j+1} - beta_j||^2 + eps^2)

    over S segment values beta_j (p, r).  The dual w_j ~ (beta_{j+1} - beta_j) / n_j (||w_j|| <= 1) enters the
    Hessian of the penalty in place of the primal direction, which keeps Newton quadratically convergent
    for small eps, where plain Newton on the smoothed norm crawls.  The Hessian is block tridiagonal with
    (p r)-blocks: one banded Cholesky (LAPACK pbtrf/pbtrs) per step.  Returns (beta, w, steps)."""
    from scipy.linalg import lapack

    S, p, r = Bs.shape
    q = p * r
    Q = 2.0 * np.einsum("jab,cd->jacbd", Gs, np.eye(r)).reshape(S, q, q)    # row-major vec(beta_j)
    kd, diag, low, off = _gl_band_pattern(S, q)
    ab = np.zeros((kd + 1, S * q))
    x = beta.reshape(S, q).copy()
    w = w.reshape(S - 1, q).copy()
    bq = Bs.reshape(S, q)
    Iq = np.eye(q)
    steps = 0
    for _ in range(max_newton):
        steps += 1
        Dx = x[1:] - x[:-1]
        nd = np.sqrt(np.einsum("ja,ja->j", Dx, Dx) + eps * eps)
        s = Dx / nd[:, None]
        Qx = np.einsum("jab,jb->ja", Q, x)
        fval = yy + float(np.sum(x * (0.5 * Qx - 2.0 * bq))) + lam * float(np.sum(nd))
        grad = Qx - 2.0 * bq
        grad[:-1] -= lam * s
        grad[1:] += lam * s
        wD = w[:, :, None] * Dx[:, None, :]
        Hd = (lam / nd)[:, None, None] * (Iq - (wD + np.swapaxes(wD, 1, 2)) / (2.0 * nd)[:, None, None])
        Dg = Q.copy()
        Dg[:-1] += Hd
        Dg[1:] += Hd
        ab[diag] = Dg[:, low].ravel()
        ab[off] = (-Hd).ravel()
        cb, info = lapack.dpbtrf(ab, lower=1)
        if info != 0:
            raise np.linalg.LinAlgError("reduced group-lasso Hessian is not positive definite")
        dx, _ = lapack.dpbtrs(cb, -grad.reshape(-1), lower=1)
        dx = dx.reshape(S, q)
        dec = -float(np.sum(grad * dx))              # Newton decrement^2 ~ 2 (F - F_min)
        # dual step from the linearized n_j w_j = D_j, kept inside the unit balls (fraction to boundary)
        dD = dx[1:] - dx[:-1]
        dw = (dD - w * (np.einsum("ja,ja->j", Dx, dD) / nd)[:, None]) / nd[:, None] - w + s
        a2 = np.einsum("ja,ja->j", dw, dw)
        b1 = np.einsum("ja,ja->j", w, dw)
        c0 = np.einsum("ja,ja->j", w, w) - 1.0
        tmax = (-b1 + np.sqrt(np.maximum(b1 * b1 - a2 * c0, 0.0))) / np.maximum(a2, 1e-300)
        tw = min(1.0, 0.99 * float(np.min(tmax))) if tmax.size else 1.0
        x += dx
        w += tw * dw
        if dec <= dec_tol * max(abs(fval), 1e-300):
            break
    return x.reshape(S, p, r), w.reshape(S - 1, p, r), steps


def _gl_active_set(G, Bt, yy, lam, max_iter=5000, gap_tol=1e-6, max_rounds=200, viol_tol=1e-7,
                   eps_seq=(1e-4, 1e-6, 1e-8, 1e-10, 1e-12), max_set=None):
    """Working-set solver for the first-difference group lasso (7.6)

        min_k  sum_t ||Y_t - Phi_t k_t||^2 + lam sum_t ||k_{t+1} - k_t||_2      (k_t in R^{p x r})

    from the sufficient statistics G_t = Phi_t^T Phi_t, Bt_t = Phi_t^T Y_t, yy = ||Y||^2.

    The solution is piecewise constant, so only the S segment values between the current change points
    W are unknowns (segment statistics summed over each segment); the reduced problem is solved by primal-dual
    Newton on a smoothed norm (:func:`_gl_reduced_newton`).  Optimality of the full problem: with the
    gradient g_t = 2 (G_t k_t - Bt_t) and the prefix sums nu_t = sum_{s<=t} g_s (the dual of the
    difference k_{t+1} - k_t), every ||nu_t|| <= lam.  Each round adds, for every run of consecutive t
    with ||nu_t|| > lam, the t of largest violation to W, and drops the change points whose difference
    collapsed below the smoothing eps.  When nothing is violated, eps is decreased until the relative
    duality gap certifies the cost: for the dual point theta * nu (theta <= lam / max ||nu_t||) the
    dual value is -h*(theta mu) with mu = 2 (Phi k - Y), computable from (G, Bt, yy).

    The working set is meant for sparse changes: it gives up (clean = False) when it would exceed
    ``max_set`` change points (default max(100, 200 T / (p r)^3)), where ADMM is faster.

    Returns (k (T, p, r), rounds, Newton steps, relative duality gap, converged, clean), where
    ``converged`` means gap <= gap_tol and ``clean`` that no ||nu_t|| exceeds lam at the end (on badly
    scaled data the statistics may not resolve the gap to gap_tol although the solution is optimal)."""
    T, p, r = Bt.shape
    # a Newton step costs ~ S (p r)^3 flops: with many changes and large p r ADMM is faster (measured on
    # the Sec. 7.6/7.7 systems: p r = 6 with S ~ T/4 favours Newton, p r = 15 with S ~ T/5 favours ADMM)
    max_set = max(100, 200 * T // (p * r) ** 3) if max_set is None else int(max_set)
    Gtot, Btot = G.sum(axis=0), Bt.sum(axis=0)
    beta = np.linalg.solve(Gtot, Btot)[None]         # LTI fit (LinAlgError when not identifiable)
    # size of k (smoothing eps are relative to it): the LTI fit, or |y| / |Phi| if that vanishes
    scale = max(float(np.max(np.abs(beta))), np.sqrt(yy / max(float(np.trace(Gtot)), 1e-300)), 1e-300)
    bnd = np.zeros(0, int)                           # segment starts (change between t-1 and t)
    w = np.zeros((0, p, r))
    steps, stage, gap, converged = 0, 0, np.inf, False
    min_stage = min(2, len(eps_seq) - 1)             # eps <= 1e-8 scale before declaring convergence
    dropped, protected = set(), set()
    dec_tol = max(1e-3 * gap_tol, 1e-14)
    k = None
    for rnd in range(1, max_rounds + 1):
        eps = eps_seq[stage] * scale
        e = np.concatenate([[0], bnd, [T]])
        if bnd.size:
            # segment statistics summed directly (prefix-sum differences lose digits on long logs)
            Gs, Bs = np.add.reduceat(G, e[:-1]), np.add.reduceat(Bt, e[:-1])
            # coarse stage: only the working set matters, a loose Newton tolerance suffices
            beta, w, n = _gl_reduced_newton(Gs, Bs, yy, lam, beta, w, eps, dec_tol if stage else 1e-4,
                                            min(50, max_iter - steps))
            steps += n
            dn = np.sqrt(np.sum((beta[1:] - beta[:-1]) ** 2, axis=(1, 2)))
            # collapsed differences (||D_j|| <= eps): merge the segments.  At small eps an active
            # difference has n_j - ||D_j|| = O(eps^2), so ||D_j|| / n_j < 1 - 1e-3 (||D_j|| < 22 eps)
            # marks an inactive one.  Change points that were dropped and came back are kept.
            keep = dn > (22.0 * eps if stage >= min_stage else eps)
            if protected:
                keep |= np.isin(bnd, np.fromiter(protected, int, len(protected)))
            if not np.all(keep):
                dropped.update(bnd[~keep].tolist())
                bnd, w = bnd[keep], w[keep]
                beta = beta[np.concatenate([[True], keep])]
                e = np.concatenate([[0], bnd, [T]])
            Gs, Bs = np.add.reduceat(G, e[:-1]), np.add.reduceat(Bt, e[:-1])
            # exact minimization along a common shift of all segments makes sum_t g_t = 0
            beta = beta - np.linalg.solve(Gtot, np.einsum("jab,jbr->ar", Gs, beta) - Btot)[None]
        k = np.repeat(beta, np.diff(e), axis=0)
        Gk = G @ k
        nu = np.cumsum(2.0 * (Gk[:-1] - Bt[:-1]), axis=0)
        nn = np.sqrt(np.einsum("tpr,tpr->t", nu, nu))
        viol = nn > lam * (1.0 + viol_tol)
        viol[bnd - 1] = False
        # relative duality gap of (k, theta nu)
        dk = beta[1:] - beta[:-1]
        gap = _gl_rel_gap(yy, float(np.sum(k * Bt)), float(np.sum(k * Gk)),
                          float(np.sum(np.sqrt(np.sum(dk * dk, axis=(1, 2))))),
                          float(nn.max()) if nn.size else 0.0, lam)
        if not viol.any():
            if gap <= gap_tol and stage >= min_stage:
                converged = True
                break
            if stage + 1 == len(eps_seq) or steps >= max_iter:
                break
            stage += 1
            continue
        if steps >= max_iter:
            break
        # add the largest violation of every run of consecutive violations
        idx = np.flatnonzero(viol)
        starts = np.concatenate([[0], np.flatnonzero(np.diff(idx) > 1) + 1])
        runmax = np.maximum.reduceat(nn[idx], starts)
        runid = np.cumsum(np.isin(np.arange(idx.size), starts)) - 1
        hit = np.flatnonzero(nn[idx] == runmax[runid])
        first = hit[np.concatenate([[True], np.diff(runid[hit]) > 0])]
        new = idx[first] + 1
        protected.update(t for t in new.tolist() if t in dropped)     # no add/drop cycles
        bnd2 = np.union1d(bnd, new)
        if bnd2.size > max_set:
            # a dense solution (changes almost everywhere): ADMM is the better tool, give up here
            return k, rnd, steps, gap, False, False
        e2 = np.concatenate([[0], bnd2, [T]])
        beta = beta[np.searchsorted(e, e2[:-1], side="right") - 1]
        w2 = 0.99 * nu[bnd2 - 1] / np.maximum(nn[bnd2 - 1], lam)[:, None, None]
        w2[np.isin(bnd2, bnd)] = w
        bnd, w = bnd2, w2
        stage = 0                                    # new differences open at the coarse smoothing
    return k, rnd, steps, gap, converged, not viol.any()


def _gl_solve(Phi, Y, lam, order, P, names, check, block=None, **admm_kw):
    lam = _check_lam(lam)
    if lam <= 0:
        raise DataError("group lasso needs lam > 0")
    c = _poly(order, P)
    if check:
        check_identifiable(Phi, c, names, what="group-lasso problem")
    G = np.einsum("tmi,tmj->tij", Phi, Phi)
    Bt = np.einsum("tmi,tmr->tir", Phi, Y)
    yy = float(np.sum(Y * Y))
    T = G.shape[0]
    block = max(1, T // 2000) if block is None else int(block)
    if block < 1:
        raise DataError(f"block must be >= 1, got {block}")
    if block > 1:
        # k constant within blocks of `block` samples: exact sums of the sufficient statistics
        edges = np.arange(0, T, block)
        if edges.size < c.size + 1:
            raise DataError(f"block={block} leaves {edges.size} blocks; need more than {c.size}")
        Gb, Bb = np.add.reduceat(G, edges), np.add.reduceat(Bt, edges)
    else:
        Gb, Bb = G, Bt
    k = None
    working_set = (c.size == 2 and c[0] == -c[1] and not admm_kw.get("linearized")
                   and admm_kw.get("rho") is None)
    if working_set:
        # (7.6): working-set primal-dual Newton with a duality-gap certificate (relative gap <= ftol);
        # ADMM below stays the fallback (and the solver for (7.9), general P(z), an explicit rho)
        try:
            k, _, it, _, conv, clean = _gl_active_set(Gb, Bb, yy, lam * abs(float(c[1])),
                                                      max_iter=admm_kw.get("max_iter", 5000),
                                                      gap_tol=max(float(admm_kw.get("ftol", 1e-6)), 1e-12))
        except np.linalg.LinAlgError:
            k, clean = None, False
        if clean:        # converged, or optimal to the precision the statistics allow (conv False)
            z = _apply_D(c, k)
        else:
            k = None
    if k is None:
        if working_set:
            # dense changes: ADMM, stopped by the same duality-gap certificate (gap <= ftol)
            admm_kw = dict(admm_kw, gap_tol=max(float(admm_kw.get("ftol", 1e-6)), 1e-12))
        k, z, it, conv = _admm(Gb, Bb, yy, lam, c, **admm_kw)
    if block > 1:
        k = np.repeat(k, np.diff(np.append(edges, T)), axis=0)
    cost = _group_lasso_cost(G, Bt, yy, k, c, lam) if block == 1 else _group_lasso_cost(Gb, Bb, yy, k[edges], c, lam)
    d = c.size - 1
    zn = np.sqrt(np.sum(z.reshape(z.shape[0], -1) ** 2, axis=1))
    nz = np.flatnonzero(zn > 0)
    times = [t * block for t in _cluster_times(nz + d, zn[nz])]
    return k, z, cost, it, conv, times, c


def tv_regression_group_lasso(Phi, y, lam, order=1, P=None, rho=None, max_iter=5000, eps_abs=1e-5,
                              eps_rel=1e-4, linearized=False, check=True, names=None, block=None, ftol=1e-6):
    """Solve (7.6) (``order=1``) or (7.9) (``order=2``) for y_t = Phi_t k_t:
    min ||y - Phi k||^2 + lam sum_t ||P(z) k_t||_2  (group lasso on the differences).

    Solver: for first differences (7.6) a working-set method (only the values between the current change
    points are unknowns, solved by primal-dual Newton; change points are added where the optimality
    condition is violated) that stops when the relative duality gap is <= ``ftol`` (``iterations`` counts
    Newton steps); when the changes are dense, ADMM with the same duality-gap stopping rule.  For
    (7.9)/general ``P`` or with an explicit ``rho``: ADMM whose k-update is one banded Cholesky solve,
    stopping when the residuals fall below eps_abs/eps_rel or the objective changes by less than
    ``ftol`` over 10 iterations.
    ``linearized=True`` uses linearized ADMM as in App. 7.A (much slower to converge).  ``change_times`` of the result are
    the indices t at which the (exactly sparse) split variable reports a change, clustered so that
    adjacent nonzero differences count as one event located at the largest one.

    ``block > 1`` (default ``None``: T // 2000, i.e. 1 below 4000 samples) constrains k to be constant on consecutive blocks of that many samples (the
    sufficient statistics are summed exactly, so this is the same problem on a coarser time grid):
    a T = 20,000 series with block = 10 solves in a fraction of the time; change times are then
    block boundaries (refine them with :func:`tv_regression_segments` if needed)."""
    Phi, Y = _as_regression(Phi, y)
    k, z, cost, it, conv, times, c = _gl_solve(Phi, Y, lam, order, P, names, check, block=block, rho=rho,
                                               max_iter=max_iter, ftol=ftol,
                                               eps_abs=eps_abs, eps_rel=eps_rel, linearized=linearized)
    return GroupLassoResult(k[:, :, 0], z[:, :, 0], cost, float(lam), it, conv, times,
                            {"order": c.size - 1, "linearized": linearized,
                             "block": max(1, Phi.shape[0] // 2000) if block is None else int(block)})


def ltv_group_lasso(x, u, lam, order=1, P=None, y=None, rho=None, max_iter=5000, eps_abs=1e-5, eps_rel=1e-4,
                    linearized=False, check=True, ftol=1e-6):
    """(7.6)/(7.9) for the state-space LTV model: piecewise constant / piecewise affine A_t, B_t.

    The group is the whole parameter vector k_t (all entries of A and B change together)."""
    phi, Yn, n, m, names = _as_state_space(x, u, y)
    k, z, cost, it, conv, times, c = _gl_solve(phi[:, None, :], Yn[:, None, :], lam, order, P, names, check,
                                               rho=rho, max_iter=max_iter, eps_abs=eps_abs, eps_rel=eps_rel,
                                               linearized=linearized, ftol=ftol)
    res = _to_ltv(k, None, n, m, cost, float(lam), info={"iterations": it, "converged": conv, "dk": z})
    res.change_times = times
    return res


# =============================================================================================
# change points, knots and the two-step refinement (7.10)
# =============================================================================================
def _cluster_times(idx, w, gap=1):
    """Group consecutive indices (distance <= gap) into events; each event at its largest weight."""
    idx = np.asarray(idx, int)
    if idx.size == 0:
        return []
    out, start = [], 0
    for i in range(1, idx.size + 1):
        if i == idx.size or idx[i] - idx[i - 1] > gap:
            j = start + int(np.argmax(w[start:i]))
            out.append(int(idx[j]))
            start = i
    return out


def change_points(k, n=None, threshold=None, rel_threshold=0.1, min_separation=1, order=1):
    """Detected change times of a (piecewise constant) parameter trajectory k (T, ...).

    a_t = ||k_t - k_{t-1}||_2 (``order=1``) or the second difference (``order=2``, a slope change at t);
    returns sorted indices t (the first sample of the new segment).  ``n``: return the n largest
    separated events; otherwise all events with a_t > ``threshold`` (default ``rel_threshold``
    times the largest a_t).  Adjacent indices closer than ``min_separation`` form one event located
    at its largest a_t."""
    k = np.asarray(k, float)
    k = k.reshape(k.shape[0], -1)
    if k.shape[0] < order + 1:
        return []
    c = _poly(order)
    a = np.sqrt(np.sum(_apply_D(c, k) ** 2, axis=1))
    off = order if order == 1 else 1
    if a.max(initial=0.0) <= 0:
        return []
    if n is not None:
        chosen = []
        aa = a.copy()
        for _ in range(int(n)):
            j = int(np.argmax(aa))
            if aa[j] <= 0:
                break
            chosen.append(j + off)
            aa[max(0, j - min_separation):j + min_separation + 1] = -np.inf
        return sorted(chosen)
    thr = rel_threshold * a.max() if threshold is None else float(threshold)
    idx = np.flatnonzero(a > thr)
    return sorted(_cluster_times(idx + off, a[idx], gap=min_separation))


def _segment_bounds(knots, T):
    b = [0] + sorted(int(t) for t in knots) + [T]
    if any(b[i + 1] <= b[i] for i in range(len(b) - 1)) or b[0] < 0 or b[-1] > T:
        raise DataError(f"knots must be strictly increasing inside (0, {T}), got {list(knots)}")
    return b


def refine_with_knots(Phi, y, knots, lam=None, order=1, names=None):
    """Two-step refinement, Eq. (7.10): given knots (change times), re-fit without the sparsity
    penalty.  ``lam=None``: one constant (LTI) parameter vector per segment; otherwise each segment
    is solved with the squared penalty lam^2 ||D_order k||^2 (closed form, via the smoother)."""
    Phi, Y = _as_regression(Phi, y)
    return _refine(Phi, Y, knots, lam, order, names)[:, :, 0]


def _refine(Phi, Y, knots, lam, order, names):
    T, m, p = Phi.shape
    b = _segment_bounds(knots, T)
    k = np.empty((T, p, Y.shape[2]))
    for a, e in zip(b[:-1], b[1:]):
        Ps, Ys = Phi[a:e], Y[a:e]
        if lam is None:
            A = Ps.reshape(-1, p)
            if np.linalg.matrix_rank(A) < p:
                raise IdentifiabilityError(f"segment [{a}, {e}) has rank-deficient regressors "
                                           f"({np.linalg.matrix_rank(A)} of {p}); move or drop the knot")
            sol = np.linalg.lstsq(A, Ys.reshape(-1, Y.shape[2]), rcond=None)[0]
            k[a:e] = sol
        else:
            if e - a < 2:
                raise DataError(f"segment [{a}, {e}) is too short for the smoothing refinement")
            k[a:e] = _tv_smooth(Ps, Ys, lam, order, None, None, None, None, None, "banded", True, names,
                                want_cov=False, want_loglik=False).k
    return k


def ltv_refine_with_knots(x, u, knots, lam=None, order=1, y=None):
    """(7.10) for the state-space model: LTI fit (or smooth fit) between the knots."""
    phi, Yn, n, m, names = _as_state_space(x, u, y)
    k = _refine(phi[:, None, :], Yn[:, None, :], knots, lam, order, names)
    res = _to_ltv(k, None, n, m, float("nan"), float("nan") if lam is None else float(lam))
    pred = np.einsum("tpr,tp->tr", k, phi)
    res.cost = float(np.sum((pred - Yn) ** 2))
    res.change_times = sorted(int(t) for t in knots)
    return res


# =============================================================================================
# (7.8): known number of switches, dynamic programming (Algorithm 3)
# =============================================================================================
@dataclass
class SegmentsResult:
    """Optimal piecewise-constant fit with a known number of switches, Eq. (7.8).
    ``change_times`` are the first indices of the new segments, ``params`` (M+1, p[, r]) the LTI
    parameters per segment, ``k`` (T, p[, r]) the expanded trajectory, ``cost`` the squared error."""
    k: np.ndarray
    change_times: list
    params: np.ndarray
    cost: float
    info: dict = field(default_factory=dict)


class _SegmentCost:
    """Least-squares cost of an LTI fit on a segment [a, b) of blocks, from prefix sums.

    With cumulative sums of Phi^T Phi, Phi^T Y and Y^T Y the statistics of any segment cost O(1)
    (the incremental computation of App. 7.B) and the cost is ||Y||^2 - b^T G^{-1} b; the costs
    of all segments starting at one block are computed with one batched solve."""

    def __init__(self, G, Bt, yy, min_len):
        self.cG = np.concatenate([np.zeros((1,) + G.shape[1:]), np.cumsum(G, axis=0)])
        self.cB = np.concatenate([np.zeros((1,) + Bt.shape[1:]), np.cumsum(Bt, axis=0)])
        self.cy = np.concatenate([[0.0], np.cumsum(yy)])
        p = G.shape[1]
        self.eps = 1e-12 * max(float(np.trace(self.cG[-1])) / p, 1e-300)
        self.min_len = min_len
        self.p = p

    def stats(self, a, b):
        return self.cG[b] - self.cG[a], self.cB[b] - self.cB[a], self.cy[b] - self.cy[a]

    def cost(self, a, b):
        """a, b arrays (broadcast) of block boundaries, b > a; inf for segments shorter than min_len."""
        a = np.asarray(a); b = np.asarray(b)
        G, B, yy = self.stats(a, b)
        sol = np.linalg.solve(G + self.eps * np.eye(self.p), B)
        c = yy - np.sum(B * sol, axis=(-2, -1))
        c = np.maximum(c, 0.0)
        return np.where(b - a >= self.min_len, c, np.inf)

    def argmin(self, a, b):
        G, B, _ = self.stats(a, b)
        return np.linalg.solve(G + self.eps * np.eye(self.p), B)


def _dp(sc, nB, M):
    """Bellman recursion of Algorithm 3 on nB blocks with M switches; the segment-cost table is the
    memo (computed once, one batched solve per start block).  Returns (cost, boundaries)."""
    C = np.full((nB + 1, nB + 1), np.inf)        # C[a, b] = cost of blocks [a, b)
    for a in range(nB):
        bs = np.arange(a + 1, nB + 1)
        C[a, a + 1:] = sc.cost(np.full(bs.shape, a), bs)
    # F[j][a] = best cost of covering blocks [a, nB) with j switches
    F = C[:, nB].copy()
    back = []
    for j in range(1, M + 1):
        tot = C[:, :nB] + F[None, :nB]           # split at l: [a, l) + F[l]
        tot[:, 0] = np.inf
        tot[np.tril_indices(nB + 1, 0, nB)] = np.inf
        arg = np.argmin(tot, axis=1)
        F = tot[np.arange(nB + 1), arg]
        back.append(arg)
    cost = float(F[0])
    if not np.isfinite(cost):
        raise IdentifiabilityError(f"no segmentation into {M + 1} segments of at least {sc.min_len} samples "
                                   f"with identifiable parameters exists")
    bounds, a = [], 0
    for j in range(M, 0, -1):
        a = int(back[j - 1][a])
        bounds.append(a)
    return cost, bounds


def _segments(Phi, Y, M, min_length, max_blocks, names):
    T, m, p = Phi.shape
    M = int(M)
    if M < 0:
        raise DataError(f"n_switches must be >= 0, got {M}")
    min_len = int(min_length) if min_length is not None else int(np.ceil(p / m))
    if (M + 1) * min_len > T:
        raise DataError(f"{M + 1} segments of at least {min_len} samples need T >= {(M + 1) * min_len}, got {T}")
    check_identifiable(Phi, _poly(1), names, what="piecewise-constant problem (7.8)")
    G = np.einsum("tmi,tmj->tij", Phi, Phi)
    Bt = np.einsum("tmi,tmr->tir", Phi, Y)
    yy = np.einsum("tmr,tmr->t", Y, Y)
    full = _SegmentCost(G, Bt, yy, min_len)
    bs = max(1, int(np.ceil(T / max_blocks)))
    if bs == 1:
        cost, bounds = _dp(full, T, M)
    else:
        # exact statistics summed over blocks of bs samples; DP on block boundaries, then refine
        # every boundary at full resolution within +-bs samples (coordinate descent, exact costs)
        nB = -(-T // bs)
        edges = np.minimum(np.arange(nB + 1) * bs, T)
        coarse = _SegmentCost(np.add.reduceat(G, edges[:-1]), np.add.reduceat(Bt, edges[:-1]),
                              np.add.reduceat(yy, edges[:-1]), max(1, int(np.ceil(min_len / bs))))
        _, bb = _dp(coarse, nB, M)
        bounds = [int(edges[b]) for b in bb]
        for _sweep in range(2):
            for i in range(len(bounds)):
                lo = bounds[i - 1] if i > 0 else 0
                hi = bounds[i + 1] if i + 1 < len(bounds) else T
                cand = np.arange(max(lo + min_len, bounds[i] - bs), min(hi - min_len, bounds[i] + bs) + 1)
                if cand.size == 0:
                    continue
                tot = full.cost(np.full(cand.shape, lo), cand) + full.cost(cand, np.full(cand.shape, hi))
                bounds[i] = int(cand[np.argmin(tot)])
        edges_f = [0] + bounds + [T]
        cost = float(sum(full.cost(a, b) for a, b in zip(edges_f[:-1], edges_f[1:])))
    edges_f = [0] + bounds + [T]
    params = np.array([full.argmin(a, b) for a, b in zip(edges_f[:-1], edges_f[1:])])
    k = np.empty((T,) + params.shape[1:])
    for s, (a, b) in enumerate(zip(edges_f[:-1], edges_f[1:])):
        k[a:b] = params[s]
    return k, bounds, params, cost, bs


def tv_regression_segments(Phi, y, n_switches, min_length=None, max_blocks=400):
    """Solve (7.8): the best piecewise-constant k with at most ``n_switches`` changes, by dynamic
    programming (Algorithm 3, App. 7.B) with memoized segment costs from prefix sums.

    Exact for T <= ``max_blocks``.  For longer series the sufficient statistics are summed into
    ceil(T / max_blocks)-sample blocks, the DP runs on block boundaries, and every change time is
    then refined at full resolution (+-one block, exact costs).  ``min_length`` (default ceil(p/m))
    is the shortest allowed segment."""
    Phi, Y = _as_regression(Phi, y)
    k, bounds, params, cost, bs = _segments(Phi, Y, n_switches, min_length, max_blocks, None)
    return SegmentsResult(k[:, :, 0], bounds, params[:, :, 0], cost, {"block_size": bs})


def ltv_segments(x, u, n_switches, y=None, min_length=None, max_blocks=400):
    """(7.8) for the state-space model: piecewise-constant A_t, B_t with a known number of switches."""
    phi, Yn, n, m, names = _as_state_space(x, u, y)
    k, bounds, params, cost, bs = _segments(phi[:, None, :], Yn[:, None, :], n_switches,
                                            min_length if min_length is not None else phi.shape[1],
                                            max_blocks, names)
    res = _to_ltv(k, None, n, m, cost, float("nan"), info={"block_size": bs})
    res.change_times = bounds
    return res


def segments_brute_force(Phi, y, n_switches, min_length=None):
    """Exhaustive search over all switch times (for tests on small T)."""
    Phi, Y = _as_regression(Phi, y)
    T, m, p = Phi.shape
    min_len = int(min_length) if min_length is not None else int(np.ceil(p / m))
    G = np.einsum("tmi,tmj->tij", Phi, Phi)
    Bt = np.einsum("tmi,tmr->tir", Phi, Y)
    sc = _SegmentCost(G, Bt, np.einsum("tmr,tmr->t", Y, Y), min_len)
    best, arg = np.inf, None
    for cut in combinations(range(1, T), n_switches):
        e = (0,) + cut + (T,)
        c = float(sum(sc.cost(a, b) for a, b in zip(e[:-1], e[1:])))
        if c < best:
            best, arg = c, list(cut)
    return best, arg


# =============================================================================================
# MathematicalProgram references (tests and benchmarks)
# =============================================================================================
def _mp_program(Phi, Y, lam, c, kind):
    from pydrake.solvers import MathematicalProgram

    T, m, p = Phi.shape
    r = Y.shape[2]
    d = c.size - 1
    prog = MathematicalProgram()
    k = prog.NewContinuousVariables(T, p * r, "k")          # k[t] = vec of the (p, r) block, column major
    for t in range(T):
        A = np.kron(np.eye(r), Phi[t])
        prog.Add2NormSquaredCost(A, Y[t].T.reshape(-1), k[t])
    Dm = np.kron(c[None, :], np.eye(p * r))
    if kind == "squared":
        for t in range(T - d):
            prog.Add2NormSquaredCost(lam * Dm, np.zeros(p * r), k[t:t + d + 1].reshape(-1))
    else:
        s = prog.NewContinuousVariables(T - d, "s")
        prog.AddLinearCost(lam * np.ones(T - d), 0.0, s)
        A = np.zeros((1 + p * r, 1 + (d + 1) * p * r))
        A[0, 0] = 1.0
        A[1:, 1:] = Dm
        for t in range(T - d):
            prog.AddLorentzConeConstraint(A, np.zeros(1 + p * r), np.concatenate([[s[t]], k[t:t + d + 1].reshape(-1)]))
    return prog, k


def _mp_solve(prog, k, solver, T, p, r, tight=True):
    """Solve with tight tolerances (reference accuracy) or the solver's defaults (``tight=False``)."""
    from pydrake.solvers import ClarabelSolver, OsqpSolver, ScsSolver, SolverOptions

    opts = SolverOptions()
    if solver == "clarabel":
        s = ClarabelSolver()
        if tight:
            for name in ("tol_gap_abs", "tol_gap_rel", "tol_feas", "tol_ktratio"):
                opts.SetOption(s.solver_id(), name, 1e-10)
    elif solver == "osqp":
        s = OsqpSolver()
        if tight:
            opts.SetOption(s.solver_id(), "eps_abs", 1e-10)
            opts.SetOption(s.solver_id(), "eps_rel", 1e-10)
            opts.SetOption(s.solver_id(), "max_iter", 200000)
    elif solver == "scs":
        s = ScsSolver()
    else:
        raise DataError(f"solver must be 'clarabel', 'osqp' or 'scs', got {solver!r}")
    result = s.Solve(prog, None, opts)
    if not result.is_success():
        raise DataError(f"{solver} did not solve the reference program: {result.get_solution_result()}")
    kk = result.GetSolution(k).reshape(T, r, p)
    return np.swapaxes(kk, 1, 2), result


def tv_regression_qp_reference(Phi, y, lam, order=1, P=None, solver="clarabel", return_program=False):
    """(7.3)/(7.5)/(7.13) written as a QP in Drake's ``MathematicalProgram`` (reference solution)."""
    Phi, Y = _as_regression(Phi, y)
    prog, k = _mp_program(Phi, Y, float(lam), _poly(order, P), "squared")
    kk, res = _mp_solve(prog, k, solver, Phi.shape[0], Phi.shape[2], 1)
    return (kk[:, :, 0], prog) if return_program else kk[:, :, 0]


def tv_regression_group_lasso_reference(Phi, y, lam, order=1, P=None, solver="clarabel"):
    """(7.6)/(7.9) in ``MathematicalProgram`` with second-order cones (Clarabel or SCS through Drake).
    Returns (k, cost)."""
    Phi, Y = _as_regression(Phi, y)
    c = _poly(order, P)
    prog, k = _mp_program(Phi, Y, float(lam), c, "lasso")
    kk, res = _mp_solve(prog, k, solver, Phi.shape[0], Phi.shape[2], 1)
    G = np.einsum("tmi,tmj->tij", Phi, Phi)
    Bt = np.einsum("tmi,tmr->tir", Phi, Y)
    return kk[:, :, 0], _group_lasso_cost(G, Bt, float(np.sum(Y * Y)), kk, c, float(lam))


def ltv_qp_reference(x, u, lam, order=1, y=None, solver="clarabel", tight=True):
    """(7.3)/(7.5) for the state-space model as a ``MathematicalProgram`` QP; returns (A, B).
    ``tight=False`` keeps the solver's default tolerances (what the benchmark times)."""
    phi, Yn, n, m, _ = _as_state_space(x, u, y)
    prog, k = _mp_program(phi[:, None, :], Yn[:, None, :], float(lam), _poly(order), "squared")
    kk, _ = _mp_solve(prog, k, solver, phi.shape[0], phi.shape[1], n, tight)
    AB = np.swapaxes(kk, 1, 2)
    return AB[:, :, :n], AB[:, :, n:]


def ltv_group_lasso_reference(x, u, lam, order=1, y=None, solver="clarabel"):
    """(7.6)/(7.9) for the state-space model in ``MathematicalProgram``; returns (A, B, cost)."""
    phi, Yn, n, m, _ = _as_state_space(x, u, y)
    Phi, Y = phi[:, None, :], Yn[:, None, :]
    c = _poly(order)
    prog, k = _mp_program(Phi, Y, float(lam), c, "lasso")
    kk, _ = _mp_solve(prog, k, solver, phi.shape[0], phi.shape[1], n)
    G = np.einsum("tmi,tmj->tij", Phi, Phi)
    Bt = np.einsum("tmi,tmr->tir", Phi, Y)
    cost = _group_lasso_cost(G, Bt, float(np.sum(Y * Y)), kk, c, float(lam))
    AB = np.swapaxes(kk, 1, 2)
    return AB[:, :, :n], AB[:, :, n:], cost


# =============================================================================================
# simulation helpers for examples (Secs. 7.6-7.7)
# =============================================================================================
def simulate_ltv(A, B, u, x0=None, sigma_v=0.0, seed=0):
    """x_{t+1} = A_t x_t + B_t u_t + v_t; A (T, n, n) or (n, n); returns x (T+1, n)."""
    rng = np.random.default_rng(seed)
    u = np.asarray(u, float)
    if u.ndim == 1:
        u = u[:, None]
    T = u.shape[0]
    A = np.broadcast_to(np.asarray(A, float), (T,) + np.shape(A)[-2:])
    B = np.broadcast_to(np.asarray(B, float), (T,) + np.shape(B)[-2:])
    n = A.shape[1]
    x = np.zeros((T + 1, n))
    if x0 is not None:
        x[0] = x0
    for t in range(T):
        x[t + 1] = A[t] @ x[t] + B[t] @ u[t] + sigma_v * rng.standard_normal(n)
    return x


def jump_system(T=400, t_switch=200, sigma=0.2, seed=0):
    """The jump-linear system of Sec. 7.6 (Fig. 7.1): A changes at t = t_switch.

    Returns (x (T+1, 2), u (T, 1), y (T, 2) = x_{t+1} + e_t, A_true (T, 2, 2), B_true (T, 2, 1)).
    State-transition and measurement noise both have standard deviation ``sigma``."""
    rng = np.random.default_rng(seed)
    A1 = np.array([[0.95, 0.1], [0.0, 0.95]])
    A2 = np.array([[0.5, 0.05], [0.0, 0.5]])
    Bm = np.array([[0.2], [1.0]])
    A = np.array([A1 if t < t_switch else A2 for t in range(T)])
    B = np.broadcast_to(Bm, (T, 2, 1)).copy()
    u = rng.standard_normal((T, 1))
    x = np.zeros((T + 1, 2))
    for t in range(T):
        x[t + 1] = A[t] @ x[t] + B[t] @ u[t] + sigma * rng.standard_normal(2)
    y = x[1:] + sigma * rng.standard_normal((T, 2))
    return x, u, y, A, B


def drift_system(T=2000, n=3, m=2, sigma_v=0.01, sigma_w=0.001, seed=0):
    """The slowly drifting system of Sec. 7.7: k follows a random walk with std ``sigma_w``,
    the state noise has std ``sigma_v``, inputs are N(0, I).  Returns (x, u, A_true, B_true)."""
    rng = np.random.default_rng(seed)
    A0 = np.diag(rng.uniform(0.8, 0.95, n)) + 0.05 * rng.standard_normal((n, n))
    rad = np.max(np.abs(np.linalg.eigvals(A0)))
    if rad > 0.95:
        A0 *= 0.95 / rad
    B0 = rng.standard_normal((n, m)) * 0.5
    k = np.hstack([A0, B0]).reshape(-1)
    K = k.size
    ks = k + np.cumsum(sigma_w * rng.standard_normal((T, K)), axis=0)
    AB = ks.reshape(T, n, n + m)
    A, B = AB[:, :, :n], AB[:, :, n:]
    u = rng.standard_normal((T, m))
    x = np.zeros((T + 1, n))
    for t in range(T):
        x[t + 1] = A[t] @ x[t] + B[t] @ u[t] + sigma_v * rng.standard_normal(n)
    return x, u, A, B


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
