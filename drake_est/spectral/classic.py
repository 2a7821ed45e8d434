"""Classic spectral estimators for comparison (thesis Fig. 10.3, Fig. 10.5), through scipy.

The periodogram and Welch's method need equidistant samples: the data are sorted by
their location ``x`` and linearly interpolated onto a uniform grid (what the thesis
does for Figs. 10.3 and 10.5).  The Lomb-Scargle periodogram works on the raw samples.
All frequencies are in cycles per unit of ``x``.
"""
from __future__ import annotations

import numpy as np
import scipy.signal

from drake_est.errors import DataError
from drake_est.spectral.lssa import _clean_1d


def resample_uniform(x, y, n: int | None = None):
    """Sort by ``x``, average duplicates, and interpolate linearly onto ``n`` (default: len(x))
    equidistant points.  Returns ``(x_grid, y_grid, fs)`` with ``fs`` samples per unit of x."""
    x = _clean_1d(x, "sample locations")
    y = _clean_1d(y, "signal")
    if x.size != y.size:
        raise DataError(f"signal has {y.size} samples, sample locations {x.size}")
    xu, inv = np.unique(x, return_inverse=True)
    if xu.size < 4:
        raise DataError("need at least 4 distinct sample locations to resample")
    yu = np.bincount(inv, weights=y) / np.bincount(inv)
    n = int(n or x.size)
    xg = np.linspace(xu[0], xu[-1], n)
    yg = np.interp(xg, xu, yu)
    fs = (n - 1) / (xu[-1] - xu[0])
    return xg, yg, fs


def periodogram(x, y, n: int | None = None, detrend="constant"):
    """Periodogram of the sorted, interpolated data: ``(freqs, power spectral density)``."""
    _, yg, fs = resample_uniform(x, y, n)
    return scipy.signal.periodogram(yg, fs=fs, detrend=detrend)


def welch(x, y, n: int | None = None, nperseg: int | None = None, detrend="constant"):
    """Welch's averaged periodogram of the sorted, interpolated data (Hann windows,
    ``nperseg`` default ``len/8``): ``(freqs, power spectral density)``."""
    _, yg, fs = resample_uniform(x, y, n)
    if nperseg is None:
        nperseg = max(16, yg.size // 8)
    return scipy.signal.welch(yg, fs=fs, nperseg=min(nperseg, yg.size), detrend=detrend)


def lomb_scargle(x, y, freqs):
    """Lomb-Scargle periodogram on the raw samples at ``freqs`` (cycles per unit x), with a
    floating mean; returns the power (scipy's 'power' normalization)."""
    x = _clean_1d(x, "sample locations")
    y = _clean_1d(y, "signal")
    freqs = np.asarray(freqs, dtype=float)
    if np.any(freqs <= 0):
        raise DataError("Lomb-Scargle needs strictly positive frequencies")
    return scipy.signal.lombscargle(x, y, 2 * np.pi * freqs, floating_mean=True)


def top_peaks(freqs, power, n: int = 3, exclude_zero: bool = True) -> np.ndarray:
    """Frequencies of the ``n`` largest local maxima of a spectrum (descending power)."""
    freqs = np.asarray(freqs)
    power = np.asarray(power)
    idx, _ = scipy.signal.find_peaks(np.r_[-np.inf, power, -np.inf])
    idx = idx - 1
    if exclude_zero:
        idx = idx[freqs[idx] > 0]
    order = idx[np.argsort(-power[idx])]
    return freqs[order[:n]]


def isolates(found, truth, tol: float) -> bool:
    """True when every true frequency is within ``tol`` of one of the ``found`` ones."""
    found = np.atleast_1d(found)
    return bool(all(np.any(np.abs(found - t) <= tol) for t in np.atleast_1d(truth)))
