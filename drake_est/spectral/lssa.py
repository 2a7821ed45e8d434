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
  (generalized Lomb-Scargle when ``phi == 1``; ``fit_mean=True`` adds a floating offset), every
  sum of its normal equations by a non-uniform FFT (:mod:`drake_est.spectral.nufft`,
  O(N log(1/eps) + O log O)) or, for tiny problems and as the reference, explicitly (O(N O J^2)).
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


def _offset_gram(G, b, N: int, sum_y: float, T: np.ndarray):
    """Extend per-frequency normal equations (O, 2J, 2J), (O, 2J) by a leading constant column
    (the floating offset): ``G[0, 0] = N``, ``G[0, 1:] = [Re T, Im T]`` with ``T_j = sum phi_j exp(i w x)``."""
    O, d = b.shape
    Ge = np.empty((O, d + 1, d + 1))
    Ge[:, 1:, 1:] = G
    Ge[:, 0, 0] = N
    cross = np.concatenate([T.real, T.imag], axis=1)
    Ge[:, 0, 1:] = cross
    Ge[:, 1:, 0] = cross
    be = np.empty((O, d + 1))
    be[:, 0] = sum_y
    be[:, 1:] = b
    return Ge, be


def _gram_system(xs, freqs, Phi, fit_mean: bool, sums, one_at_a_time: bool = False, show=None, diag=None):
    """The signal-independent part of the LPV periodogram's per-frequency normal equations: the Gram matrices
    G (O, 2J, 2J) of ``[phi cos(wx), phi sin(wx)]`` from trigonometric sums ``sums(x, weights (K, N), freqs,
    harmonic) -> (K, O)`` (:func:`~drake_est.spectral.nufft.trig_sums` or its direct reference); ``xs`` centred
    locations.  Returns ``(G, T)`` with ``T`` (O, J) the sums ``sum phi_j exp(iwx)`` of the floating offset
    (None without ``fit_mean``).  ``one_at_a_time`` builds and transforms one weight vector at a time (memory
    O(N) for long logs); ``show(total)`` wraps the loop in a progress bar; ``diag`` receives what
    :func:`_ill_conditioned` needs."""
    from drake_est.spectral.nufft import gram_blocks, sym_blocks

    N, J = Phi.shape
    iu = np.triu_indices(J)
    jobs = [(2.0, ("m", c)) for c in range(iu[0].size)]
    if fit_mean:
        jobs = [(1.0, ("t", j)) for j in range(J)] + jobs

    def weight(key):
        kind, k = key
        if kind == "t":
            return Phi[:, k]
        return Phi[:, iu[0][k]] * Phi[:, iu[1][k]]

    O = freqs.size
    S = {}
    m0 = np.zeros(iu[0].size)
    if one_at_a_time:
        it = range(len(jobs)) if show is None else show(len(jobs))
        for q in it:
            h, key = jobs[q]
            w = weight(key)
            if key[0] == "m":
                m0[key[1]] = w.sum()
                if not np.any(w):          # disjoint supports (sign split): no sum needed
                    S[key] = np.zeros(O, dtype=complex)
                    continue
            S[key] = sums(xs, w[None, :], freqs, h)[0]
    else:
        for h in (1.0, 2.0):
            keys = [k for hh, k in jobs if hh == h]
            if not keys:
                continue
            W = np.array([weight(k) for k in keys])
            R = sums(xs, W, freqs, h)
            for k, row, w in zip(keys, R, W):
                S[k] = row
                if k[0] == "m":
                    m0[k[1]] = w.sum()
    S2 = np.array([S[("m", c)] for c in range(iu[0].size)])           # (P, O)
    T = np.array([S[("t", j)] for j in range(J)]).T if fit_mean else None
    if diag is not None:               # what _ill_conditioned needs
        dg = np.flatnonzero(iu[0] == iu[1])
        diag["S2d"], diag["m0d"] = S2[dg], m0[dg]
        if fit_mean:
            diag["T"] = T.T
            diag["tsum"] = Phi.sum(axis=0)
    M0 = sym_blocks(m0, iu, J)
    G = gram_blocks(M0, sym_blocks(S2.real.T, iu, J), sym_blocks(S2.imag.T, iu, J))
    return G, T


def _rhs_system(xs, y, freqs, Phi, sums) -> np.ndarray:
    """The signal's part of the normal equations: b (O, 2J) = [Re, Im] of ``sum phi_j y exp(iwx)``."""
    bj = sums(xs, (Phi * y[:, None]).T, freqs, 1.0).T
    return np.concatenate([bj.real, bj.imag], axis=1)


class LSScanPlan:
    """The least-squares periodogram (:func:`ls_scan`) of many signals over the same sample locations ``x``,
    frequency grid and basis ``Phi``: the Gram matrices of the per-frequency normal equations, which do not
    depend on the signal, are computed once (J(J+1)/2 transforms, and the ill-conditioned frequencies found,
    see :func:`ls_scan`); each :meth:`ess` then costs the J transforms of the signal's sums.  The greedy
    component search (:func:`~drake_est.spectral.detect.find_periodic_components`) and the diagnosis' rounds
    scan residual after residual at the same positions.  Arguments as :func:`ls_scan`."""

    def __init__(self, x, freqs, Phi=None, chunk: int | None = None, jitter: float = 1e-10, fit_mean: bool = False,
                 method: str = "auto", eps: float | None = None, nthreads: int | None = None,
                 exact_cond: float | None = None):
        from drake_est.spectral.nufft import DEFAULT_EPS, TrigSumPlan, trig_sums_direct

        x = _clean_1d(x, "sample locations")
        freqs = np.atleast_1d(np.asarray(freqs, dtype=float)).ravel()
        if not np.all(np.isfinite(freqs)):
            raise DataError("frequency grid contains NaN/inf")
        if method not in ("auto", "nufft", "direct"):
            raise DataError(f"unknown ls_scan method '{method}'; use auto, nufft or direct")
        N = x.size
        if Phi is None:
            Phi = np.ones((N, 1))
        Phi = np.asarray(Phi, dtype=float)
        if Phi.ndim != 2 or Phi.shape[0] != N:
            raise DataError(f"basis Phi must have shape ({N}, J), got {Phi.shape}")
        if not np.all(np.isfinite(Phi)):
            raise DataError("basis Phi contains NaN/inf")
        eps = DEFAULT_EPS if eps is None else float(eps)
        if method == "auto":
            method = "direct" if (N * freqs.size <= 2e6 or freqs.size < 8 or not _have_finufft()) else "nufft"
        self.x, self.freqs, self.Phi = x, freqs, Phi
        self.jitter, self.fit_mean, self.method = float(jitter), bool(fit_mean), method
        self.xs = x - 0.5 * (float(np.min(x)) + float(np.max(x)))     # the periodogram is shift invariant
        chunk_elems = int(4e6 if chunk is None else float(chunk) * N)
        self._direct = lambda xx, c, f, h: trig_sums_direct(xx, c, f, h, chunk_elems=chunk_elems)  # noqa: E731
        if method == "direct":
            self._sums = self._direct
            self.G, self.T = _gram_system(self.xs, freqs, Phi, self.fit_mean, self._direct)
            self.bad = np.zeros(0, dtype=int)
            self._factor()
            return
        plans = {}

        def fast(xx, c, f, h):                    # one prepared NUFFT per harmonic, reused for every weight
            if h not in plans:
                base = plans[1.0].phase if (h == 2.0 and 1.0 in plans) else None
                plans[h] = TrigSumPlan(xx, f, h, eps=eps, nthreads=nthreads, center=False, base_phase=base)
            return plans[h](c)

        self._sums = fast
        # the harmonic-1 plan first: the harmonic-2 phase is its square
        plans[1.0] = TrigSumPlan(self.xs, freqs, 1.0, eps=eps, nthreads=nthreads, center=False)
        diag = {}
        self.G, self.T = _gram_system(self.xs, freqs, Phi, self.fit_mean, fast, one_at_a_time=True,
                                      show=_progress_if_slow(N, freqs.size), diag=diag)
        self.bad = _ill_conditioned(diag["S2d"], diag["m0d"], diag.get("T"), diag.get("tsum"),
                                    1e-10 / eps if exact_cond is None else float(exact_cond))
        if self.bad.size:
            Gd, Td = _gram_system(self.xs, freqs[self.bad], Phi, self.fit_mean, self._direct)
            self.G[self.bad] = Gd
            if self.fit_mean:
                self.T[self.bad] = Td
        self._factor()

    def _factor(self):
        """Factor the signal-independent Gram blocks once (without a floating offset, whose blocks depend on the
        signal's sum), so that each :meth:`ess` is a forward substitution instead of O dense solves."""
        from drake_est.spectral.nufft import gram_factor

        self.L = None if self.fit_mean else gram_factor(self.G, self.jitter)

    def ess(self, y) -> np.ndarray:
        """Explained sum of squares of ``y`` by each grid frequency (see :func:`ls_scan`)."""
        from drake_est.spectral.nufft import explained_ss, explained_ss_factored

        y = _clean_1d(y, "signal")
        if y.size != self.x.size:
            raise DataError(f"signal has {y.size} samples, sample locations {self.x.size}")
        if self.fit_mean:
            y = y - np.mean(y)       # with the offset in every model, centring changes no residual
        b = _rhs_system(self.xs, y, self.freqs, self.Phi, self._sums)
        if self.bad.size:
            b[self.bad] = _rhs_system(self.xs, y, self.freqs[self.bad], self.Phi, self._direct)
        if self.L is not None:
            return explained_ss_factored(self.L, b)
        G = self.G
        if self.fit_mean:
            G, b = _offset_gram(G, b, self.x.size, float(np.sum(y)), self.T)
        return explained_ss(G, b, self.jitter)


def ls_scan(x, y, freqs, Phi=None, chunk: int | None = None, jitter: float = 1e-10, fit_mean: bool = False,
            method: str = "auto", eps: float | None = None, nthreads: int | None = None,
            exact_cond: float | None = None) -> np.ndarray:
    """Explained sum of squares of ``y`` by each grid frequency on its own (least-squares periodogram).

    For every ``f`` in ``freqs`` (cycles per unit x) the least-squares fit of ``y`` on the
    2J columns ``[Phi cos(2 pi f x), Phi sin(2 pi f x)]`` (the LPV regressors of Eq. (10.4) for one
    frequency; ``Phi = None``: one constant column, the generalized Lomb-Scargle periodogram without
    offset, Eq. (10.1)) and its explained sum of squares ``b^T G^-1 b`` is returned.  Divide by
    ``sum(y**2)`` for the explained fraction (astropy's ``LombScargle(fit_mean=False,
    center_data=False)`` "standard" power).

    ``fit_mean=True`` adds a floating offset (a constant column) to every frequency's model and
    returns the sum of squares explained beyond the mean, ``sum((y - mean y)**2) - RSS(f)``
    (astropy's ``fit_mean=True`` power times ``sum((y - mean y)**2)``).

    ``method``: ``"nufft"`` -- every sum of the normal equations by a non-uniform FFT
    (:mod:`drake_est.spectral.nufft`, O(N log(1/eps) + F log F), tolerance ``eps``, default 1e-13);
    ``"direct"`` -- explicit cosines and sines (O(N F), the reference); ``"auto"`` -- direct when
    ``N F <= 2e6`` or ``F < 8``, NUFFT otherwise.  With NUFFT, frequencies whose 2J x 2J normal
    equations have condition number above ``exact_cond`` (default ``1e-10 / eps``: near 0 and near a
    regular-sampling Nyquist rate the sine column vanishes and the NUFFT error would be amplified) are
    recomputed by the direct sums, so the result equals the direct path to a relative ~1e-9.  Scanning many
    signals at the same locations: :class:`LSScanPlan`."""
    x = _clean_1d(x, "sample locations")
    y = _clean_1d(y, "signal")
    if y.size != x.size:
        raise DataError(f"signal has {y.size} samples, sample locations {x.size}")
    return LSScanPlan(x, freqs, Phi, chunk=chunk, jitter=jitter, fit_mean=fit_mean, method=method, eps=eps,
                      nthreads=nthreads, exact_cond=exact_cond).ess(y)


def _ill_conditioned(S2d, m0d, T, tsum, limit: float) -> np.ndarray:
    """Indices of frequencies whose normal equations are ill conditioned because a column pair
    degenerates: for basis function j the (cos, sin) block has eigenvalues ``(m0_jj +- |S2_jj|)/2``, so
    its condition number is ``(1 + r)/(1 - r)`` with ``r = |sum phi_j^2 exp(2iwx)| / sum phi_j^2`` (-> 1 near
    0 and near a regular-sampling Nyquist rate, where the sine column vanishes); with the floating offset
    also ``r = |sum phi_j exp(iwx)| / sum phi_j`` (cosine column -> constant).  There the NUFFT error would be
    amplified, so these frequencies are recomputed by the direct sums.  O(F J)."""
    def cond(num, den):
        r = np.abs(num) / np.maximum(den, 1e-300)[:, None]
        return (1.0 + r) / np.maximum(1.0 - r, 1e-300)

    c = cond(S2d, m0d).max(axis=0)
    if T is not None:
        c = np.maximum(c, cond(T, np.abs(tsum)).max(axis=0))
    return np.flatnonzero(c > limit)


def _have_finufft() -> bool:
    try:
        import finufft  # noqa: F401
    except ImportError:
        return False
    return True


def _progress_if_slow(N: int, F: int, seconds_per_point: float = 1.5e-7):
    """A progress-bar factory for the NUFFT sums when they are expected to take more than a second
    (about ``seconds_per_point`` per sample and transform at tolerance 1e-13, one core), else None."""
    from drake_est.progress import progress

    def show(total: int):
        if total * (N * seconds_per_point + F * 1e-7) <= 1.0:
            return range(total)
        return progress(range(total), desc=f"NUFFT periodogram ({N} samples, {F} frequencies)", total=total)

    return show

