"""Particle filters (thesis Sec. 4.2, Algorithm 1) on numpy arrays.

:class:`ParticleFilter` is the bootstrap filter of Algorithm 1 -- weight the particles with the measurement
likelihood p(y|x), estimate, resample, propagate through p(x+|x) -- with two additions the thesis mentions
in passing: resampling only when the effective sample size ESS = 1/sum(w_i^2) drops below a threshold
(systematic resampling, default N/2), and an optional *proposal* q(x+ | x, y+) that may look at the next
measurement (the weights then carry p(x+|x)/q(x+|x, y+)).  Weights are kept as log-weights throughout.

Belief (the filter protocol of :mod:`drake_est.estimation.protocol`): ``(particles (N, nx), logw (N,))``.
After ``correct`` the log-weights are normalised (logsumexp = 0); after ``predict`` they are the normalised
weights plus the log importance ratio log p/q (zero for the bootstrap filter), so that
``log p(y_t | y_{0:t-1}) ~= logsumexp(logw + log p(y_t|x_t^i))`` (the standard unbiased estimate).

Randomness is a pure function of ``seed`` and the time index ``t`` (never hidden generator state), so the
step-by-step protocol loop, :meth:`ParticleFilter.forward_trajectory` and the Drake ``LeafSystem`` give
identical numbers for the same seed.

:meth:`ParticleFilter.gaussian` builds the filter for ``x+ = f(x,u,t) + v, v ~ N(0,R1)``,
``y = h(x,u,t) + e, e ~ N(0,R2)``; with ``f_point``/``h_point`` (per-particle functions compiled by numba)
its ``forward_trajectory`` runs a fused compiled loop (:mod:`drake_est.estimation.pf_kernels`) that gives
the numpy loop's numbers to 1e-10.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import solve_triangular

from drake_est.errors import DataError
from drake_est.estimation.protocol import Filter, FilterResult, check_inputs

_LOG2PI = np.log(2.0 * np.pi)
_CHUNK_BYTES = 1 << 22          # random numbers are drawn in chunks of about 4 MB of normals


# -------------------------------------------------------------------------------------------------
# small numpy building blocks (each used by the step functions and by the fused numpy loop)
# -------------------------------------------------------------------------------------------------
def logsumexp(a) -> float:
    """log(sum(exp(a))) without overflow; -inf when every entry is -inf."""
    m = np.max(a)
    if not np.isfinite(m):
        return float(m) if m == -np.inf else -np.inf
    return float(m + np.log(np.sum(np.exp(a - m))))


def effective_sample_size(logw) -> float:
    """ESS = 1 / sum(w_i^2) of normalised weights (Kong-Liu-Wong)."""
    w = np.exp(logw - logsumexp(logw))
    return float(1.0 / np.dot(w, w))


def systematic_resample(w, u0: float) -> np.ndarray:
    """Systematic resampling: indices i_j = min{i : sum_{k<=i} w_k >= (u0 + j)/N}, u0 ~ U[0, 1).

    ``w`` are normalised weights; one uniform number makes the draw (low variance, O(N))."""
    N = w.shape[0]
    c = np.cumsum(w)
    pos = (u0 + np.arange(N)) / N
    idx = np.searchsorted(c, pos, side="left")
    np.minimum(idx, N - 1, out=idx)
    return idx


def box_muller_f32(rng: np.random.Generator, out: np.ndarray, scratch: np.ndarray) -> None:
    """Fill the float32 vector ``out`` with standard normals by the Box-Muller transform
    z = sqrt(-2 ln(1 - U)) (cos 2 pi V, sin 2 pi V) of float32 uniforms U, V from ``rng``.

    Used for the process noise of the Gaussian particle filter: with numpy's vectorised float32 log/sin/cos
    it costs about 3.4 ns per normal against 8.7 ns for ``standard_normal(dtype=float32)`` (ziggurat) on the
    benchmark machine.  Exact normal marginals up to float32 rounding, except that |z| <= 5.77 (the tail
    beyond, probability 8e-9, is cut by the 2^-24 resolution of U).  Every filter path consumes the same
    array, so they agree to rounding.  ``scratch``: float32 (2, >= ceil(n/2))."""
    n = out.shape[0]
    h = (n + 1) // 2
    U, V = scratch[0, :h], scratch[1, :h]
    rng.random(dtype=np.float32, out=U)
    rng.random(dtype=np.float32, out=V)
    np.subtract(np.float32(1.0), U, out=U)        # (0, 1]: log is finite
    np.log(U, out=U)
    np.multiply(U, np.float32(-2.0), out=U)
    np.sqrt(U, out=U)
    np.multiply(V, np.float32(2.0 * np.pi), out=V)
    np.cos(V, out=out[:h])
    np.multiply(out[:h], U, out=out[:h])
    m = n - h
    np.sin(V[:m], out=out[h:])
    np.multiply(out[h:], U[:m], out=out[h:])


def weighted_moments(x, w):
    """Weighted mean and covariance sum_i w_i (x_i - m)(x_i - m)^T of normalised weights."""
    m = w @ x
    d = x - m
    P = (d * w[:, None]).T @ d
    return m, 0.5 * (P + P.T)


def chol_psd(M, name: str) -> np.ndarray:
    """Lower Cholesky factor of a symmetric positive-definite covariance, or a one-line DataError."""
    M = np.atleast_2d(np.asarray(M, dtype=float))
    if M.ndim != 2 or M.shape[0] != M.shape[1]:
        raise DataError(f"{name} must be a square covariance matrix, got shape {M.shape}")
    if not np.all(np.isfinite(M)):
        raise DataError(f"{name} contains NaN/Inf")
    if not np.allclose(M, M.T, rtol=1e-10, atol=1e-14 * max(1.0, np.abs(M).max())):
        raise DataError(f"{name} is not symmetric")
    try:
        L = np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        raise DataError(f"{name} is not positive definite (min eigenvalue "
                        f"{np.linalg.eigvalsh(M).min():.3g})") from None
    d = np.diag(L)
    if d.min() <= 1e-12 * d.max():
        raise DataError(f"{name} is numerically singular (condition number > 1e24)")
    return L


# -------------------------------------------------------------------------------------------------
@dataclass
class ParticleSmoothResult:
    """Output of :meth:`ParticleFilter.smooth` (FFBSi): ``trajectories`` (M, T, nx) drawn from
    p(x_{0:T-1} | y_{0:T-1}); ``x_smooth``/``P_smooth`` their mean and covariance per step;
    ``filtered`` the forward pass."""
    x_smooth: np.ndarray
    P_smooth: np.ndarray
    trajectories: np.ndarray
    loglik: float
    filtered: FilterResult


class ParticleFilter(Filter):
    """Bootstrap particle filter (Algorithm 1) with ESS-triggered systematic resampling and an optional
    proposal density.

    transition(x, u, t, rng) -> x+        vectorised sampler from p(x+ | x) over all particles, x (N, nx)
    measurement_logpdf(x, y, u, t) -> (N,) vectorised log p(y | x) over all particles
    initial                              (N, nx) array of initial particles, or ``initial(rng, N) -> (N, nx)``
    proposal(x, u, t, y_next, rng) -> x+ optional sampler from q(x+ | x, y+) (``y_next`` is None when the
                                         next measurement is missing or unknown: then ``transition`` is used)
    proposal_logpdf(x+, x, u, t, y_next), transition_logpdf(x+, x, u, t) -> (N,)
                                         log-densities for the importance weights p/q (needed with a proposal)
    resample_threshold                   resample when ESS < resample_threshold * N (default 0.5)

    ``seed`` fixes every random draw: the draws of step t depend only on (seed, t)."""

    def __init__(self, transition, measurement_logpdf, initial, n_particles: int, nx: int | None = None,
                 seed: int = 0, resample_threshold: float = 0.5, proposal=None, proposal_logpdf=None,
                 transition_logpdf=None, nu: int | None = None, ny: int | None = None):
        n = int(n_particles) if np.ndim(n_particles) == 0 else -1
        if n < 2 or n != n_particles:
            raise DataError(f"n_particles must be an integer >= 2, got {n_particles}")
        if not 0.0 <= resample_threshold <= 1.0:
            raise DataError(f"resample_threshold must be in [0, 1], got {resample_threshold}")
        if proposal is not None and (proposal_logpdf is None or transition_logpdf is None):
            raise DataError("proposal needs proposal_logpdf and transition_logpdf (for the weights p/q)")
        if not callable(transition) or not callable(measurement_logpdf):
            raise DataError("transition and measurement_logpdf must be callables")
        self.N = n
        self.seed = int(seed)
        self.resample_threshold = float(resample_threshold)
        self.transition = transition
        self.measurement_logpdf = measurement_logpdf
        self.proposal = proposal
        self.proposal_logpdf = proposal_logpdf
        self.transition_logpdf = transition_logpdf
        self.nu, self.ny = nu, ny
        self._initial = initial
        x = self._initial_particles()
        self.nx = x.shape[1] if nx is None else int(nx)
        if x.shape != (self.N, self.nx):
            raise DataError(f"initial particles have shape {x.shape}, expected ({self.N}, {self.nx})")
        self._x_init = x
        self._chunk_cache = {}

    # -- randomness: a pure function of (seed, stream, t) -----------------------------------------
    def rng(self, t: int, stream: int = 2) -> np.random.Generator:
        """The generator of step t (stream 2: transition, 4: proposal, 5: smoother)."""
        return np.random.default_rng([self.seed, stream, int(t)])

    @property
    def chunk(self) -> int:
        """Steps per chunk of pre-drawn random numbers (depends only on N and nx)."""
        return int(max(1, min(256, _CHUNK_BYTES // (8 * self.N * max(1, self.nx)))))

    def _draws(self, c: int):
        """Chunk c of pre-drawn numbers: standard normals (K, N, nx) (float32, :func:`box_muller_f32`, in a
        buffer reused by the next chunk) and resampling uniforms (K,); a pure function of (seed, c)."""
        hit = self._chunk_cache.get("c")
        if hit is not None and hit[0] == c:
            return hit[1], hit[2]
        K = self.chunk
        rng = np.random.default_rng([self.seed, 1, c])
        z = self._chunk_cache.get("zbuf")
        if z is None:                           # one buffer per filter, refilled in place (no page faults)
            z = self._chunk_cache["zbuf"] = np.empty((K, self.N, self.nx), dtype=np.float32)
            self._chunk_cache["bm"] = np.empty((2, (z.size + 1) // 2), dtype=np.float32)
        box_muller_f32(rng, z.reshape(-1), self._chunk_cache["bm"])
        uu = rng.random(K)
        self._chunk_cache["c"] = (c, z, uu)
        return z, uu

    def normals(self, t: int) -> np.ndarray:
        """Standard normals (N, nx) of step t (used by the Gaussian transition)."""
        z, _ = self._draws(int(t) // self.chunk)
        return z[int(t) % self.chunk]

    def uniform(self, t: int) -> float:
        """The uniform number of systematic resampling at step t."""
        _, uu = self._draws(int(t) // self.chunk)
        return float(uu[int(t) % self.chunk])

    def _initial_particles(self):
        init = self._initial
        rng = np.random.default_rng([self.seed, 0])
        x = init(rng, self.N) if callable(init) else init
        x = np.array(x, dtype=float)
        if x.ndim == 1:
            x = x[:, None]
        if not np.all(np.isfinite(x)):
            raise DataError("initial particles contain NaN/Inf")
        return x

    # -- protocol ---------------------------------------------------------------------------------
    def initial_belief(self):
        return self._x_init.copy(), np.full(self.N, -np.log(self.N))

    def _check_particles(self, x, what):
        x = np.asarray(x, dtype=float)
        if x.shape != (self.N, self.nx):
            raise DataError(f"{what} returned shape {x.shape}, expected (n_particles, nx) = "
                            f"({self.N}, {self.nx})")
        return x

    def _propagate(self, x, u, t, y_next):
        """x+ and the log importance ratio (None for the bootstrap filter)."""
        if self.proposal is not None and y_next is not None:
            rng = self.rng(t, 4)
            xn = self._check_particles(self.proposal(x, u, t, y_next, rng), "proposal")
            lr = (np.asarray(self.transition_logpdf(xn, x, u, t), float)
                  - np.asarray(self.proposal_logpdf(xn, x, u, t, y_next), float))
            return xn, lr
        return self._check_particles(self.transition(x, u, t, self.rng(t)), "transition"), None

    def predict(self, particles, logw, u=None, t: int = 0, y_next=None):
        """Propagate every particle through p(x+|x) (or the proposal, when ``y_next`` is given).

        Particles that become non-finite get weight zero and are replaced by resampling."""
        xn, lr = self._propagate(particles, u, t, y_next)
        logw = logw if lr is None else logw + lr
        bad = ~np.isfinite(xn).all(axis=1)
        if lr is not None:
            bad |= np.isnan(logw)
        if bad.any():
            logw = np.where(bad, -np.inf, logw)
            xn, logw = self._replace_bad(xn, logw, t)
        return xn, logw

    def _replace_bad(self, x, logw, t):
        ls = logsumexp(logw)
        if not np.isfinite(ls):
            raise DataError(f"transition returned non-finite states for every particle at step {t}")
        w = np.exp(logw - ls)
        idx = systematic_resample(w, self.uniform(t))
        return x[idx], np.full(self.N, -np.log(self.N))

    def correct(self, particles, logw, y, u=None, t: int = 0):
        """Weight with log p(y|x), normalise, resample when ESS < threshold * N (Algorithm 1).

        Returns (particles, logw, log p(y_t | y_{0:t-1}) estimate)."""
        particles, logw, ll, _info = self._correct(particles, logw, y, u, t)
        return particles, logw, ll

    def _correct(self, x, logw, y, u, t):
        g = np.asarray(self.measurement_logpdf(x, y, u, t), dtype=float)
        if g.shape != (self.N,):
            raise DataError(f"measurement_logpdf returned shape {g.shape}, expected ({self.N},)")
        return self._weight(x, logw, g, t)

    def _weight(self, x, logw, g, t):
        """Shared by every path: returns (x, logw, ll, (ess, resampled, degenerate, x_filt, P_filt))."""
        a = logw + g
        fin = np.isfinite(a)
        degenerate = False
        if not fin.all():
            a = np.where(fin | (a == -np.inf), a, -np.inf)      # NaN / +inf likelihoods -> weight 0
        ll = logsumexp(a)
        if not np.isfinite(ll):
            # every weight is zero: the measurement is impossible under every particle.  Recover from
            # the prior predictive (keep the predicted weights) and report it.
            degenerate = True
            a = logw
            ll_norm = logsumexp(logw)
            ll = -np.inf
        else:
            ll_norm = ll
        lw = a - ll_norm
        w = np.exp(lw)
        ess = 1.0 / np.dot(w, w)
        m, P = weighted_moments(x, w)
        resampled = bool(ess < self.resample_threshold * self.N) or bool(np.any(~fin & (g != -np.inf)))
        if resampled:
            idx = systematic_resample(w, self.uniform(t))
            x = x[idx]
            lw = np.full(self.N, -np.log(self.N))
        return x, lw, float(ll), (float(ess), resampled, degenerate, m, P)

    def mean(self, belief):
        x, logw = belief
        w = np.exp(logw - logsumexp(logw))
        return w @ x

    def cov(self, belief):
        x, logw = belief
        w = np.exp(logw - logsumexp(logw))
        return weighted_moments(x, w)[1]

    # -- whole logs -------------------------------------------------------------------------------
    def forward_trajectory(self, u, y, keep_particles: bool = False) -> FilterResult:
        """Run the filter over a log (correct with y[t], then predict with u[t]).

        ``extras``: ``ess`` (T,) after weighting, ``n_resampled``, ``degenerate_steps`` (steps where every
        weight was zero and the prior predictive was kept), ``n_degenerate``; with ``keep_particles``
        also ``particles`` (T, N, nx) and ``logw`` (T, N) after each correction (for smoothing)."""
        u, y, T, missing = check_inputs(u, y, self.nu, self.ny)
        nx, N = self.nx, self.N
        x, logw = self.initial_belief()
        xf = np.empty((T, nx)); Pf = np.empty((T, nx, nx))
        xp = np.empty((T + 1, nx)); Pp = np.empty((T + 1, nx, nx))
        ess = np.full(T, np.nan)
        n_res = 0
        degenerate = []
        store_x = np.empty((T, N, nx)) if keep_particles else None
        store_w = np.empty((T, N)) if keep_particles else None
        ll = 0.0
        for t in range(T):
            xp[t], Pp[t] = self._moments(x, logw)
            ut = None if u is None else u[t]
            if not missing[t]:
                x, logw, l_t, (e, r, d, xf[t], Pf[t]) = self._correct(x, logw, y[t], ut, t)
                ll += l_t
                ess[t] = e
                n_res += r
                if d:
                    degenerate.append(t)
            else:
                xf[t], Pf[t] = xp[t], Pp[t]
            if keep_particles:
                store_x[t], store_w[t] = x, logw
            y_next = y[t + 1] if (self.proposal is not None and t + 1 < T and not missing[t + 1]) else None
            x, logw = self.predict(x, logw, u=ut, t=t, y_next=y_next)
        xp[T], Pp[T] = self._moments(x, logw)
        extras = {"ess": ess, "n_resampled": int(n_res), "degenerate_steps": degenerate,
                  "n_degenerate": len(degenerate), "n_particles": N}
        if keep_particles:
            extras["particles"], extras["logw"] = store_x, store_w
        return FilterResult(xf, Pf, xp, Pp, float(ll), int(missing.sum()), extras)

    def _moments(self, x, logw):
        w = np.exp(logw - logsumexp(logw))
        return weighted_moments(x, w)

    # -- smoothing (FFBSi) ------------------------------------------------------------------------
    def smooth(self, u, y, n_trajectories: int = 100) -> ParticleSmoothResult:
        """Forward-filtering backward-simulation (Godsill, Doucet & West 2004): draws ``n_trajectories``
        state trajectories from p(x_{0:T-1} | y) by sampling x_t^j with probability
        proportional to w_t^i p(x_{t+1}^j | x_t^i).  Needs ``transition_logpdf``."""
        if self.transition_logpdf is None:
            raise DataError("smooth needs transition_logpdf(x_next, x, u, t) (log p(x+|x))")
        M = int(n_trajectories)
        if M < 1:
            raise DataError(f"n_trajectories must be >= 1, got {n_trajectories}")
        fr = self.forward_trajectory(u, y, keep_particles=True)
        u_, _, T, _ = check_inputs(u, y, self.nu, self.ny)
        X, LW = fr.extras.pop("particles"), fr.extras.pop("logw")
        trajs = np.empty((M, T, self.nx))
        rng = np.random.default_rng([self.seed, 5])
        w = np.exp(LW[T - 1] - logsumexp(LW[T - 1]))
        j = rng.choice(self.N, size=M, p=w / w.sum())
        trajs[:, T - 1] = X[T - 1, j]
        for t in range(T - 2, -1, -1):
            ut = None if u_ is None else u_[t]
            xt = X[t]
            # log p(x_{t+1}^j | x_t^i) for all (j, i): evaluated as (M*N) pairs
            xn = np.repeat(trajs[:, t + 1], self.N, axis=0)
            xo = np.tile(xt, (M, 1))
            lp = np.asarray(self.transition_logpdf(xn, xo, ut, t), float).reshape(M, self.N)
            a = LW[t][None, :] + lp
            a -= a.max(axis=1, keepdims=True)
            p = np.exp(a)
            p /= p.sum(axis=1, keepdims=True)
            c = np.cumsum(p, axis=1)
            r = rng.random(M)[:, None]
            idx = np.minimum((c < r).sum(axis=1), self.N - 1)
            trajs[:, t] = xt[idx]
        xs = trajs.mean(axis=0)
        d = trajs - xs
        Ps = np.einsum("mti,mtj->tij", d, d) / M
        return ParticleSmoothResult(xs, Ps, trajs, fr.loglik, fr)

    # -- convenience constructor ------------------------------------------------------------------
    @classmethod
    def gaussian(cls, f, h, R1, R2, x0, P0, n_particles: int = 1000, seed: int = 0,
                 resample_threshold: float = 0.5, f_point=None, h_point=None, nu=None):
        """Bootstrap PF for ``x+ = f(x,u,t) + v, v ~ N(0,R1)``, ``y = h(x,u,t) + e, e ~ N(0,R2)``,
        ``x[0] ~ N(x0, P0)``; f and h broadcast over the leading dimensions of x (shape (..., nx)).

        Optional ``f_point(x, u, t, out)`` / ``h_point(x, u, t, out)``: the same model for one particle,
        writing into ``out``, compilable by numba; with them ``forward_trajectory`` runs a fused compiled
        loop (unless ``DRAKE_EST_NO_NUMBA=1``) giving the numpy loop's numbers to 1e-10."""
        return GaussianParticleFilter(f, h, R1, R2, x0, P0, n_particles=n_particles, seed=seed,
                                      resample_threshold=resample_threshold, f_point=f_point,
                                      h_point=h_point, nu=nu)


def _jit_kernels():
    """The compiled helpers of :mod:`pf_kernels`, or None (no numba, or DRAKE_EST_NO_NUMBA=1)."""
    if os.environ.get("DRAKE_EST_NO_NUMBA") == "1":
        return None
    from drake_est.estimation import pf_kernels
    return pf_kernels if pf_kernels.HAVE_NUMBA else None


class GaussianParticleFilter(ParticleFilter):
    """The filter of :meth:`ParticleFilter.gaussian` (additive Gaussian noise); it also knows
    log p(x+|x) (for FFBSi) and runs a vectorised loop with pre-drawn normals."""

    def __init__(self, f, h, R1, R2, x0, P0, n_particles=1000, seed=0, resample_threshold=0.5,
                 f_point=None, h_point=None, nu=None):
        x0 = np.atleast_1d(np.asarray(x0, dtype=float))
        if x0.ndim != 1 or not np.all(np.isfinite(x0)):
            raise DataError(f"x0 must be a finite vector, got shape {x0.shape}")
        nx = x0.shape[0]
        self.L1 = chol_psd(R1, "R1")
        self.L2 = chol_psd(R2, "R2")
        L0 = chol_psd(P0, "P0")
        for name, L in (("R1", self.L1), ("P0", L0)):
            if L.shape[0] != nx:
                raise DataError(f"{name} is {L.shape[0]}x{L.shape[0]}, the state has nx = {nx}")
        self.f, self.h = f, h
        self.x0, self.P0 = x0, L0 @ L0.T
        self.R1, self.R2 = self.L1 @ self.L1.T, self.L2 @ self.L2.T
        ny = self.L2.shape[0]
        self._logdet2 = 2.0 * float(np.sum(np.log(np.diag(self.L2))))
        self._logdet1 = 2.0 * float(np.sum(np.log(np.diag(self.L1))))
        self._g0 = -0.5 * (self._logdet2 + ny * _LOG2PI)
        self._diag2 = np.allclose(self.L2, np.diag(np.diag(self.L2)))
        self._diag1 = bool(np.all(self.L1 == np.diag(np.diag(self.L1))))
        self._inv_sd2 = 1.0 / np.diag(self.L2)
        self.f_point, self.h_point = f_point, h_point
        n = n_particles
        super().__init__(self._transition, self._meas_logpdf,
                         lambda rng, N: x0 + rng.standard_normal((N, nx)) @ L0.T,
                         n, nx=nx, seed=seed, resample_threshold=resample_threshold,
                         transition_logpdf=self._trans_logpdf, nu=nu, ny=ny)

    def _h(self, x, u, t):
        yh = np.asarray(self.h(x, u, t), dtype=float)
        if yh.ndim == 1 and self.ny == 1 and x.ndim == 2:
            yh = yh[:, None]
        if yh.shape != (x.shape[0], self.ny):
            raise DataError(f"h returned shape {yh.shape}, expected ({x.shape[0]}, {self.ny})")
        return yh

    def _transition(self, x, u, t, rng=None):
        xn = np.asarray(self.f(x, u, t), dtype=float)
        if xn.shape != x.shape:
            raise DataError(f"f returned shape {xn.shape}, expected {x.shape} (transition)")
        z = self.normals(t)
        return xn + (z * np.diag(self.L1) if self._diag1 else z @ self.L1.T)

    def _meas_logpdf(self, x, y, u, t):
        e = np.asarray(y, float)[None, :] - self._h(x, u, t)
        if self._diag2:
            r = e * self._inv_sd2
        else:
            r = solve_triangular(self.L2, e.T, lower=True).T
        return self._g0 - 0.5 * np.einsum("ij,ij->i", r, r)

    def _trans_logpdf(self, xn, x, u, t):
        d = xn - np.asarray(self.f(x, u, t), dtype=float)
        r = solve_triangular(self.L1, d.T, lower=True).T
        return -0.5 * (np.einsum("ij,ij->i", r, r) + self._logdet1 + self.nx * _LOG2PI)

    def forward_trajectory(self, u, y, keep_particles: bool = False,
                           covariances: bool = True) -> FilterResult:
        """As :meth:`ParticleFilter.forward_trajectory`, as a vectorised loop over pre-drawn noise chunks
        (same numbers as the step-by-step protocol loop); with ``f_point``/``h_point`` and numba available
        a fused compiled loop (same numbers to 1e-10).  ``covariances=False`` skips the weighted
        covariances (``P_filt``/``P_pred`` are then (T, 0, 0) arrays): means and log-likelihood only."""
        if keep_particles:
            return super().forward_trajectory(u, y, keep_particles=True)
        if (self.f_point is not None and self.h_point is not None
                and os.environ.get("DRAKE_EST_NO_NUMBA") != "1"):
            from drake_est.estimation import pf_kernels
            if pf_kernels.HAVE_NUMBA:
                return pf_kernels.run_fused(self, u, y, covariances=covariances)
        return self._numpy_loop(u, y, covariances)

    def _scaled_noise(self, z):
        """Process noise L1 z of a chunk of standard normals z (K, N, nx)."""
        if self._diag1:
            return z * np.diag(self.L1)
        K, N, nx = z.shape
        return (z.reshape(K * N, nx) @ self.L1.T).reshape(K, N, nx)

    def _numpy_loop(self, u, y, covariances):
        u, y, T, missing = check_inputs(u, y, self.nu, self.ny)
        N, nx = self.N, self.nx
        x, logw = self.initial_belief()
        w = np.exp(logw)
        logw_u, w_u = logw.copy(), w.copy()
        ar = np.arange(N, dtype=float)
        nc = nx if covariances else 0
        xf = np.empty((T, nx)); Pf = np.empty((T, nc, nc))
        xp = np.empty((T + 1, nx)); Pp = np.empty((T + 1, nc, nc))
        ess = np.full(T, np.nan)
        n_res, degenerate, ll = 0, [], 0.0
        f, h, K, L1T, thr = self.f, self.h, self.chunk, self.L1.T, self.resample_threshold * N
        g0, diag2, inv_sd, L2 = self._g0, self._diag2, self._inv_sd2, self.L2
        V = uu = None
        shape_ok = False
        jit = _jit_kernels()
        if jit is not None:
            # compiled internals (weighting, moments, resampling; the user's f and h stay numpy): same numbers
            x = np.ascontiguousarray(x)
            xbuf, wbuf = np.empty_like(x), np.empty(N)
            abuf, kbuf = np.empty(N), np.empty(N, np.int64)
            Pdummy = np.empty((nx, nx))
            need_mean = True          # xp[t] is accumulated by propagate, except at t = 0 / after repairs
        for t in range(T):
            if jit is not None:
                k = t % K
                if k == 0:
                    z, uu = self._draws(t // K)
                if need_mean:
                    jit.moments(x, w, False, xp[t], Pdummy)
                    need_mean = False
                if covariances:
                    jit.wcov(x, w, xp[t], Pp[t])
                ut = None if u is None else u[t]
                status = -1
                if not missing[t]:
                    yh = h(x, ut, t) if shape_ok else self._h(x, ut, t)
                    if diag2:
                        status, l_t, e = jit.weight_step(x, logw, (yh if yh.flags.c_contiguous and yh.dtype == np.float64 else np.ascontiguousarray(yh, dtype=float)), y[t],
                                                         inv_sd, thr, uu[k], covariances, xf[t],
                                                         Pf[t] if covariances else Pdummy, xbuf, wbuf,
                                                         abuf, kbuf)
                    if status >= 0:
                        if status == 1:
                            x, xbuf = xbuf, x
                        w = wbuf
                        ll += l_t + g0
                        ess[t] = e
                        n_res += status
                    else:                       # general path (rare cases, full R2)
                        e_ = yh - y[t]
                        e_ = e_ * inv_sd if diag2 else solve_triangular(L2, e_.T, lower=True).T
                        g = g0 - 0.5 * np.einsum("ij,ij->i", e_, e_)
                        x, logw, l_t, (e, r, d, xf[t], P) = self._weight(x, logw, g, t)
                        x = np.ascontiguousarray(x)
                        if covariances:
                            Pf[t] = P
                        w = np.exp(logw)
                        logw = logw.copy()
                        ll += l_t
                        ess[t] = e
                        n_res += r
                        if d:
                            degenerate.append(t)
                else:
                    xf[t] = xp[t]
                    if covariances:
                        Pf[t] = Pp[t]
                x_old = x
                xn = f(x_old, ut, t)
                if not shape_ok:
                    if getattr(xn, "shape", None) != (N, nx):
                        raise DataError(f"f returned shape {np.shape(xn)}, expected {(N, nx)} (transition)")
                    shape_ok = not missing[t]
                if not (xn.flags.c_contiguous and xn.dtype == np.float64):
                    xn = np.ascontiguousarray(xn, dtype=float)
                # x = f(x) + L1 z in one compiled pass (both buffers are the filter's own arrays)
                if w is not wbuf:
                    wbuf[:] = w
                    w = wbuf
                finite = jit.propagate(xn, z[k], self.L1, self._diag1, xbuf, w, xp[t + 1])
                x = xbuf
                xbuf = x_old
                if not finite:
                    need_mean = True
                    bad = ~np.isfinite(x).all(axis=1)
                    if bad.any():
                        x, logw = self._replace_bad(x, np.where(bad, -np.inf, logw), t)
                        x = np.ascontiguousarray(x)
                        w = np.exp(logw)
                continue
            k = t % K
            if k == 0:
                z, uu = self._draws(t // K)
                V = self._scaled_noise(z)
            if covariances:
                xp[t], Pp[t] = weighted_moments(x, w)
            else:
                xp[t] = w @ x
            ut = None if u is None else u[t]
            if not missing[t]:
                # log N(y; h(x), R2) up to the constant g0 (added to the log-likelihood below)
                if shape_ok:
                    e = h(x, ut, t) - y[t]
                else:
                    e = self._h(x, ut, t) - y[t]
                if diag2:
                    e *= inv_sd
                else:
                    e = solve_triangular(L2, e.T, lower=True).T
                a = logw - 0.5 * np.einsum("ij,ij->i", e, e)
                amax = a.max()
                if not np.isfinite(amax):
                    # rare cases (zero / NaN likelihoods) go through the shared weighting code
                    x, logw, l_t, (e, r, d, xf[t], P) = self._weight(x, logw, a - logw + g0, t)
                    if covariances:
                        Pf[t] = P
                    w = np.exp(logw)
                    if d:
                        degenerate.append(t)
                else:
                    ea = np.exp(a - amax)
                    sa = ea.sum()
                    l_t = amax + np.log(sa)
                    w = ea / sa
                    e = 1.0 / np.dot(w, w)
                    if covariances:
                        xf[t], Pf[t] = weighted_moments(x, w)
                    else:
                        xf[t] = w @ x
                    r = e < thr
                    if r:
                        idx = np.searchsorted(np.cumsum(w), (uu[k] + ar) / N, side="left")
                        np.minimum(idx, N - 1, out=idx)
                        x = x[idx]
                        logw, w = logw_u, w_u
                    else:
                        logw = a - l_t
                    l_t += g0
                ll += l_t
                ess[t] = e
                n_res += r
            else:
                xf[t] = xp[t]
                if covariances:
                    Pf[t] = Pp[t]
            xn = f(x, ut, t)
            if not shape_ok:
                if getattr(xn, "shape", None) != (N, nx):
                    raise DataError(f"f returned shape {np.shape(xn)}, expected {(N, nx)} (transition)")
                shape_ok = not missing[t]        # h has been checked once as well
            x = xn + V[k]
            if not np.isfinite(np.add.reduce(x, axis=None)):
                bad = ~np.isfinite(x).all(axis=1)
                if bad.any():
                    x, logw = self._replace_bad(x, np.where(bad, -np.inf, logw), t)
                    w = np.exp(logw)
        if covariances:
            xp[T], Pp[T] = weighted_moments(x, w)
        else:
            xp[T] = w @ x
        extras = {"ess": ess, "n_resampled": int(n_res), "degenerate_steps": degenerate,
                  "n_degenerate": len(degenerate), "n_particles": N}
        return FilterResult(xf, Pf, xp, Pp, float(ll), int(missing.sum()), extras)
