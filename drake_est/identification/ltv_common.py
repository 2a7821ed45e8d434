"""Shared pieces of the LTV identification (thesis Ch. 7): input handling (regression and state-space
forms), the difference regularizer P(z) and Lambda, identifiability checks, and the result classes.

Split out of :mod:`drake_est.identification.ltv`, which re-exports every name."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drake_est.errors import DataError, IdentifiabilityError


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
# difference operators and change-point detection on a parameter trajectory (used by the results above,
# the smoothers and the segmentation)
# =============================================================================================
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
