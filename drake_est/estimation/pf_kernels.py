"""Fused compiled loop of the Gaussian bootstrap particle filter (thesis Algorithm 1).

:func:`run_fused` runs :class:`drake_est.estimation.pf.GaussianParticleFilter` over a log with the model
given per particle (``f_point(x, u, t, out)``, ``h_point(x, u, t, out)``, compiled by numba): weighting,
log-likelihood, ESS, weighted mean/covariance, systematic resampling and propagation in one pass per step.
It consumes the filter's own pre-drawn random numbers (``pf.normals(t)``, ``pf.uniform(t)``), so it gives the
numpy loop's numbers to rounding (tested to 1e-10).  ``DRAKE_EST_NO_NUMBA=1`` or a missing numba selects
the numpy loop.
"""
from __future__ import annotations

import numpy as np

from drake_est.estimation.protocol import FilterResult, check_inputs

try:
    import numba
    HAVE_NUMBA = True
except ImportError:          # pragma: no cover - numba is a dependency, but keep the numpy path usable
    numba = None
    HAVE_NUMBA = False

_JIT_CACHE: dict = {}


def jit_point(fun):
    """numba-compile a per-particle model function (kept per function object)."""
    key = id(fun)
    hit = _JIT_CACHE.get(key)
    if hit is not None and hit[0] is fun:
        return hit[1]
    j = fun if isinstance(fun, numba.core.registry.CPUDispatcher) else numba.njit(fun, fastmath=False)
    _JIT_CACHE[key] = (fun, j)
    return j


_LN2_HI, _LN2_LO, _INV_LN2 = 6.93147180369123816490e-01, 1.90821492927058770002e-10, 1.44269504088896338700e+00
_C2, _C3, _C4, _C5, _C6 = 1 / 2, 1 / 6, 1 / 24, 1 / 120, 1 / 720
_C7, _C8, _C9, _C10, _C11, _C12 = 1 / 5040, 1 / 40320, 1 / 362880, 1 / 3628800, 1 / 39916800, 1 / 479001600


def vexp(a, shift, out, kbuf):
    """out[i] = exp(a[i] - shift) for arguments <= 0 (0 below -708, so exp(-inf) = 0), to ~3e-16 relative.

    Written as two call-free loops that LLVM vectorises (numba's scalar exp is ~4x slower per element):
    exp(x) = 2^k exp(r), k = round(x / ln 2), |r| <= ln(2)/2, exp(r) by its degree-12 Taylor polynomial, 2^k
    built from the exponent bits."""
    n = a.shape[0]
    for i in range(n):
        x = max(a[i] - shift, -708.0)
        k = np.floor(x * _INV_LN2 + 0.5)
        r = (x - k * _LN2_HI) - k * _LN2_LO
        out[i] = 1.0 + r * (1.0 + r * (_C2 + r * (_C3 + r * (_C4 + r * (_C5 + r * (_C6 + r * (_C7 + r * (
            _C8 + r * (_C9 + r * (_C10 + r * (_C11 + r * _C12)))))))))))
        kbuf[i] = (np.int64(k) + 1023) << 52
    sc = kbuf.view(np.float64)
    for i in range(n):
        v = out[i] * sc[i]
        out[i] = v if a[i] - shift > -708.0 else 0.0


if HAVE_NUMBA:
    vexp = numba.njit(cache=True)(vexp)


def _chunk_loop(f_point, h_point, x, xn, logw, w, u, y, missing, t0, K, z, uu, L1, diag1, L2, inv_sd, diag2,
                g0, thr, xf, Pf, xp, Pp, ess, flags, cov):
    """Steps t0 .. t0+K-1 of Algorithm 1 (in place on x, logw, w and the outputs); returns the summed
    log-likelihood.  On entry xp[t0] holds the predicted mean of (x, w); each step writes xp[t+1] while
    propagating (one pass over the particles per stage: weight, normalise + mean, resample, propagate + mean).
    ``xn`` is a scratch array of x's shape; the particles end in ``x``.

    flags[t]: bit 0 resampled, bit 1 degenerate (every weight zero), bit 2 non-finite particle replaced."""
    N, nx = x.shape
    ny = y.shape[1]
    T = y.shape[0]
    a = np.empty(N)
    yh = np.empty(ny)
    r = np.empty(ny)
    kbuf = np.empty(N, np.int64)
    fx = np.empty(nx)
    m = np.empty(nx)
    d1 = np.empty(nx)
    for p in range(nx):
        d1[p] = L1[p, p]
    x0 = x
    ll = 0.0
    lnN = np.log(N)
    for k in range(K):
        t = t0 + k
        if t >= T:
            break
        ut = u[t]
        if cov:
            _wcov(x, w, xp[t], Pp[t])
        if not missing[t]:
            # weights: a_i = logw_i + log N(y; h(x_i), R2)    (thesis Algorithm 1, weighting)
            nanlike = False
            amax = -np.inf
            for i in range(N):
                h_point(x[i], ut, t, yh)
                qd = 0.0
                if diag2:
                    for p in range(ny):
                        e = (y[t, p] - yh[p]) * inv_sd[p]
                        qd += e * e
                else:
                    for p in range(ny):
                        s = y[t, p] - yh[p]
                        for q in range(p):
                            s -= L2[p, q] * r[q]
                        r[p] = s / L2[p, p]
                        qd += r[p] * r[p]
                gi = g0 - 0.5 * qd
                ai = logw[i] + gi
                if ai - ai != 0.0:                  # non-finite (rare): weight zero, resample if NaN/+inf
                    if gi != -np.inf:
                        nanlike = True
                    ai = -np.inf
                a[i] = ai
                if ai > amax:
                    amax = ai
            degenerate = amax == -np.inf
            if degenerate:
                flags[t] |= 2
                for i in range(N):
                    a[i] = logw[i]
                    if a[i] > amax:
                        amax = a[i]
            vexp(a, amax, w, kbuf)
            s = 0.0
            for i in range(N):
                s += w[i]
            lse = amax + np.log(s)
            ll += lse if not degenerate else -np.inf
            # normalise, ESS and the filtered mean in one pass
            s2 = 0.0
            inv_s = 1.0 / s
            for p in range(nx):
                m[p] = 0.0
            for i in range(N):
                wi = w[i] * inv_s
                w[i] = wi
                logw[i] = a[i] - lse
                s2 += wi * wi
                for p in range(nx):
                    m[p] += wi * x[i, p]
            e = 1.0 / s2
            ess[t] = e
            for p in range(nx):
                xf[t, p] = m[p]
            if cov:
                _wcov(x, w, m, Pf[t])
            if e < thr * N or nanlike:
                flags[t] |= 1
                _systematic_into(x, w, uu[k], xn)
                x, xn = xn, x
                for i in range(N):
                    logw[i] = -lnN
                    w[i] = 1.0 / N
        else:
            xf[t, :] = xp[t]
            if cov:
                Pf[t, :, :] = Pp[t]
        # propagate x_i <- f(x_i) + L1 z_i and accumulate the predicted mean of step t+1
        for p in range(nx):
            m[p] = 0.0
        chk = 0.0
        for i in range(N):
            f_point(x[i], ut, t, fx)
            wi = w[i]
            for p in range(nx):
                if diag1:
                    v = fx[p] + d1[p] * z[k, i, p]
                else:
                    v = fx[p]
                    for q in range(p + 1):
                        v += L1[p, q] * z[k, i, q]
                xn[i, p] = v
                chk += v - v                        # NaN once any entry is non-finite
                m[p] += wi * v
        x, xn = xn, x
        if chk != 0.0:
            anybad = False
            for i in range(N):
                for p in range(nx):
                    if not np.isfinite(x[i, p]):
                        logw[i] = -np.inf
                        anybad = True
            if anybad:
                flags[t] |= 4
                amax = -np.inf
                for i in range(N):
                    if logw[i] > amax:
                        amax = logw[i]
                s = 0.0
                for i in range(N):
                    s += np.exp(logw[i] - amax)
                lse = amax + np.log(s)
                for i in range(N):
                    w[i] = np.exp(logw[i] - lse)
                _systematic_into(x, w, uu[k], xn)
                x, xn = xn, x
                for i in range(N):
                    logw[i] = -lnN
                    w[i] = 1.0 / N
            _wmoments(x, w, m, xp[t + 1], Pp[t + 1], False)
        else:
            for p in range(nx):
                xp[t + 1, p] = m[p]
    if x is not x0:             # the particles must end in the caller's array
        xn[:, :] = x
    return ll


def _wcov(x, w, m, Pout):
    """Weighted covariance sum_i w_i (x_i - m)(x_i - m)^T about the given mean m."""
    N, nx = x.shape
    for p in range(nx):
        for q in range(nx):
            Pout[p, q] = 0.0
    for i in range(N):
        for p in range(nx):
            dp = w[i] * (x[i, p] - m[p])
            for q in range(p + 1):
                Pout[p, q] += dp * (x[i, q] - m[q])
    for p in range(nx):
        for q in range(p):
            Pout[q, p] = Pout[p, q]


def _wmoments(x, w, m, mout, Pout, cov):
    N, nx = x.shape
    for p in range(nx):
        m[p] = 0.0
    for i in range(N):
        for p in range(nx):
            m[p] += w[i] * x[i, p]
    for p in range(nx):
        mout[p] = m[p]
    if cov:
        _wcov(x, w, m, Pout)


def weight_step(x, logw, yh, y, inv_sd, thr, u0, cov, mout, Pout, xbuf, w, a, kbuf):
    """One measurement update of the generic Gaussian PF (thesis Algorithm 1, weighting and resampling;
    the user's h already evaluated: yh (N, ny)); ``a`` (N,) and ``kbuf`` (N,) int64 are scratch.

    a_i = logw_i - 0.5 |(yh_i - y) * inv_sd|^2; normalises into ``logw`` and ``w``, writes the weighted mean
    (and covariance) of x, resamples into ``xbuf`` when ESS < thr.  Returns (status, log-sum, ess): status -1
    = every weight zero / non-finite (nothing modified; the caller takes the general path), 0 = weighted,
    1 = weighted and resampled (the particles are in ``xbuf``)."""
    N, ny = yh.shape
    nx = x.shape[1]
    amax = -np.inf
    for i in range(N):
        q = 0.0
        for p in range(ny):
            e = (yh[i, p] - y[p]) * inv_sd[p]
            q += e * e
        ai = logw[i] - 0.5 * q
        a[i] = ai
        if ai > amax or ai != ai:
            amax = ai
    if not np.isfinite(amax):
        return -1, 0.0, 0.0
    vexp(a, amax, w, kbuf)
    s = 0.0
    for i in range(N):
        s += w[i]
    lse = amax + np.log(s)
    s2 = 0.0
    inv_s = 1.0 / s
    for p in range(nx):
        mout[p] = 0.0
    for i in range(N):
        wi = w[i] * inv_s
        w[i] = wi
        s2 += wi * wi
        for p in range(nx):
            mout[p] += wi * x[i, p]
    ess = 1.0 / s2
    if cov:
        _wcov(x, w, mout, Pout)
    if ess < thr:
        _systematic_into(x, w, u0, xbuf)
        ln = -np.log(N)
        for i in range(N):
            logw[i] = ln
            w[i] = 1.0 / N
        return 1, lse, ess
    for i in range(N):
        logw[i] = a[i] - lse
    return 0, lse, ess


def _systematic_into(x, w, u0, xn):
    """xn <- x[idx], idx of pf.systematic_resample (searchsorted 'left' on the sequential cumulative sum,
    which is accumulated on the fly here; same sums as np.cumsum)."""
    N, nx = x.shape
    i = 0
    c = w[0]
    for j in range(N):
        pos = (u0 + j) / N
        while i < N - 1 and c < pos:
            i += 1
            c += w[i]
        for p in range(nx):
            xn[j, p] = x[i, p]


def propagate(xn, z, L1, diag, out, w, mout):
    """out = xn + L1 z row by row (L1 lower triangular; only its diagonal when ``diag``) and
    mout = sum_i w_i out_i (the predicted mean); True when every entry is finite."""
    N, nx = xn.shape
    chk = 0.0
    for p in range(nx):
        mout[p] = 0.0
    if diag:
        d = np.empty(nx)
        for p in range(nx):
            d[p] = L1[p, p]
        for i in range(N):
            wi = w[i]
            for p in range(nx):
                s = xn[i, p] + z[i, p] * d[p]
                out[i, p] = s
                chk += s - s
                mout[p] += wi * s
    else:
        for i in range(N):
            wi = w[i]
            for p in range(nx):
                s = 0.0
                for q in range(p + 1):
                    s += z[i, q] * L1[p, q]
                s = xn[i, p] + s
                out[i, p] = s
                chk += s - s
                mout[p] += wi * s
    return chk == 0.0


def wcov(x, w, m, Pout):
    """Weighted covariance about a given mean (compiled entry point of :func:`_wcov`)."""
    _wcov(x, w, m, Pout)


def moments(x, w, cov, mout, Pout):
    """Weighted mean (and covariance) of x with normalised weights w."""
    m = np.empty(x.shape[1])
    _wmoments(x, w, m, mout, Pout, cov)


if HAVE_NUMBA:
    _wmoments = numba.njit(cache=True)(_wmoments)
    _wcov = numba.njit(cache=True)(_wcov)
    wcov = numba.njit(cache=True)(wcov)
    _systematic_into = numba.njit(cache=True)(_systematic_into)
    weight_step = numba.njit(cache=True)(weight_step)
    moments = numba.njit(cache=True)(moments)
    propagate = numba.njit(cache=True)(propagate)
    _chunk_loop_jit = numba.njit(_chunk_loop)


def run_fused(pf, u, y, covariances: bool = True) -> FilterResult:
    """The compiled forward pass of a GaussianParticleFilter with ``f_point``/``h_point``."""
    u, y, T, missing = check_inputs(u, y, pf.nu, pf.ny)
    f1, h1 = jit_point(pf.f_point), jit_point(pf.h_point)
    N, nx = pf.N, pf.nx
    x, logw = pf.initial_belief()
    uu_ = np.zeros((T, 0)) if u is None else np.ascontiguousarray(u)
    y_ = np.ascontiguousarray(np.nan_to_num(y))
    nc = nx if covariances else 0
    xf = np.empty((T, nx)); Pf = np.empty((T, nc, nc))
    xp = np.empty((T + 1, nx)); Pp = np.empty((T + 1, nc, nc))
    ess = np.full(T, np.nan)
    flags = np.zeros(T, np.int64)
    ll = 0.0
    K = pf.chunk
    x = np.ascontiguousarray(x)
    xn = np.empty_like(x)
    wcur = np.exp(logw)
    m0 = np.empty(nx)
    _wmoments(x, wcur, m0, xp[0], Pp[0], False)
    diag2 = bool(pf._diag2)
    for c in range((T + K - 1) // K):
        z, uu = pf._draws(c)
        ll += _chunk_loop_jit(f1, h1, x, xn, logw, wcur, uu_, y_, missing, c * K, K, z, uu, pf.L1,
                              bool(pf._diag1), pf.L2, pf._inv_sd2, diag2, pf._g0, pf.resample_threshold,
                              xf, Pf, xp, Pp, ess, flags, covariances)
    # moments of the final prediction
    w = np.exp(logw - logw.max()); w /= w.sum()
    m = w @ x
    d = x - m
    xp[T] = m
    if covariances:
        P = (d * w[:, None]).T @ d
        Pp[T] = 0.5 * (P + P.T)
    deg = [int(t) for t in np.flatnonzero(flags & 2)]
    extras = {"ess": ess, "n_resampled": int(np.sum(flags & 1)), "degenerate_steps": deg,
              "n_degenerate": len(deg), "n_particles": N, "compiled": True}
    return FilterResult(xf, Pf, xp, Pp, float(ll), int(missing.sum()), extras)
