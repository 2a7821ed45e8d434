"""numba kernels of the iLQR/DDP inner loop (backward pass with box-QP, cart-pole rollout and derivatives).

Every kernel has a numpy twin (:func:`drake_est.control.ilqr.backward_pass_numpy`,
:func:`drake_est.control.boxqp.boxqp`, :class:`drake_est.control.cartpole.CartPoleModel` numpy methods)
that gives the same iterates (tested to 1e-10).  ``DRAKE_EST_NO_NUMBA=1`` (or a missing numba) selects the
numpy path everywhere; :func:`use_numba` is the switch the callers consult.
"""
from __future__ import annotations

import math
import os

import numpy as np

try:
    import numba
    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - numba is a dependency
    numba = None
    HAVE_NUMBA = False


def use_numba(flag=None) -> bool:
    """True when the compiled kernels should be used (``flag`` overrides; env DRAKE_EST_NO_NUMBA=1 disables)."""
    if not HAVE_NUMBA or os.environ.get("DRAKE_EST_NO_NUMBA", "") not in ("", "0"):
        return False
    return True if flag is None else bool(flag)


def _njit(f):
    if not HAVE_NUMBA:
        return f
    return numba.njit(cache=True, fastmath=False)(f)


# ------------------------------------------------------------------------------------------------
# small dense helpers
# ------------------------------------------------------------------------------------------------
@_njit
def _chol_sub(H, idx, nf, L):
    """Lower Cholesky of H[idx[:nf]][:, idx[:nf]] into L[:nf, :nf]; returns False if not PD."""
    for i in range(L.shape[0]):
        for j in range(L.shape[1]):
            L[i, j] = 0.0
    for j in range(nf):
        s = H[idx[j], idx[j]]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not (s > 0.0):
            return False
        d = math.sqrt(s)
        L[j, j] = d
        for i in range(j + 1, nf):
            s = H[idx[i], idx[j]]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / d
    return True


@_njit
def _chol_solve_inplace(L, nf, b):
    """Solve (L L^T) y = b for the leading nf block, b (nf,) overwritten."""
    for i in range(nf):
        s = b[i]
        for k in range(i):
            s -= L[i, k] * b[k]
        b[i] = s / L[i, i]
    for i in range(nf - 1, -1, -1):
        s = b[i]
        for k in range(i + 1, nf):
            s -= L[k, i] * b[k]
        b[i] = s / L[i, i]


@_njit
def _qpval(H, g, x):
    m = g.shape[0]
    v = 0.0
    for i in range(m):
        v += x[i] * g[i]
        s = 0.0
        for j in range(m):
            s += H[i, j] * x[j]
        v += 0.5 * x[i] * s
    return v


@_njit
def boxqp_nb(H, g, lower, upper, x0, x, free, L, max_iter):
    """numba twin of :func:`drake_est.control.boxqp.boxqp`; writes x, free, L; returns (status, iterations)."""
    m = g.shape[0]
    grad = np.empty(m)
    dx = np.empty(m)
    xc = np.empty(m)
    old_free = np.zeros(m, np.bool_)
    idx = np.empty(m, np.int64)
    b = np.empty(m)
    for i in range(m):
        x[i] = min(max(x0[i], lower[i]), upper[i])
        free[i] = True
    for i in range(m):
        for j in range(m):
            L[i, j] = 0.0
    first = True
    value = _qpval(H, g, x)
    status = 1
    it = 0
    nf = 0
    for it in range(1, max_iter + 1):
        nf = 0
        for i in range(m):
            s = g[i]
            for j in range(m):
                s += H[i, j] * x[j]
            grad[i] = s
            cl = (x[i] == lower[i] and s > 0.0) or (x[i] == upper[i] and s < 0.0)
            free[i] = not cl
            if not cl:
                idx[nf] = i
                nf += 1
        if nf == 0:
            status = 4
            break
        changed = first
        for i in range(m):
            if free[i] != old_free[i]:
                changed = True
        if changed:
            if not _chol_sub(H, idx, nf, L):
                status = -1
                break
        first = False
        for i in range(m):
            old_free[i] = free[i]
        gn = 0.0
        for a in range(nf):
            gn += grad[idx[a]] ** 2
        if math.sqrt(gn) < 1e-8:
            status = 3
            break
        for a in range(nf):
            i = idx[a]
            s = g[i]
            for j in range(m):
                if not free[j]:
                    s += H[i, j] * x[j]
            b[a] = s
        _chol_solve_inplace(L, nf, b)
        for i in range(m):
            dx[i] = 0.0
        for a in range(nf):
            dx[idx[a]] = -b[a] - x[idx[a]]
        sdotg = 0.0
        for i in range(m):
            sdotg += dx[i] * grad[i]
        if sdotg >= 0:
            status = 0
            break
        step = 1.0
        for i in range(m):
            xc[i] = min(max(x[i] + step * dx[i], lower[i]), upper[i])
        vc = _qpval(H, g, xc)
        tiny = False
        while (vc - value) / (step * sdotg) < 0.1:
            step *= 0.6
            for i in range(m):
                xc[i] = min(max(x[i] + step * dx[i], lower[i]), upper[i])
            vc = _qpval(H, g, xc)
            if step < 1e-22:
                tiny = True
                break
        if tiny:
            status = 0
            break
        improve = value - vc
        for i in range(m):
            x[i] = xc[i]
        old_value = value
        value = vc
        if improve < 1e-8 * abs(old_value):
            status = 2
            break
    return status, it


# ------------------------------------------------------------------------------------------------
# backward pass (Eqs. (11.3)-(11.8) with box-QP and Q_uu + mu I)
# ------------------------------------------------------------------------------------------------
@_njit
def backward_pass_nb(fx, fu, fxx, fux, fuu, second_order, lx, lu, lxx, luu, lux, U, lb, ub, mu,
                     k_warm, K, k, Quu_out, free_out, dV):
    """Backward pass; writes K (T,m,n), k (T,m), Quu_out (T,m,m) (unregularized Q_uu), free_out (T,m),
    dV (2,).  Returns -1 on success or the time index where the regularized Q_uu was not PD."""
    T = fx.shape[0]
    n = fx.shape[1]
    m = fu.shape[2]
    Vx = lx[T].copy()
    Vxx = lxx[T].copy()
    Qx = np.empty(n)
    Qu = np.empty(m)
    Qxx = np.empty((n, n))
    Quu = np.empty((m, m))
    Qux = np.empty((m, n))
    H = np.empty((m, m))
    Qs = np.empty((m, m))
    VA = np.empty((n, n))
    VB = np.empty((n, m))
    lo = np.empty(m)
    hi = np.empty(m)
    kk = np.empty(m)
    fr = np.empty(m, np.bool_)
    L = np.empty((m, m))
    idx = np.empty(m, np.int64)
    col = np.empty(m)
    Quk = np.empty(m)
    dV[0] = 0.0
    dV[1] = 0.0
    for t in range(T - 1, -1, -1):
        A = fx[t]
        B = fu[t]
        # VA = Vxx A, VB = Vxx B
        for i in range(n):
            for j in range(n):
                s = 0.0
                for a in range(n):
                    s += Vxx[i, a] * A[a, j]
                VA[i, j] = s
            for j in range(m):
                s = 0.0
                for a in range(n):
                    s += Vxx[i, a] * B[a, j]
                VB[i, j] = s
        for i in range(n):
            s = lx[t, i]
            for a in range(n):
                s += A[a, i] * Vx[a]
            Qx[i] = s
            for j in range(n):
                s = lxx[t, i, j]
                for a in range(n):
                    s += A[a, i] * VA[a, j]
                Qxx[i, j] = s
        for i in range(m):
            s = lu[t, i]
            for a in range(n):
                s += B[a, i] * Vx[a]
            Qu[i] = s
            for j in range(m):
                s = luu[t, i, j]
                for a in range(n):
                    s += B[a, i] * VB[a, j]
                Quu[i, j] = s
            for j in range(n):
                s = lux[t, i, j]
                for a in range(n):
                    s += B[a, i] * VA[a, j]
                Qux[i, j] = s
        if second_order:
            for c in range(n):
                v = Vx[c]
                for i in range(n):
                    for j in range(n):
                        Qxx[i, j] += v * fxx[t, c, i, j]
                for i in range(m):
                    for j in range(n):
                        Qux[i, j] += v * fux[t, c, i, j]
                    for j in range(m):
                        Quu[i, j] += v * fuu[t, c, i, j]
        for i in range(m):
            for j in range(m):
                Quu_out[t, i, j] = Quu[i, j]
                H[i, j] = 0.5 * (Quu[i, j] + Quu[j, i])
                Qs[i, j] = H[i, j]
            H[i, i] += mu
            lo[i] = lb[t, i] - U[t, i]
            hi[i] = ub[t, i] - U[t, i]
        status, _ = boxqp_nb(H, Qu, lo, hi, k_warm[t], kk, fr, L, 100)
        if status == -1:
            return t
        nf = 0
        for i in range(m):
            free_out[t, i] = fr[i]
            k[t, i] = kk[i]
            if fr[i]:
                idx[nf] = i
                nf += 1
        for i in range(m):
            for j in range(n):
                K[t, i, j] = 0.0
        if nf > 0:
            for j in range(n):
                for a in range(nf):
                    col[a] = Qux[idx[a], j]
                _chol_solve_inplace(L, nf, col)
                for a in range(nf):
                    K[t, idx[a], j] = -col[a]
        # expected change and value function update (Tassa et al. 2012, Eq. (11))
        for i in range(m):
            s = 0.0
            for j in range(m):
                s += Qs[i, j] * kk[j]
            Quk[i] = s
        for i in range(m):
            dV[0] += kk[i] * Qu[i]
            dV[1] += 0.5 * kk[i] * Quk[i]
        Kt = K[t]
        for i in range(n):
            s = Qx[i]
            for a in range(m):
                s += Kt[a, i] * (Quk[a] + Qu[a]) + Qux[a, i] * kk[a]
            Vx[i] = s
        for i in range(n):
            for j in range(n):
                s = Qxx[i, j]
                for a in range(m):
                    hk = 0.0
                    for b in range(m):
                        hk += Qs[a, b] * Kt[b, j]
                    s += Kt[a, i] * hk + Kt[a, i] * Qux[a, j] + Qux[a, i] * Kt[a, j]
                VA[i, j] = s
        for i in range(n):
            for j in range(n):
                Vxx[i, j] = 0.5 * (VA[i, j] + VA[j, i])
    return -1


# ------------------------------------------------------------------------------------------------
# cart-pole (Eqs. (8.11)-(8.12), explicit Euler): rollout and analytic derivatives
# ------------------------------------------------------------------------------------------------
@_njit
def cartpole_forward_nb(x0, Xn, Un, K, k, alpha, lb, ub, h, g, l, d, X, U):
    """Closed-loop rollout u_t = clip(Un_t + alpha k_t + K_t (x_t - Xn_t)), x_{t+1} = x_t + h f(x_t, u_t).
    Writes X (T+1, 4), U (T, 1); returns False if a state became non-finite."""
    T = Un.shape[0]
    for i in range(4):
        X[0, i] = x0[i]
    for t in range(T):
        u = Un[t, 0] + alpha * k[t, 0]
        for j in range(4):
            u += K[t, 0, j] * (X[t, j] - Xn[t, j])
        u = min(max(u, lb[t, 0]), ub[t, 0])
        U[t, 0] = u
        th = X[t, 0]
        w = X[t, 1]
        X[t + 1, 0] = th + h * w
        X[t + 1, 1] = w + h * (-(g / l) * math.sin(th) + (u / l) * math.cos(th) - d * w)
        X[t + 1, 2] = X[t, 2] + h * X[t, 3]
        X[t + 1, 3] = X[t, 3] + h * u
        if not (math.isfinite(X[t + 1, 0]) and math.isfinite(X[t + 1, 1])):
            return False
    return True


@_njit
def cartpole_derivs_nb(X, U, h, g, l, d, fx, fu, fxx, fux, second_order):
    """Analytic Jacobians fx (T,4,4), fu (T,4,1) and, if second_order, fxx (T,4,4,4), fux (T,4,1,4)."""
    T = U.shape[0]
    for t in range(T):
        th = X[t, 0]
        u = U[t, 0]
        s = math.sin(th)
        c = math.cos(th)
        for i in range(4):
            for j in range(4):
                fx[t, i, j] = 1.0 if i == j else 0.0
        fx[t, 0, 1] = h
        fx[t, 1, 0] = h * (-(g / l) * c - (u / l) * s)
        fx[t, 1, 1] = 1.0 - h * d
        fx[t, 2, 3] = h
        fu[t, 0, 0] = 0.0
        fu[t, 1, 0] = h * c / l
        fu[t, 2, 0] = 0.0
        fu[t, 3, 0] = h
        if second_order:
            fxx[t, 1, 0, 0] = h * ((g / l) * s - (u / l) * c)
            fux[t, 1, 0, 0] = -h * s / l


# ------------------------------------------------------------------------------------------------
# LTV model rollout
# ------------------------------------------------------------------------------------------------
@_njit
def ltv_forward_nb(x0, Xn, Un, K, k, alpha, lb, ub, A, B, c, X, U):
    """Closed-loop rollout of x_{t+1} = A_t x_t + B_t u_t + c_t; returns False on a non-finite state."""
    T = Un.shape[0]
    n = x0.shape[0]
    m = Un.shape[1]
    for i in range(n):
        X[0, i] = x0[i]
    for t in range(T):
        for a in range(m):
            u = Un[t, a] + alpha * k[t, a]
            for j in range(n):
                u += K[t, a, j] * (X[t, j] - Xn[t, j])
            U[t, a] = min(max(u, lb[t, a]), ub[t, a])
        for i in range(n):
            s = c[t, i]
            for j in range(n):
                s += A[t, i, j] * X[t, j]
            for a in range(m):
                s += B[t, i, a] * U[t, a]
            if not math.isfinite(s):
                for tt in range(t + 1, T + 1):
                    for ii in range(n):
                        X[tt, ii] = np.nan
                return False
            X[t + 1, i] = s
    return True
