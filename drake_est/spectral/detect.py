"""Find periodic components of a signal in a position variable, with schedule-dependent
amplitude and phase (the LPV spectral method of thesis Ch. 10 used as a detector).

:func:`find_periodic_components` is what the diagnosis calls to name "motor-position
ripple": it does not need the gear ratio.  It

1. removes the part of the signal explained by a smooth function of the schedule (and any
   user ``base`` regressors, e.g. a friction model);
2. scans a frequency grid (cycles per unit of the position) with the least-squares
   periodogram of the LPV regressors (:func:`fft_scan`: samples binned on a fine position
   grid and all grid frequencies evaluated with FFTs, so tens of thousands of samples and
   frequencies take about a second);
3. refines the best frequency off the grid by a bounded 1-D search maximizing the exactly
   computed explained variance, adds the component, refits all components jointly
   (:class:`~drake_est.spectral.lpv.LPVSpectrum` with base columns) and repeats.

The result, :class:`PeriodicComponents`, holds the frequencies, their RMS amplitudes, the
explained variance fractions and can build the regressor columns of the components
(``[phi_bar(v) cos(2 pi f x), phi_bar(v) sin(2 pi f x)]``) for other models and held-out data.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.fft
import scipy.optimize

from drake_est.errors import DataError
from drake_est.spectral.basis import ScheduleBasis
from drake_est.spectral.lpv import LPVSpectrum
from drake_est.spectral.lssa import (_clean_1d, _pair_products, check_frequency_grid, frequency_resolution,
                                     ls_scan, sampling_density_limit)

MAX_FFT = 1 << 20
BINS_PER_PERIOD = 16


def _gram_solve(b, M0, Mc, Ms, J, jitter=1e-10):
    """Batched explained sum of squares b^T G^-1 b for per-frequency Gram blocks."""
    O = b.shape[0]
    G = np.empty((O, 2 * J, 2 * J))
    G[:, :J, :J] = 0.5 * (M0[None] + Mc)
    G[:, J:, J:] = 0.5 * (M0[None] - Mc)
    G[:, :J, J:] = 0.5 * Ms
    G[:, J:, :J] = np.transpose(0.5 * Ms, (0, 2, 1))
    scale = np.trace(G, axis1=1, axis2=2) / (2 * J)
    G = G + (jitter * np.maximum(scale, 1e-300))[:, None, None] * np.eye(2 * J)[None]
    sol = np.linalg.solve(G, b[..., None])[..., 0]
    return np.einsum("oi,oi->o", b, sol)


def fft_grid(x, f_max: float | None = None, f_min: float | None = None, oversample: float = 4.0,
             bins_per_period: int = BINS_PER_PERIOD, max_fft: int | None = None):
    """The automatic uniform grid of :func:`fft_scan`: ``(freqs, ks, h, M)`` with ``freqs = ks / (M h)``, ``h``
    the position bin and ``M`` the (FFT-friendly) number of bins."""
    x = _clean_1d(x, "sample locations")
    span = 1.0 / frequency_resolution(x)
    if f_max is None:
        f_max = sampling_density_limit(x)
    h = 1.0 / (bins_per_period * f_max)
    df = 1.0 / (oversample * span)
    M = int(np.ceil(1.0 / (df * h)))
    M = max(M, int(np.ceil(span / h)) + 2)
    max_fft = MAX_FFT if max_fft is None else int(max_fft)
    if M > max_fft:
        raise DataError(f"FFT scan up to {f_max:.6g} cycles per unit over a span of {span:.6g} needs {M} bins "
                        f"(> {max_fft}); lower f_max or oversample")
    M = scipy.fft.next_fast_len(M, real=True)
    df = 1.0 / (M * h)
    k_max = int(np.floor(f_max / df))
    k_min = max(1, int(np.ceil((f_min if f_min is not None else df) / df)))
    if k_min > k_max:
        raise DataError(f"empty scan range: f_min {f_min} above f_max {f_max}")
    ks = np.arange(k_min, k_max + 1)
    return ks * df, ks, h, M


def fft_scan(x, y, Phi=None, f_max: float | None = None, f_min: float | None = None, oversample: float = 4.0,
             bins_per_period: int = BINS_PER_PERIOD, max_fft: int | None = None, method: str = "nufft"):
    """Least-squares periodogram with LPV regressors on the automatic uniform grid, by (non-uniform) FFTs.

    The grid is ``k df`` with ``df`` about ``1 / (oversample * span)``, adjusted so that a position
    grid of step ``h = 1 / (bins_per_period * f_max)`` has an FFT-friendly number of bins ``M = 1/(df h)``
    (at most ``max_fft``).  ``method="nufft"`` (default): the explained sum of squares per frequency is
    exact, every sum of the normal equations by a type-1 NUFFT (:func:`~drake_est.spectral.lssa.ls_scan`);
    ``method="binned"``: the sums ``sum phi_j y exp(i w x)`` and ``sum phi_i phi_j exp(2 i w x)`` are FFTs
    of the samples binned on that position grid (phase error at most ``pi / bins_per_period`` at
    ``f_max``; approximate).  Returns ``(freqs, ess)``."""
    if method not in ("nufft", "binned"):
        raise DataError(f"unknown fft_scan method '{method}'; use nufft or binned")
    x = _clean_1d(x, "sample locations")
    y = _clean_1d(y, "signal")
    N = x.size
    if Phi is None:
        Phi = np.ones((N, 1))
    J = Phi.shape[1]
    freqs, ks, h, M = fft_grid(x, f_max, f_min, oversample, bins_per_period, max_fft)
    if method == "nufft":
        from drake_est.spectral.lssa import _have_finufft

        return freqs, ls_scan(x, y, freqs, Phi, method="nufft" if _have_finufft() else "direct")
    x0 = float(np.min(x))
    idx = np.rint((x - x0) / h).astype(np.int64)
    # conj(FFT) gives sum_b W(b) exp(+2 pi i k b / M); the e^{i w x0} factor restores absolute phase
    ph1 = np.exp(2j * np.pi * freqs * x0)
    ph2 = np.exp(4j * np.pi * freqs * x0)
    bc = np.empty((ks.size, J))
    bs = np.empty((ks.size, J))
    for j in range(J):
        W = np.bincount(idx, weights=Phi[:, j] * y, minlength=M)
        F = np.conj(scipy.fft.rfft(W, n=M))[ks] * ph1
        bc[:, j] = F.real
        bs[:, j] = F.imag
    PP, iu = _pair_products(Phi)
    m0 = PP.sum(axis=0)
    half0 = np.zeros((J, J))
    half0[iu] = m0
    M0 = half0 + np.triu(half0, 1).T
    Mc = np.empty((ks.size, J, J))
    Ms = np.empty((ks.size, J, J))
    k2 = 2 * ks          # < M / 2 because k_max = M / bins_per_period
    for c in range(PP.shape[1]):
        i, j = iu[0][c], iu[1][c]
        if m0[c] == 0.0:          # basis functions with disjoint support (sign split): no cross terms
            Mc[:, i, j] = Mc[:, j, i] = 0.0
            Ms[:, i, j] = Ms[:, j, i] = 0.0
            continue
        W = np.bincount(idx, weights=PP[:, c], minlength=M)
        F = np.conj(scipy.fft.rfft(W, n=M))[k2] * ph2
        Mc[:, i, j] = Mc[:, j, i] = F.real
        Ms[:, i, j] = Ms[:, j, i] = F.imag
    b = np.concatenate([bc, bs], axis=1)
    return freqs, _gram_solve(b, M0, Mc, Ms, J)


@dataclass
class PeriodicComponents:
    """Periodic components found by :func:`find_periodic_components`.

    Frequencies are in cycles per unit of the position given (cycles per radian for an angle);
    ``per_revolution()`` converts to cycles per revolution of that angle, and
    ``per_motor_revolution(gear_ratio)`` to cycles per motor revolution."""

    freqs: np.ndarray                 # (C,) cycles per unit position, strongest first
    amplitudes: np.ndarray            # (C,) RMS over the data of the amplitude function A(f, v)
    explained_fraction: np.ndarray    # (C,) (RSS without the component - RSS_full) / RSS_base
    total_explained_fraction: float   # (RSS_base - RSS_full) / RSS_base: share of what the schedule trend
                                      # and base columns leave that the periodic components explain
    base_explained_fraction: float    # (TSS - RSS_base) / TSS: explained by schedule trend + base columns
    basis: ScheduleBasis
    model: LPVSpectrum                # the joint fit (components + base columns)
    scan_freqs: np.ndarray = field(repr=False, default=None)
    scan_power: np.ndarray = field(repr=False, default=None)   # ESS / RSS_base per grid frequency (1st scan)
    velocity_trend: np.ndarray = None  # (C,) slope of A(f, v) against |v| over the data (amplitude per unit |v|)
    n_samples: int = 0

    @property
    def n_components(self) -> int:
        return self.freqs.size

    def per_revolution(self) -> np.ndarray:
        """Frequencies in cycles per revolution (position in radians)."""
        return self.freqs * 2 * np.pi

    def per_motor_revolution(self, gear_ratio: float) -> np.ndarray:
        """Frequencies in cycles per motor revolution when the position is the arm angle (rad)."""
        return self.freqs * 2 * np.pi / float(gear_ratio)

    @property
    def n_basis(self) -> int:
        return self.basis.n_basis

    def regressors(self, position, schedule=None, which=None) -> np.ndarray:
        """Columns (N, 2 J C') ``[phi_bar(v) cos(2 pi f x), phi_bar(v) sin(2 pi f x)]`` of the components
        ``which`` (default all), frequency-major, for adding them to another linear model."""
        x = _clean_1d(position, "position")
        which = np.arange(self.n_components) if which is None else np.atleast_1d(which)
        Phi = self._phi(schedule, x.size)
        arg = np.outer(x, 2 * np.pi * self.freqs[which])
        C, S = np.cos(arg), np.sin(arg)
        return LPVSpectrum._design_rows(Phi, C, S, None)

    def _phi(self, schedule, N):
        if self.basis.n_basis == 1:
            return np.ones((N, 1))
        if schedule is None:
            raise DataError("these components depend on the schedule; pass schedule=")
        v = _clean_1d(schedule, "schedule")
        if v.size != N:
            raise DataError(f"schedule has {v.size} samples, position {N}")
        return self.basis(v)

    def coefficients(self, which=None) -> np.ndarray:
        """Real coefficient vector matching :meth:`regressors` columns."""
        which = np.arange(self.n_components) if which is None else np.atleast_1d(which)
        k = self.model.coef[which]
        return np.stack([k.real, k.imag], axis=1).reshape(-1)

    def predict(self, position, schedule=None, which=None) -> np.ndarray:
        """The periodic part of the signal (without the base/schedule trend) at new samples."""
        return self.regressors(position, schedule, which) @ self.coefficients(which)

    def amplitude(self, v) -> np.ndarray:
        """Amplitude functions A(f, v) (C, M)."""
        return self.model.amplitude(v)

    def phase(self, v) -> np.ndarray:
        return self.model.phase(v)

    def summary(self, gear_ratio: float | None = None) -> list:
        """One dict per component, JSON-ready."""
        out = []
        for c in range(self.n_components):
            d = {"frequency_per_unit": float(self.freqs[c]),
                 "frequency_per_rev": float(self.freqs[c] * 2 * np.pi),
                 "rms_amplitude": float(self.amplitudes[c]),
                 "explained_fraction": float(self.explained_fraction[c])}
            if gear_ratio:
                d["frequency_per_motor_rev"] = float(self.freqs[c] * 2 * np.pi / gear_ratio)
            if self.velocity_trend is not None:
                d["amplitude_slope_vs_speed"] = float(self.velocity_trend[c])
            out.append(d)
        return out


#: :class:`_SingleFrequencyESS` keeps the basis pairs' products as one matrix up to this many numbers (64 MB)
SINGLE_ESS_MAX_ELEMS = 8_000_000


class _SingleFrequencyESS:
    """Explained sum of squares of ``r`` by the 2J LPV regressors of one frequency (Eq. (10.5) for one
    frequency), by direct sums over the samples: what the off-grid refinement maximizes.  The products of the
    basis pairs are kept as one matrix while it holds at most :data:`SINGLE_ESS_MAX_ELEMS` numbers (each call is
    then two matrix products); for longer logs the pairs are streamed, so memory stays O(N)."""

    def __init__(self, x, r, Phi, jitter: float = 1e-10):
        self.xs = x - 0.5 * (float(np.min(x)) + float(np.max(x)))     # shift invariant, better rounded
        self.Py = Phi * r[:, None]
        self.Phi = Phi
        J = Phi.shape[1]
        self.iu = np.triu_indices(J)
        self.m0 = np.array([Phi[:, i] @ Phi[:, j] for i, j in zip(*self.iu)])
        self.jitter = jitter
        # the pairs with overlapping support (disjoint ones of a sign split have no cross terms)
        self.live = np.flatnonzero((self.m0 != 0.0) | (self.iu[0] == self.iu[1]))
        self.PP = None
        if self.live.size * x.size <= SINGLE_ESS_MAX_ELEMS:
            self.PP = np.stack([Phi[:, self.iu[0][k]] * Phi[:, self.iu[1][k]] for k in self.live])

    def __call__(self, f: float) -> float:
        from drake_est.spectral.nufft import explained_ss, gram_blocks, sym_blocks

        a = (2 * np.pi * f) * self.xs
        c, s = np.cos(a), np.sin(a)
        b = np.r_[self.Py.T @ c, self.Py.T @ s]
        c2 = c * c - s * s
        s2 = 2.0 * c * s
        J = self.Phi.shape[1]
        mc = np.zeros(self.m0.size)
        ms = np.zeros(self.m0.size)
        if self.PP is not None:
            mc[self.live] = self.PP @ c2
            ms[self.live] = self.PP @ s2
        else:
            for k in self.live:
                w = self.Phi[:, self.iu[0][k]] * self.Phi[:, self.iu[1][k]]
                mc[k], ms[k] = w @ c2, w @ s2
        iu = self.iu
        G = gram_blocks(sym_blocks(self.m0, iu, J), sym_blocks(mc[None], iu, J), sym_blocks(ms[None], iu, J))
        return float(explained_ss(G, b[None], self.jitter)[0])


def _single_ess(x, r, Phi, f):
    return _SingleFrequencyESS(x, r, Phi)(f)


def default_schedule_basis(schedule, n_basis: int, sign_split=None) -> ScheduleBasis:
    v = np.asarray(schedule, dtype=float)
    if sign_split is None:
        sign_split = bool(np.mean(v > 0) > 0.05 and np.mean(v < 0) > 0.05 and n_basis >= 2)
    if sign_split and n_basis < 2:
        n_basis = 2
    return ScheduleBasis.from_data(v, n_basis, sign_split=sign_split, quantile=0.005)


def find_periodic_components(position, signal, schedule=None, freq_grid=None, n_components: int = 3,
                             n_basis: int = 4, sign_split=None, f_max: float | None = None,
                             f_min: float | None = None, oversample: float = 4.0, base=None, lam: float = 1e-8,
                             max_fft: int = MAX_FFT, refine: bool = True,
                             scan_plans: dict | None = None) -> PeriodicComponents:
    """Dominant periodic components of ``signal`` in ``position`` with amplitude/phase depending on ``schedule``.

    Parameters
    ----------
    position : (N,) sampling locations, e.g. the arm angle q [rad] (any order, any spacing).
    signal : (N,) e.g. a torque residual.
    schedule : (N,) scheduling variable, e.g. the velocity; None for a constant amplitude.
    freq_grid : frequencies (cycles per unit position) to scan; default: a uniform grid from
        ``f_min`` (default 2 / span) to ``f_max`` (default: the sampling-density limit of ``position``,
        capped so the FFT scan fits in ``max_fft`` bins), spacing ``1 / (oversample span)``.
        A grid above the sampling-density limit raises :class:`DataError`.
    n_components : how many components to extract (greedily, strongest first).
    n_basis, sign_split : schedule basis: ``n_basis`` normalized Gaussians in all; with the Coulomb-style
        sign split (default when more than 5 % of the samples have each sign) ``ceil(n_basis / 2)`` of them
        on v >= 0 and the rest on v < 0.
    base : (N, b) extra regressors fitted jointly and not counted as periodic (e.g. friction terms).
    lam : tiny ridge (relative to the mean Gram diagonal) for numerical safety.
    scan_plans : a dict in which the periodogram's signal-independent part (:class:`~drake_est.spectral.lssa.
        LSScanPlan`) is kept, keyed by a fingerprint of the positions, grid and basis, and reused by later calls
        at the same positions (the diagnosis scans residual after residual of one joint); None: not kept.
    """
    x = _clean_1d(position, "position")
    y = _clean_1d(signal, "signal")
    N = x.size
    if y.size != N:
        raise DataError(f"signal has {y.size} samples, position {N}")
    if n_components < 1:
        raise DataError(f"n_components must be >= 1, got {n_components}")
    with np.errstate(over="ignore", invalid="ignore"):
        too_big = not (np.isfinite(np.sum((y - np.mean(y)) ** 2)) and np.isfinite(np.ptp(x) * np.max(np.abs(x))))
    if too_big:
        raise DataError(f"signal or position values are too large for floating point (max |signal| "
                        f"{np.max(np.abs(y)):.3g}, max |position| {np.max(np.abs(x)):.3g}); check the units")
    if schedule is not None:
        v = _clean_1d(schedule, "schedule")
        if v.size != N:
            raise DataError(f"schedule has {v.size} samples, position {N}")
        basis = default_schedule_basis(v, n_basis, sign_split)
        Phi = basis(v)
    else:
        v = None
        basis = ScheduleBasis(1)
        Phi = np.ones((N, 1))
    J = basis.n_basis
    if N < 4 * J * (n_components + 1):
        raise DataError(f"{N} samples are too few for {n_components} components with {J} basis functions "
                        f"(need at least {4 * J * (n_components + 1)})")
    B = Phi if base is None else np.hstack([Phi, np.asarray(base, dtype=float).reshape(N, -1)])
    if not np.all(np.isfinite(B)):
        raise DataError("base regressors contain NaN/inf")
    # an orthonormal basis of the span of [schedule basis, base]: base columns that the sign-split
    # schedule basis already spans (e.g. sign(v)) are dropped instead of making the fit singular
    U, sv, _ = np.linalg.svd(B, full_matrices=False)
    B = U[:, sv > sv[0] * 1e-10] * np.sqrt(N)
    coef_b, *_ = np.linalg.lstsq(B, y, rcond=None)
    r0 = y - B @ coef_b
    tss = float(np.sum((y - y.mean()) ** 2))
    if tss <= 0:
        raise DataError("signal is constant; nothing periodic to find")
    rss_base = float(r0 @ r0)
    if not rss_base > 1e-20 * tss:
        raise DataError(f"the schedule and base regressors explain the signal entirely (residual "
                        f"{rss_base / tss:.1e} of its variance): nothing periodic is left; is the schedule the "
                        "signal itself?")
    span = 1.0 / frequency_resolution(x)
    limit = sampling_density_limit(x)
    res = 1.0 / span
    if freq_grid is None:
        if f_min is None:
            f_min = 2.0 * res
        cap = max_fft / (oversample * span * BINS_PER_PERIOD) * 0.99
        fm = min(limit, cap) if f_max is None else f_max
        if fm > limit * (1 + 1e-9):
            raise DataError(f"f_max = {fm:.6g} is above the sampling-density limit {limit:.6g} of the position "
                            f"(quantization step {0.5 / limit:.3g}); higher frequencies alias")
        grid = fft_grid(x, f_max=fm, f_min=f_min, oversample=oversample, max_fft=max_fft)[0]
        step = res / oversample
    else:
        grid = check_frequency_grid(x, freq_grid)
        step = float(np.min(np.diff(np.unique(grid)))) if grid.size > 1 else res
    # the automatic grid is scanned by NUFFT (fft_scan's default), a user grid as ls_scan chooses
    fits = {}

    def joint_fit(fs):            # the same frequency list gives the same fit: the greedy loop's fits are reused
        key = tuple(float(f) for f in fs)
        if key not in fits:
            fits[key] = _joint_fit(x, y, v, basis, list(key), B, lam)
        return fits[key]

    plan = _scan_plan(x, grid, Phi, scan_plans, "nufft" if freq_grid is None else "auto")
    scan = lambda r: (grid, plan.ess(r))  # noqa: E731
    found = []
    r = r0
    scan_freqs = scan_power = None
    model = None
    for c in range(n_components):
        fr, ess = scan(r)
        if scan_freqs is None:
            scan_freqs, scan_power = fr, ess / rss_base
        ess = np.where(np.isfinite(ess), ess, -np.inf)
        for f0 in found:
            ess[np.abs(fr - f0) < 1.5 * res] = -np.inf
        if not np.any(np.isfinite(ess)):
            break
        k = int(np.argmax(ess))
        f = float(fr[k])
        if refine:
            lo, hi = max(f - step, 1e-12), f + step
            ess1 = _SingleFrequencyESS(x, r, Phi)
            opt = scipy.optimize.minimize_scalar(lambda ff: -ess1(ff), bounds=(lo, hi),
                                                 method="bounded", options={"xatol": 1e-7 * max(f, 1e-9)})
            if -opt.fun >= ess[k]:
                f = float(opt.x)
        found.append(f)
        model = joint_fit(found)
        r = y - model.predict(x, v, base=B)
    if model is None:
        raise DataError("no periodic component could be fitted: the scan has no finite power at any frequency "
                        "(signal or position values out of floating-point range?)")
    freqs = np.array(found)
    rss_full = model.rss
    expl = np.empty(freqs.size)
    for c in range(freqs.size):
        others = [f for i, f in enumerate(found) if i != c]
        rss_wo = rss_base if not others else joint_fit(others).rss
        expl[c] = (rss_wo - rss_full) / rss_base
    amp = model.amplitude(v if v is not None else None) if J > 1 else np.abs(model.coef)
    rms = np.sqrt(np.mean(amp**2, axis=1))
    trend = None
    if v is not None:
        av = np.abs(v)
        A = np.column_stack([np.ones(N), av])
        trend = np.linalg.lstsq(A, amp.T, rcond=None)[0][1]
    order = np.argsort(-expl)
    sel = lambda a: None if a is None else a[order]  # noqa: E731
    model_sorted = joint_fit(freqs[order])
    return PeriodicComponents(freqs=freqs[order], amplitudes=rms[order], explained_fraction=expl[order],
                              total_explained_fraction=float((rss_base - rss_full) / rss_base),
                              base_explained_fraction=float((tss - rss_base) / tss), basis=basis,
                              model=model_sorted, scan_freqs=scan_freqs, scan_power=scan_power,
                              velocity_trend=sel(trend), n_samples=N)


#: how many scan plans a ``scan_plans`` dict keeps (the oldest are dropped; each holds (O, 2J, 2J) Gram blocks)
MAX_SCAN_PLANS = 2


def _scan_plan(x, grid, Phi, scan_plans, method="auto"):
    """An :class:`~drake_est.spectral.lssa.LSScanPlan` for these positions, grid and basis, from ``scan_plans``
    when one was made for the same (fingerprint of the arrays' bytes)."""
    import hashlib

    from drake_est.spectral.lssa import LSScanPlan, _have_finufft

    method = method if _have_finufft() else "direct"
    if scan_plans is None:
        return LSScanPlan(x, grid, Phi, method=method)
    h = hashlib.blake2b(digest_size=16)
    h.update(method.encode())
    for a in (x, grid, Phi):
        a = np.ascontiguousarray(a, dtype=float)
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    key = h.hexdigest()
    if key not in scan_plans:
        while len(scan_plans) >= MAX_SCAN_PLANS:
            scan_plans.pop(next(iter(scan_plans)))
        scan_plans[key] = LSScanPlan(x, grid, Phi, method=method)
    return scan_plans[key]


def _joint_fit(x, y, v, basis, freqs, B, lam):
    m = LPVSpectrum(np.asarray(freqs, float), basis=basis, lam=0.0, check_grid=False, solver="direct",
                    direct_max=10**9)
    # tiny relative ridge through the direct solver: scale with the data
    m.lam = lam * float(np.sum(basis(v) ** 2) if v is not None else x.size) / max(basis.n_basis, 1)
    return m.fit(x, y, v, base=B)
