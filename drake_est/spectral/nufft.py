"""Non-uniform FFT engine for the least-squares and LPV periodograms (thesis Eqs. (10.1), (10.4)-(10.5)).

Every term of the per-frequency normal equations of the least-squares periodogram with the
2J columns ``[phi(v) cos(w x), phi(v) sin(w x)]`` (``w = 2 pi f``; J = 1, ``phi = 1`` is the
generalized Lomb-Scargle periodogram) is a trigonometric sum over the samples:

* ``b_j(f)   = sum_n phi_j(v_n) y_n exp(i w x_n)``           (right-hand side, cos part = Re, sin part = Im),
* ``M_ij(f)  = sum_n phi_i(v_n) phi_j(v_n) exp(2 i w x_n)``  (``cos^2 = (1 + cos 2wx)/2``, ...),
* ``M0_ij    = sum_n phi_i(v_n) phi_j(v_n)``, and for the floating offset ``sum_n phi_j exp(i w x_n)``.

:func:`trig_sums` evaluates ``sum_n c_n exp(i h 2 pi f x_n)`` for all ``f`` of a grid at once with
FINUFFT: a *type-1* NUFFT (``O(N log(1/eps) + F log F)``) when the grid is uniform
(``f_k = f_0 + k df``: the offset ``f_mid`` is moved into the weights, ``c_n exp(i 2 pi h f_mid x_n)``,
and the points are ``t_n = 2 pi h df x_n``), a *type-3* NUFFT for an arbitrary grid.  The
tolerance defaults to ``1e-13`` so that the periodogram equals the direct sums to a relative 1e-9
(tested).  :func:`trig_sums_direct` is the plain ``O(N F)`` reference.

:func:`gram_blocks` and :func:`explained_ss` turn the sums into the batched 2J x 2J normal
equations and their explained sum of squares ``b^T G^-1 b`` (with the same relative diagonal
jitter as the direct path, so frequencies near 0 or a regular-sampling Nyquist rate, whose sine
column vanishes, are handled identically).
"""
from __future__ import annotations

import os

import numpy as np

from drake_est.errors import DataError

DEFAULT_EPS = 1e-13
UNIFORM_RTOL = 1e-13


def default_threads() -> int:
    """FINUFFT threads: ``DRAKE_EST_NUFFT_THREADS`` (default 1, the machines are shared)."""
    try:
        return max(1, int(os.environ.get("DRAKE_EST_NUFFT_THREADS", "1")))
    except ValueError:
        raise DataError("DRAKE_EST_NUFFT_THREADS must be an integer") from None


def uniform_grid_params(freqs) -> tuple[float, float] | None:
    """``(f0, df)`` when ``freqs`` is ``f0 + df * arange(F)`` to a relative ``1e-13`` (F >= 2, df > 0),
    else ``None``."""
    f = np.asarray(freqs, dtype=float)
    if f.ndim != 1 or f.size < 2:
        return None
    f0 = float(f[0])
    df = float(f[-1] - f[0]) / (f.size - 1)
    if not df > 0:
        return None
    err = np.max(np.abs(f - (f0 + df * np.arange(f.size))))
    return (f0, df) if err <= UNIFORM_RTOL * max(float(np.max(np.abs(f))), df) else None


def trig_sums_direct(x, c, freqs, harmonic: float = 1.0, chunk_elems: int = 4_000_000) -> np.ndarray:
    """Reference ``S[k, o] = sum_n c[k, n] exp(i 2 pi harmonic f_o x_n)`` by explicit sums (O(N F))."""
    x = np.asarray(x, dtype=float)
    c = np.atleast_2d(np.asarray(c))
    freqs = np.asarray(freqs, dtype=float)
    out = np.empty((c.shape[0], freqs.size), dtype=complex)
    step = max(1, int(chunk_elems // max(x.size, 1)))
    for s in range(0, freqs.size, step):
        arg = np.outer(x, 2 * np.pi * harmonic * freqs[s:s + step])
        E = np.cos(arg) + 1j * np.sin(arg)
        out[:, s:s + step] = c @ E
    return out


class TrigSumPlan:
    """A prepared NUFFT for ``sum_n c_n exp(i 2 pi harmonic f_o x_n)`` over fixed locations ``x`` and grid
    ``freqs``: the points, the shift phase and the FINUFFT plan are made once and reused for every weight
    vector (the LPV periodogram needs J + J(J+1)/2 of them).  See :func:`trig_sums`."""

    def __init__(self, x, freqs, harmonic: float = 1.0, eps: float = DEFAULT_EPS, nthreads: int | None = None,
                 center: bool = True, base_phase=None):
        import finufft

        x = np.asarray(x, dtype=float)
        freqs = np.asarray(freqs, dtype=float).ravel()
        self.N, self.F = x.size, freqs.size
        nthreads = default_threads() if nthreads is None else int(nthreads)
        self.xc = 0.5 * (float(np.min(x)) + float(np.max(x))) if center and x.size else 0.0
        xs = x - self.xc if self.xc != 0.0 else x
        self.g = harmonic * freqs
        uni = uniform_grid_params(self.g)
        if uni is not None:
            g0, dg = uni
            g_mid = g0 + (self.F // 2) * dg            # modes k = -F//2 .. (F-1)//2 around g_mid
            t = (2 * np.pi * dg) * xs
            if np.max(np.abs(t)) >= np.pi:             # fold onto [-pi, pi): exp(i k t) is 2 pi periodic
                t = np.mod(t + np.pi, 2 * np.pi) - np.pi
            if base_phase is not None:                 # the harmonic-1 phase of the same grid: h = 2 is its square
                self.phase = base_phase * base_phase
            else:
                a = (2 * np.pi * g_mid) * xs
                self.phase = np.cos(a) + 1j * np.sin(a)
            self.plan = finufft.Plan(1, (self.F,), eps=eps, isign=1, nthreads=nthreads)
            self.plan.setpts(t)
        else:
            self.phase = None
            self.plan = finufft.Plan(3, 1, eps=eps, isign=1, nthreads=nthreads)
            self.plan.setpts(xs, s=2 * np.pi * self.g)
        a = (2 * np.pi * self.xc) * self.g
        self.post = None if self.xc == 0.0 else np.cos(a) + 1j * np.sin(a)

    def __call__(self, c) -> np.ndarray:
        """Sums (K, F) for weights ``c`` (K, N) or (N,)."""
        c = np.atleast_2d(np.asarray(c))
        if c.shape[1] != self.N:
            raise DataError(f"trig_sums: {c.shape[1]} weights per vector but {self.N} sample locations")
        out = np.empty((c.shape[0], self.F), dtype=complex)
        for k in range(c.shape[0]):
            w = c[k] * self.phase if self.phase is not None else c[k].astype(complex)
            out[k] = self.plan.execute(np.ascontiguousarray(w, dtype=complex))
        if self.post is not None:
            out *= self.post[None, :]
        return out


def trig_sums(x, c, freqs, harmonic: float = 1.0, eps: float = DEFAULT_EPS, nthreads: int | None = None,
              center: bool = True) -> np.ndarray:
    """``S[k, o] = sum_n c[k, n] exp(i 2 pi harmonic f_o x_n)`` for every weight vector ``c[k]`` (K, N)
    and frequency ``f_o`` (cycles per unit of x) by NUFFT.

    Uniform grids (:func:`uniform_grid_params`) use a type-1 transform with the shift described in
    the module doc; other grids a type-3 transform.  ``center``: the sums are computed about the
    midpoint ``x_c`` of the data (better conditioned) and multiplied by ``exp(i 2 pi h f x_c)``."""
    x = np.asarray(x, dtype=float)
    c = np.atleast_2d(np.asarray(c))
    if x.size != c.shape[1]:
        raise DataError(f"trig_sums: {c.shape[1]} weights per vector but {x.size} sample locations")
    return TrigSumPlan(x, freqs, harmonic, eps=eps, nthreads=nthreads, center=center)(c)


# --------------------------------------------------------------------------- normal equations

def sym_blocks(vals: np.ndarray, iu, J: int) -> np.ndarray:
    """(..., P) upper-triangle values (order ``iu``) -> symmetric (..., J, J)."""
    M = np.zeros(vals.shape[:-1] + (J, J), dtype=vals.dtype)
    M[..., iu[0], iu[1]] = vals
    M[..., iu[1], iu[0]] = vals
    return M


def gram_blocks(M0: np.ndarray, Mc: np.ndarray, Ms: np.ndarray) -> np.ndarray:
    """Per-frequency Gram matrices (O, 2J, 2J) of ``[phi cos(wx), phi sin(wx)]`` from
    ``M0 = sum phi phi^T``, ``Mc = sum phi phi^T cos(2wx)``, ``Ms = sum phi phi^T sin(2wx)``
    (``cos^2 = (1 + cos 2wx)/2``, ``sin^2 = (1 - cos 2wx)/2``, ``cos sin = sin(2wx)/2``)."""
    O, J = Mc.shape[0], Mc.shape[1]
    G = np.empty((O, 2 * J, 2 * J))
    G[:, :J, :J] = 0.5 * (M0[None] + Mc)
    G[:, J:, J:] = 0.5 * (M0[None] - Mc)
    G[:, :J, J:] = 0.5 * Ms
    G[:, J:, :J] = np.transpose(0.5 * Ms, (0, 2, 1))
    return G


def gram_factor(G: np.ndarray, jitter: float = 1e-10):
    """Lower Cholesky factors (O, d, d) of the jittered Gram blocks that :func:`explained_ss` solves (the same
    ``jitter * trace(G)/d`` ridge), for :func:`explained_ss_factored`; None when some block is not positive
    definite in floating point (then :func:`explained_ss` solves each call) or for d = 2 (closed form)."""
    d = G.shape[-1]
    if d == 2:
        return None
    scale = np.trace(G, axis1=1, axis2=2) / d
    Gj = G + (jitter * np.maximum(scale, 1e-300))[:, None, None] * np.eye(d)[None]
    try:
        L = np.linalg.cholesky(Gj)
    except np.linalg.LinAlgError:
        return None
    return L if np.all(np.isfinite(L)) else None


def explained_ss_factored(L: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``b^T G^-1 b = ||L^-1 b||^2`` per frequency from the factors of :func:`gram_factor`: one forward
    substitution, vectorized over the frequencies (a periodogram scans residual after residual with the
    same Gram blocks, :class:`~drake_est.spectral.lssa.LSScanPlan`)."""
    d = L.shape[-1]
    z = np.empty(b.shape)
    for i in range(d):
        z[:, i] = (b[:, i] - np.einsum("oj,oj->o", L[:, i, :i], z[:, :i])) / L[:, i, i]
    return np.einsum("oi,oi->o", z, z)


def explained_ss(G: np.ndarray, b: np.ndarray, jitter: float = 1e-10) -> np.ndarray:
    """Batched explained sum of squares ``b^T G^-1 b`` (least-squares fit per frequency, Eq. (10.5)
    for one frequency), with a ``jitter * trace(G)/dim`` diagonal ridge for numerical safety."""
    d = G.shape[-1]
    if d == 2:                # closed form (the plain periodogram): much faster than batched LAPACK
        r = jitter * np.maximum(0.5 * (G[:, 0, 0] + G[:, 1, 1]), 1e-300)
        g11, g22, g12 = G[:, 0, 0] + r, G[:, 1, 1] + r, G[:, 0, 1]
        b1, b2 = b[:, 0], b[:, 1]
        return (g22 * b1 * b1 - 2.0 * g12 * b1 * b2 + g11 * b2 * b2) / (g11 * g22 - g12 * g12)
    scale = np.trace(G, axis1=1, axis2=2) / d
    Gj = G + (jitter * np.maximum(scale, 1e-300))[:, None, None] * np.eye(d)[None]
    sol = np.linalg.solve(Gj, b[..., None])[..., 0]
    return np.einsum("oi,oi->o", b, sol)
