"""Fused compiled loops of the Kalman filter and RTS smoother (thesis Sec. 4.3, Eqs. (4.16)-(4.25)).

:func:`kf_forward` runs the whole forward pass of a constant-matrix model (correct with y[t] in Joseph form,
then predict with u[t]; NaN rows of y = predict only) and :func:`rts_smooth_fused` the RTS backward pass, with
small dense helpers written as loops (Cholesky factor and solves, never an inverse).  They compute the same
equations as :func:`drake_est.estimation.gaussian.joseph_correct` / :func:`~drake_est.estimation.gaussian.rts_backward`
(the pure-numpy path), equal to 1e-10 (tested).  ``DRAKE_EST_NO_NUMBA=1`` or a missing numba selects numpy.
"""
from __future__ import annotations

import math
import os

import numpy as np

try:
    import numba
    HAVE_NUMBA = True
except ImportError:          # pragma: no cover - numba is a dependency; the numpy path stays usable
    numba = None
    HAVE_NUMBA = False


def use_numba() -> bool:
    """True unless numba is missing or the environment sets DRAKE_EST_NO_NUMBA=1."""
    return HAVE_NUMBA and os.environ.get("DRAKE_EST_NO_NUMBA", "") in ("", "0")


def _njit(f):
    return numba.njit(cache=True, fastmath=False)(f) if HAVE_NUMBA else f


@_njit
def _chol(S, L):
    """Lower Cholesky factor of S into L; returns False when S is not positive definite."""
    n = S.shape[0]
    for j in range(n):
        s = S[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            return False
        d = math.sqrt(s)
        L[j, j] = d
        for i in range(j + 1, n):
            s = S[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / d
        for i in range(j):
            L[i, j] = 0.0
    return True


@_njit
def _cho_solve(L, B, X):
    """X = (L L^T)^{-1} B for B (n, m) by forward and back substitution."""
    n, m = B.shape
    for c in range(m):
        for i in range(n):
            s = B[i, c]
            for k in range(i):
                s -= L[i, k] * X[k, c]
            X[i, c] = s / L[i, i]
        for i in range(n - 1, -1, -1):
            s = X[i, c]
            for k in range(i + 1, n):
                s -= L[k, i] * X[k, c]
            X[i, c] = s / L[i, i]


@_njit
def _mm(A, B, out):
    """out = A @ B."""
    n, k = A.shape
    m = B.shape[1]
    for i in range(n):
        for j in range(m):
            s = 0.0
            for r in range(k):
                s += A[i, r] * B[r, j]
            out[i, j] = s


@_njit
def _mmt(A, B, out):
    """out = A @ B.T."""
    n, k = A.shape
    m = B.shape[0]
    for i in range(n):
        for j in range(m):
            s = 0.0
            for r in range(k):
                s += A[i, r] * B[j, r]
            out[i, j] = s


@_njit
def _sym(P):
    n = P.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            v = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = v
            P[j, i] = v


@_njit
def kf_forward(A, B, C, D, R1, R2, x0, P0, u, y, missing, xf, Pf, xp, Pp):
    """Forward Kalman pass for constant (A, B, C, D, R1, R2); fills xf, Pf, xp, Pp in place.

    Returns (log-likelihood, 0) or (nan, t+1) when S was not positive definite at step t."""
    T = y.shape[0]
    nx, ny, nu = A.shape[0], C.shape[0], B.shape[1]
    x = x0.copy()
    P = P0.copy()
    PCt = np.empty((nx, ny))
    S = np.empty((ny, ny))
    L = np.empty((ny, ny))
    Kt = np.empty((ny, nx))
    e = np.empty(ny)
    Se = np.empty((ny, 1))
    IKC = np.empty((nx, nx))
    T1 = np.empty((nx, nx))
    T2 = np.empty((nx, nx))
    KR = np.empty((nx, ny))
    xn = np.empty(nx)
    ll = 0.0
    c0 = ny * math.log(2.0 * math.pi)
    for t in range(T):
        xp[t] = x
        Pp[t] = P
        if not missing[t]:
            for i in range(ny):
                s = y[t, i]
                for k in range(nx):
                    s -= C[i, k] * x[k]
                for k in range(nu):
                    s -= D[i, k] * u[t, k]
                e[i] = s
            _mmt(P, C, PCt)
            _mm(C, PCt, S)
            for i in range(ny):
                for j in range(ny):
                    S[i, j] += R2[i, j]
            _sym(S)
            if not _chol(S, L):
                return math.nan, t + 1
            _cho_solve(L, PCt.T.copy(), Kt)            # K^T = S^{-1} C P
            for i in range(nx):
                s = 0.0
                for k in range(ny):
                    s += Kt[k, i] * e[k]
                x[i] += s
            for i in range(nx):
                for j in range(nx):
                    s = 1.0 if i == j else 0.0
                    for k in range(ny):
                        s -= Kt[k, i] * C[k, j]
                    IKC[i, j] = s
            _mm(IKC, P, T1)
            _mmt(T1, IKC, T2)
            _mm(Kt.T.copy(), R2, KR)
            _mm(KR, Kt, T1)
            for i in range(nx):
                for j in range(nx):
                    P[i, j] = T2[i, j] + T1[i, j]
            _sym(P)
            for i in range(ny):
                Se[i, 0] = e[i]
            Sie = np.empty((ny, 1))
            _cho_solve(L, Se, Sie)
            quad = 0.0
            logdet = 0.0
            for i in range(ny):
                quad += e[i] * Sie[i, 0]
                logdet += math.log(abs(L[i, i]))
            ll += -0.5 * (quad + 2.0 * logdet + c0)
        xf[t] = x
        Pf[t] = P
        for i in range(nx):
            s = 0.0
            for k in range(nx):
                s += A[i, k] * x[k]
            for k in range(nu):
                s += B[i, k] * u[t, k]
            xn[i] = s
        x[:] = xn
        _mm(A, P, T1)
        _mmt(T1, A, P)
        for i in range(nx):
            for j in range(nx):
                P[i, j] += R1[i, j]
        _sym(P)
    xp[T] = x
    Pp[T] = P
    return ll, 0


@_njit
def rts_smooth_fused(A, xf, Pf, xp, Pp, xs, Ps):
    """RTS backward pass for a constant A (cross covariance P_{t|t} A^T); fills xs, Ps.

    Returns 0, or t+2 when P_{t+1|t} was not positive definite at step t."""
    T, nx = xf.shape
    xs[T - 1] = xf[T - 1]
    Ps[T - 1] = Pf[T - 1]
    L = np.empty((nx, nx))
    cross = np.empty((nx, nx))
    Gt = np.empty((nx, nx))
    dP = np.empty((nx, nx))
    T1 = np.empty((nx, nx))
    T2 = np.empty((nx, nx))
    for t in range(T - 2, -1, -1):
        _mmt(Pf[t], A, cross)
        if not _chol(Pp[t + 1], L):
            return t + 2
        _cho_solve(L, cross.T.copy(), Gt)           # G^T = P_{t+1|t}^{-1} cross^T
        for i in range(nx):
            s = xf[t, i]
            for k in range(nx):
                s += Gt[k, i] * (xs[t + 1, k] - xp[t + 1, k])
            xs[t, i] = s
        for i in range(nx):
            for j in range(nx):
                dP[i, j] = Ps[t + 1, i, j] - Pp[t + 1, i, j]
        _mm(Gt.T.copy(), dP, T1)
        _mm(T1, Gt, T2)
        for i in range(nx):
            for j in range(nx):
                Ps[t, i, j] = Pf[t, i, j] + T2[i, j]
        _sym(Ps[t])
    return 0
