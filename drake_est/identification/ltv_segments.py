"""Piecewise-constant LTV models: change points and knots, the two-step refinement (7.10), and the known
number of switches (7.8) by dynamic programming (thesis Algorithm 3).

Split out of :mod:`drake_est.identification.ltv`, which re-exports every name."""
from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations

import numpy as np

from drake_est.errors import DataError, IdentifiabilityError
from drake_est.identification.ltv_common import _as_regression, _as_state_space, _poly, _to_ltv, check_identifiable
from drake_est.identification.ltv_smoother import _tv_smooth


# =============================================================================================
# change points, knots and the two-step refinement (7.10)
# =============================================================================================
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
