"""Block-tridiagonal solver used by the LTV smoother (Ch. 7): mean, marginal covariances, log-det.

The normal equations of (7.3)/(7.5)/(7.13) are block banded; they are exactly the
information form of the Kalman smoothing problem on the parameter-state model
(7.2)/(7.11).  Grouping ``d`` consecutive time steps makes them block tridiagonal,
which we solve by *block cyclic reduction*: every level eliminates the odd blocks
with one batched numpy solve, so the per-time-step Python loop of a textbook RTS
smoother becomes ~log2(T) vectorized levels.  The selected inverse (diagonal and
first off-diagonal blocks of H^{-1}, i.e. the smoothed covariances P_{t|T} and
cross-covariances P_{t+1,t|T}) is recovered on the way back up, and the log-det of
H (needed for the likelihood) is accumulated on the way down.  Cyclic reduction of
a symmetric positive definite matrix is a symmetric permutation followed by block
Cholesky, so every pivot block is SPD.
"""
from __future__ import annotations

import numpy as np


def _tr(M):
    return np.swapaxes(M, -1, -2)


def block_tridiag_solve(D, L, R, want_cov: bool = True, want_logdet: bool = True):
    """Solve H x = R for SPD block-tridiagonal H.

    D: (N, q, q) diagonal blocks, L: (N-1, q, q) with L[i] = H[i+1, i], R: (N, q, r).
    Returns (x (N, q, r), S (N, q, q) or None, So (N-1, q, q) or None, logdet(H) or None),
    where S[i] = (H^{-1})[i, i] and So[i] = (H^{-1})[i+1, i].
    """
    N, q, _ = D.shape
    if N == 1:
        c = np.linalg.cholesky(D[0])
        x = np.linalg.solve(D[0], R[0])[None]
        S = np.linalg.solve(D[0], np.eye(q))[None] if want_cov else None
        ld = 2.0 * float(np.sum(np.log(np.diag(c)))) if want_logdet else None
        return x, S, (np.empty((0, q, q)) if want_cov else None), ld
    Do = D[1::2]
    No = Do.shape[0]
    Ne = N - No
    Hl = L[0::2][:No]                      # H[i, i-1] for odd i
    Hr = np.zeros_like(Hl)                 # H[i, i+1] for odd i (zero past the end)
    Lr = L[1::2]
    Hr[:Lr.shape[0]] = _tr(Lr)
    r = R.shape[2]
    blocks = [Hl, Hr, R[1::2]]
    if want_cov:
        blocks.append(np.broadcast_to(np.eye(q), (No, q, q)))
    W = np.linalg.solve(Do, np.concatenate(blocks, axis=2))
    Wl, Wr, Xo = W[:, :, :q], W[:, :, q:2 * q], W[:, :, 2 * q:2 * q + r]
    # Schur complement onto the even blocks (two batched products give all the terms)
    M1 = _tr(Hl) @ W[:, :, :2 * q + r]               # [Hl^T Wl, Hl^T Wr, Hl^T Xo]
    M2 = _tr(Hr) @ W[:, :, :2 * q + r]               # [Hr^T Wl, Hr^T Wr, Hr^T Xo]
    De = D[0::2].copy()
    De[:No] -= M1[:, :, :q]
    De[1:] -= M2[:Ne - 1, :, q:2 * q]
    Le = -M2[:Ne - 1, :, :q]
    Re = R[0::2].copy()
    Re[:No] -= M1[:, :, 2 * q:]
    Re[1:] -= M2[:Ne - 1, :, 2 * q:]
    xe, Se, Soe, lde = block_tridiag_solve(De, Le, Re, want_cov, want_logdet)
    # back substitution for the odd blocks: xo = Xo - [Wl Wr] [x_{i-1}; x_{i+1}]
    WW = W[:, :, :2 * q]
    xn = np.zeros((No, 2 * q, r))
    xn[:, :q] = xe[:No]
    xn[:Ne - 1, q:] = xe[1:]
    xo = Xo - WW @ xn
    x = np.empty((N, q, r))
    x[0::2], x[1::2] = xe, xo
    ld = None
    if want_logdet:
        sign, lds = np.linalg.slogdet(Do)
        ld = float(np.sum(lds)) + lde
    if not want_cov:
        return x, None, None, ld
    Dinv = W[:, :, 2 * q + r:]
    # Sigma of the two even neighbours [[S(i-1,i-1), S(i-1,i+1)], [S(i+1,i-1), S(i+1,i+1)]]
    SK = np.zeros((No, 2 * q, 2 * q))
    SK[:, :q, :q] = Se[:No]
    SK[:Ne - 1, q:, q:] = Se[1:]
    SK[:Soe.shape[0], q:, :q] = Soe[:No]
    SK[:Soe.shape[0], :q, q:] = _tr(Soe[:No])
    SLR = -(WW @ SK)                                 # [Sigma(i, i-1), Sigma(i, i+1)]
    So_odd = Dinv - SLR @ _tr(WW)
    SL, SR = SLR[:, :, :q], SLR[:, :, q:]
    S = np.empty((N, q, q))
    S[0::2], S[1::2] = Se, 0.5 * (So_odd + _tr(So_odd))
    So = np.empty((N - 1, q, q))
    So[0::2] = SL[:So[0::2].shape[0]]                # Sigma[2o+1, 2o]
    So[1::2] = _tr(SR)[:So[1::2].shape[0]]           # Sigma[2o+2, 2o+1]
    return x, S, So, ld


def group_blocks(Hb, R, g):
    """Turn block-banded H (Hb[o][s] = H[s+o, s], o = 0..g, each (T, p, p)) and R (T, p, r)
    into a block-tridiagonal system with super-blocks of g consecutive time steps.

    Missing trailing steps are padded with identity diagonal blocks (decoupled, zero rhs,
    zero contribution to the log-det)."""
    T, p, _ = Hb[0].shape
    r = R.shape[2]
    Tn = -(-T // g)
    Tp = Tn * g
    pad = Tp - T
    Hp = []
    for o, B in enumerate(Hb):
        Bp = np.zeros((Tp, p, p))
        Bp[:T] = B
        if o == 0 and pad:
            Bp[T:] = np.eye(p)
        Hp.append(Bp)
    Rp = np.zeros((Tp, p, r))
    Rp[:T] = R
    q = g * p
    D = np.zeros((Tn, q, q))
    L = np.zeros((max(Tn - 1, 0), q, q))
    s = np.arange(Tn) * g
    for a in range(g):
        for b in range(g):
            if a >= b:
                D[:, a * p:(a + 1) * p, b * p:(b + 1) * p] = Hp[a - b][s + b]
            else:
                D[:, a * p:(a + 1) * p, b * p:(b + 1) * p] = _tr(Hp[b - a][s + a])
            o = g + a - b
            if Tn > 1 and o < len(Hp):
                L[:, a * p:(a + 1) * p, b * p:(b + 1) * p] = Hp[o][s[:-1] + b]
    return D, L, Rp.reshape(Tn, q, r), pad


def ungroup(x, S, T, p):
    """Inverse of :func:`group_blocks` for the solution and the diagonal covariance blocks."""
    Tn, q, r = x.shape
    g = q // p
    xt = x.reshape(Tn * g, p, r)[:T]
    St = None
    if S is not None:
        St = np.empty((Tn * g, p, p))
        for a in range(g):
            St[a::g] = S[:, a * p:(a + 1) * p, a * p:(a + 1) * p]
        St = St[:T]
    return xt, St


def banded_lower(Hb):
    """LAPACK lower band storage (for scipy.linalg.cholesky_banded) of block-banded H."""
    T, p, _ = Hb[0].shape
    d = len(Hb) - 1
    n = T * p
    bw = (d + 1) * p - 1
    ab = np.zeros((bw + 1, n))
    for o, B in enumerate(Hb):
        m = B.shape[0]
        for a in range(p):
            for b in range(p):
                k = o * p + a - b
                if k < 0 or k > bw:
                    continue
                cols = np.arange(m) * p + b
                rows = cols + k
                ok = rows < n
                ab[k, cols[ok]] = B[ok, a, b]
    return ab
