"""Least-squares spectral analysis on arbitrary sample locations (thesis Eqs. (10.1), (10.5)).

Frequencies in this package are **cycles per unit of the sampling location x**
(cycles per second for time, cycles per radian for an angle); the angular
frequency of the thesis is ``omega = 2 pi f``.  A component is written
``a cos(omega x) + b sin(omega x) = A cos(omega x - phi)`` with the complex
coefficient ``k = a + i b``, ``A = |k|`` and ``phi = arg k`` (Lemma 3), which is the
real part of ``k exp(-i omega x)`` as in Eq. (10.4).

Functions here:

* :func:`sampling_density_limit` -- the highest frequency the sample locations can
  resolve: ``1 / (2 dx)`` with ``dx`` the quantization step of the locations (the
  spacing of a regular grid, the encoder resolution of a position signal).
  Irregular, unquantized locations resolve far beyond the mean-spacing Nyquist rate.
* :func:`frequency_grid` -- an automatic grid up to that limit; :func:`check_frequency_grid`
  raises :class:`DataError` for a grid above it.
* :func:`ls_scan` -- the least-squares periodogram: for every frequency of a grid
  separately, the variance of ``y`` explained by ``[phi(v) cos(omega x), phi(v) sin(omega x)]``
  (generalized Lomb-Scargle when ``phi == 1``), computed for the whole grid with
  matrix products (cost O(N O J^2)).
* :func:`lssa` -- the joint least-squares fit (10.5) of all grid frequencies at once,
  i.e. :class:`drake_est.spectral.lpv.LPVSpectrum` with the constant basis.
"""
from __future__ import annotations

import numpy as np

from drake_est.errors import DataError

MAX_AUTO_GRID = 200_000


def _clean_1d(a, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.ndim != 1:
        a = a.ravel() if a.ndim == 2 and 1 in a.shape else a
    if a.ndim != 1:
        raise DataError(f"{name} must be one-dimensional, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise DataError(f"{name} contains {int(np.sum(~np.isfinite(a)))} NaN/inf values")
    return a


def quantization_step(x, quantile: float = 0.01) -> float:
    """Smallest spacing between distinct sample locations that is representative of the data:
    the ``quantile`` of the positive gaps of the sorted unique locations (robust to a few
    duplicates).  For a regular grid it is the grid step; for an encoder, the count size."""
    x = np.unique(np.asarray(x, dtype=float))
    if x.size < 2:
        raise DataError("sample locations: need at least two distinct values")
    gaps = np.diff(x)
    gaps = gaps[gaps > 1e-12 * max(1.0, float(np.max(np.abs(x))))]
    if gaps.size == 0:
        raise DataError("sample locations: all values are equal")
    return float(np.quantile(gaps, quantile))


def sampling_density_limit(x, quantile: float = 0.01) -> float:
    """Highest resolvable frequency ``1 / (2 dx)`` in cycles per unit of ``x`` (see module doc)."""
    return 0.5 / quantization_step(x, quantile)


def frequency_resolution(x) -> float:
    """Rayleigh resolution ``1 / (max x - min x)`` in cycles per unit of ``x``."""
    x = np.asarray(x, dtype=float)
    span = float(np.max(x) - np.min(x))
    if span <= 0:
        raise DataError("sample locations span zero length; no frequency can be resolved")
    return 1.0 / span


def check_frequency_grid(x, freqs, quantile: float = 0.01) -> np.ndarray:
    """Validate a user grid (cycles per unit x): finite, non-negative, below the sampling-density
    limit of ``x``.  Returns the grid as a float array; raises :class:`DataError` otherwise."""
    freqs = np.atleast_1d(np.asarray(freqs, dtype=float)).ravel()
    if freqs.size == 0:
        raise DataError("frequency grid is empty")
    if not np.all(np.isfinite(freqs)) or np.any(freqs < 0):
        raise DataError("frequency grid must hold finite, non-negative frequencies")
    lim = sampling_density_limit(x, quantile)
    if freqs.max() > lim * (1 + 1e-9):
        raise DataError(
            f"frequency grid reaches {freqs.max():.6g} cycles per unit, above the sampling-density limit "
            f"{lim:.6g} = 1/(2 dx) of the sample locations (dx = {0.5 / lim:.3g}); higher frequencies alias")
    return freqs


def frequency_grid(x, f_max: float | None = None, f_min: float | None = None, oversample: float = 4.0,
                   max_points: int = MAX_AUTO_GRID) -> np.ndarray:
    """Uniform grid from ``f_min`` (default: the resolution ``1/span``) to ``f_max`` (default: the
    sampling-density limit), spaced ``1 / (oversample * span)``.  Raises :class:`DataError` when the
    grid would exceed ``max_points`` (pass a smaller ``f_max``)."""
    res = frequency_resolution(x)
    lim = sampling_density_limit(x)
    if f_max is None:
        f_max = lim
    elif f_max > lim * (1 + 1e-9):
        raise DataError(f"f_max = {f_max:.6g} is above the sampling-density limit {lim:.6g} of the data")
    if f_min is None:
        f_min = res
    df = res / float(oversample)
    n = int(np.floor((f_max - f_min) / df)) + 1
    if n < 1:
        raise DataError(f"empty frequency grid: f_min = {f_min:.6g} > f_max = {f_max:.6g}")
    if n > max_points:
        raise DataError(f"automatic frequency grid would have {n} points (up to {f_max:.6g} cycles per unit at "
                        f"spacing {df:.3g}); pass a smaller f_max or oversample")
    return f_min + df * np.arange(n)


def _pair_products(Phi: np.ndarray):
    J = Phi.shape[1]
    iu = np.triu_indices(J)
    return Phi[:, iu[0]] * Phi[:, iu[1]], iu


def ls_scan(x, y, freqs, Phi=None, chunk: int | None = None, jitter: float = 1e-10) -> np.ndarray:
    """Explained sum of squares of ``y`` by each grid frequency on its own.

    For every ``f`` in ``freqs`` (cycles per unit x) the least-squares fit of ``y`` on the
    2J columns ``[Phi cos(2 pi f x), Phi sin(2 pi f x)]`` is formed from matrix products
    (no loop over samples) and its explained sum of squares ``b^T G^-1 b`` returned.
    With ``Phi = None`` (one constant column) this is the generalized Lomb-Scargle periodogram
    without offset.  Divide by ``sum(y**2)`` for the explained fraction."""
    x = _clean_1d(x, "sample locations")
    y = _clean_1d(y, "signal")
    if y.size != x.size:
        raise DataError(f"signal has {y.size} samples, sample locations {x.size}")
    freqs = np.atleast_1d(np.asarray(freqs, dtype=float))
    N = x.size
    if Phi is None:
        Phi = np.ones((N, 1))
    Phi = np.asarray(Phi, dtype=float)
    J = Phi.shape[1]
    PP, iu = _pair_products(Phi)
    m0 = PP.sum(axis=0)
    Py = Phi * y[:, None]
    if chunk is None:
        chunk = max(8, int(4e6 // max(N, 1)))
    out = np.empty(freqs.size)
    w_all = 2 * np.pi * freqs
    for s in range(0, freqs.size, chunk):
        w = w_all[s:s + chunk]
        arg = np.outer(x, w)
        C = np.cos(arg)
        S = np.sin(arg)
        bc = Py.T @ C                      # (J, O)
        bs = Py.T @ S
        C2 = C * C - S * S                 # cos(2 w x)
        S2 = 2.0 * C * S                   # sin(2 w x)
        mc = PP.T @ C2                     # (J(J+1)/2, O)
        ms = PP.T @ S2
        O = w.size
        G = np.empty((O, 2 * J, 2 * J))
        half0 = np.zeros((J, J))
        half0[iu] = m0
        M0 = half0 + np.triu(half0, 1).T
        Mc = np.zeros((O, J, J))
        Ms = np.zeros((O, J, J))
        Mc[:, iu[0], iu[1]] = mc.T
        Mc[:, iu[1], iu[0]] = mc.T
        Ms[:, iu[0], iu[1]] = ms.T
        Ms[:, iu[1], iu[0]] = ms.T
        G[:, :J, :J] = 0.5 * (M0[None] + Mc)
        G[:, J:, J:] = 0.5 * (M0[None] - Mc)
        G[:, :J, J:] = 0.5 * Ms
        G[:, J:, :J] = 0.5 * Ms
        b = np.concatenate([bc.T, bs.T], axis=1)  # (O, 2J)
        scale = np.trace(G, axis1=1, axis2=2) / (2 * J)
        G = G + (jitter * np.maximum(scale, 1e-300))[:, None, None] * np.eye(2 * J)[None]
        sol = np.linalg.solve(G, b[..., None])[..., 0]
        out[s:s + chunk] = np.einsum("oi,oi->o", b, sol)
    return out


def lssa(x, y, freqs, lam: float = 0.0):
    """Joint least-squares spectrum (10.5) of ``y`` sampled at arbitrary ``x`` on the grid ``freqs``
    (cycles per unit x).  Returns a fitted :class:`~drake_est.spectral.lpv.LPVSpectrum` with one
    constant basis function; its ``.coef[:, 0]`` are the complex Fourier coefficients ``k``."""
    from drake_est.spectral.lpv import LPVSpectrum

    return LPVSpectrum(freqs, n_basis=1, lam=lam).fit(x, y)
