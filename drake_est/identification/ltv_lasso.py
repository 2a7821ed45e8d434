"""Group-lasso LTV identification, thesis Eqs. (7.6)/(7.9): working-set primal-dual Newton solver with a
duality-gap certificate, ADMM (plain and linearized) as fallback.

Split out of :mod:`drake_est.identification.ltv`, which re-exports every name."""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from drake_est.errors import DataError, IdentifiabilityError
from drake_est.identification.ltv_banded import banded_lower
from drake_est.identification.ltv_common import (_apply_D, _apply_DT, _as_regression, _as_state_space, _check_lam,
                                                 _cluster_times, _poly, _reg_bands, _to_ltv, change_points,
                                                 check_identifiable)


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
