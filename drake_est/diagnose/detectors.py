"""Candidate model extensions of the diagnosis, one per effect of the vocabulary.

Each detector looks at the *training* part of the current residual of one joint (or of all
joints, for the payload), chooses its nonlinear structure there (frequency, time constant, change
time, number of kernels) and returns an :class:`Extension`: extra regressor columns that are
linear in their parameters, plus what is needed to evaluate them at new samples.  The caller
(:mod:`drake_est.diagnose.core`) refits the whole model with the extension on the training part
and judges it on the validation part.

==============================  ==============================================  ============
effect                          columns                                         thesis
==============================  ==============================================  ============
position_dependent_friction     sign(qd) phi_k(q), Gaussian kernels in arm q    (9.13)-(9.16)
motor_position_ripple           LPV periodic components in q, amplitude(qd)     Ch. 10
energy_dependent_friction       [sign(qd), qd] E, E = 1/(tau_e s + 1) |F qd|   (9.21)-(9.29), Alg. 6
asymmetric_coulomb              1[qd < 0] (a different Coulomb level)           (9.3)
gear_coupling                   qd_i, sign(qd_i) of the coupled joints i        (9.12)
payload                         ID with 1 kg at the flange (4 COM offsets)      rigid body
abrupt_change                   [qd, sign(qd)] 1[t >= t_c], t_c by DP            Ch. 7, (7.8)
position_dependent_load         phi_k(q) (no sign): gravity/spring, generic only  (added name)
==============================  ==============================================  ============
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.optimize

from drake_est.diagnose.parallel import pmap
from drake_est.effects import EFFECTS, EXTRA_EFFECTS  # noqa: F401
# the column evaluators are friction terms now (one friction model); re-exported under their old names
from drake_est.identification.friction.extensions import (columns_at, gaussian_features,  # noqa: F401
                                                          stribeck_columns, unit_energy)

RIPPLE_BASIS = 8
#: asymmetric Coulomb is a candidate only when each direction holds at least this share of the training samples
ASYM_MIN_SHARE = 0.05
#: the ripple scan starts at this many cycles over the position span (slower variation is position-dependent
#: friction's); 5 lets a 7-per-revolution cogging over one revolution be seen
RIPPLE_MIN_CYCLES = 5.0
BFE_SIZES = (8, 16, 32, 64)
#: eighty-third round (kept): a number of position kernels is tried only when every kernel holds at
#: least :data:`MIN_KERNEL_SUPPORT` training samples' worth of its weight (:func:`kernel_support`); the smallest
#: size is always tried
KERNEL_SUPPORT_RULE = True
#: the least summed weight sum_i exp(-(q_i - c_k)^2 / (2 w^2)) over the training rows of each kernel k: one
#: sample's worth (below it no sample determines the coefficient)
MIN_KERNEL_SUPPORT = 1.0
#: eighty-fourth round (see ``docs/readme/diagnose_testbench.md``): an abrupt change's time is chosen only among the
#: splits where the training rows on each side hold at least :data:`MIN_CHANGE_SUPPORT` samples' worth of the
#: Coulomb + viscous law at every speed of the log (:func:`split_supports`); none such: no change candidate
CHANGE_SUPPORT_RULE = False
#: the least support (:func:`segment_supports`) of a change's segment at the log's lowest and highest speed: one
#: sample's worth (the leverage x^T (P^T P)^-1 x of the law's value there at most 1)
MIN_CHANGE_SUPPORT = 1.0
#: FFT bins of the frequency scan: the highest frequency scanned is about
#: RIPPLE_MAX_FFT / (64 span) cycles per rad (e.g. 680 cycles/rad over a 3 rad sweep), or the
#: sampling-density limit of the positions if lower
RIPPLE_MAX_FFT = 1 << 17
#: the effect vocabulary: the one list of :mod:`drake_est.effects`
VOCABULARY = EFFECTS


@dataclass
class Extension:
    """A candidate model extension.

    ``cols``: {joint: (n_rows_j, d) columns at that joint's used rows} (several joints only for
    shared-parameter extensions such as the payload); ``spec``: JSON-able description used to
    evaluate the columns at new samples (:func:`columns_at`); ``evidence``: detector output."""

    effect: str
    joint: int
    cols: dict
    names: list
    spec: dict
    evidence: dict = field(default_factory=dict)
    obj: object = None        # e.g. the PeriodicComponents of the ripple (not serialized)

    @property
    def n_params(self) -> int:
        return len(self.names)

    @property
    def shared(self) -> bool:
        """Parameters shared by several joints (the payload), fitted on all joints at once."""
        return self.effect == "payload" or len(self.cols) > 1


# ----------------------------------------------------------------------------- helpers


def _sgn(v):
    return np.sign(v)


# ----------------------------------------------------------------------------- detectors


def training_directions(jd) -> tuple:
    """(samples moving in the negative direction, all samples) among the selected training rows of ``jd``."""
    return int(np.sum(jd.v[jd.rows][jd.train] < 0)), int(jd.train.sum())


def asymmetric_testable(jd) -> bool:
    """Whether each direction holds enough of the selected training samples (:data:`ASYM_MIN_SHARE`, at least 20)
    for a direction-dependent Coulomb level: a few reversals inside a stick-slip of a one-direction sweep (about 1 %
    of the ODrive cogging samples) are not motion in both directions."""
    n_neg, n_tr = training_directions(jd)
    return min(n_neg, n_tr - n_neg) >= max(20, ASYM_MIN_SHARE * n_tr)


def asymmetric_level(jd) -> Extension:
    """The asymmetric Coulomb level of ``jd`` (a constant torque added while moving in the negative direction), whether
    or not the log can test it (:func:`asymmetric_testable`)."""
    c = (jd.v[jd.rows] < 0).astype(float)[:, None]
    n_neg, _ = training_directions(jd)
    return Extension("asymmetric_coulomb", jd.joint, {jd.joint: c}, ["dkc_neg"], {"effect": "asymmetric_coulomb"},
                     {"negative_velocity_samples": n_neg})


def asymmetric(jd, r):
    if not asymmetric_testable(jd):
        return None
    return asymmetric_level(jd)


#: the position laws built from Gaussian kernels in q: effect -> (parameter prefix, times sign(qd))
POSITION_KERNEL_LAWS = {"position_dependent_friction": ("w", True), "position_dependent_load": ("g", False)}


def position_kernels_at(jd, effect, K, lo, hi):
    """The extension of the position law ``effect`` (:data:`POSITION_KERNEL_LAWS`) with ``K`` Gaussian kernels spread
    evenly over [lo, hi] of arm position, times sign(qd) for a friction; a load also carries the gravity/spring
    shape sin q, cos q exactly (a large gravity load is not fitted to the noise level by kernels alone, and what they
    leave is named as other effects: issue 16 item 6)."""
    prefix, signed = POSITION_KERNEL_LAWS[effect]
    q = jd.q[jd.rows]
    centers = np.linspace(lo, hi, K)
    width = (hi - lo) / (K - 1)
    s = _sgn(jd.v[jd.rows])[:, None] if signed else 1.0
    H = np.empty((q.size, 0)) if signed else np.column_stack([np.sin(q), np.cos(q)])
    G = jd.cached_columns(("gauss", float(lo), float(hi), int(K)), lambda: gaussian_features(q, centers, width))
    C = np.hstack([H, s * G])
    spec = {"effect": effect, "centers": centers.tolist(), "width": float(width)}
    names = [f"{prefix}{k}" for k in range(K)]
    if not signed:
        spec["gravity_harmonic"] = True
        names = [f"{prefix}_sin", f"{prefix}_cos"] + names
    return Extension(effect, jd.joint, {jd.joint: C}, names, spec,
                     {"n_kernels": int(K), "kernel_width_rad": float(width), "range_rad": [float(lo), float(hi)]})


def kernel_support(q, K, lo, hi) -> np.ndarray:
    """Each of ``K`` Gaussian kernels' summed weight over the positions ``q`` (the training rows): about how many
    samples determine its coefficient.  A kernel over a stretch that the training blocks do not visit while the
    held-out blocks do has almost none; its coefficient is then set by the ridge alone, which is scaled to the
    column's norm (:func:`~drake_est.diagnose.core._ridge_lstsq`) and so barely holds it (loop spec 29730: 64
    kernels over a 0.12 rad hole in the training positions, one kernel weighing 0.23 samples; coefficients up to 39
    N m, the held-out RMSE 1.9 against 0.14 with 8 kernels)."""
    centers = np.linspace(lo, hi, K)
    return gaussian_features(q, centers, (hi - lo) / (K - 1)).sum(axis=0)


def supported_sizes(q, lo, hi, sizes=None, min_support=None) -> list:
    """The numbers of kernels (:data:`BFE_SIZES`) whose every kernel holds ``min_support`` (default
    :data:`MIN_KERNEL_SUPPORT`) of the positions ``q``; the smallest size always."""
    sizes = BFE_SIZES if sizes is None else sizes
    m = MIN_KERNEL_SUPPORT if min_support is None else min_support
    return [K for i, K in enumerate(sizes) if i == 0 or kernel_support(q, K, lo, hi).min() >= m]


def kernel_range(q_train):
    """(lo, hi) over which the position laws spread their kernels: the 0.2 % and 99.8 % quantiles of the training
    positions ``q_train``; None when they span less than 0.02."""
    lo, hi = np.quantile(q_train, [0.002, 0.998])
    return None if hi - lo < 0.02 else (lo, hi)


def _position_kernels(jd, fit_inner, effect):
    """:func:`position_kernels_at` over the training range (:func:`kernel_range`), the number of kernels (BFE_SIZES)
    chosen by ``fit_inner`` (with :data:`KERNEL_SUPPORT_RULE`: among the sizes the training positions support,
    :func:`supported_sizes`). None when the joint spans less than 0.02."""
    q = jd.q[jd.rows]
    span = kernel_range(q[jd.train])
    if span is None:
        return None
    lo, hi = span
    best = None
    for K in (supported_sizes(q[jd.train], lo, hi) if KERNEL_SUPPORT_RULE else BFE_SIZES):
        ext = position_kernels_at(jd, effect, K, lo, hi)
        err = fit_inner(ext.cols[jd.joint])
        if best is None or err < best[0]:
            best = (err, ext)
    return best[1]


def position_bfe(jd, r, block_of_rows, fit_inner):
    """Gaussian kernels in arm position times sign(qd) (9.16); number of kernels chosen on the
    training part by an inner split (train blocks 0, 4, 8, ... vs 2, 6, 10, ...)."""
    return _position_kernels(jd, fit_inner, "position_dependent_friction")


def position_load(jd, r, fit_inner):
    """A direction-independent torque that depends on position (gravity, springs, cables): Gaussian
    kernels in position, not multiplied by sign(qd).  Used for generic axes, whose nominal model has no
    gravity; an added effect name (the vocabulary may grow)."""
    return _position_kernels(jd, fit_inner, "position_dependent_load")


def ripple(jd, r, n_components=2, n_basis=None, fit_inner=None):
    """LPV spectral detector (Ch. 10): periodic components of the residual in arm position with
    velocity-dependent amplitude; no gear ratio is assumed.  With ``fit_inner`` (and no ``n_basis``) the
    amplitude model is chosen on the inner split of the training part: constant (one basis function) or
    velocity-dependent (RIPPLE_BASIS functions); a constant-amplitude ripple seen over a few speed levels is
    otherwise fitted with many loosely determined amplitude coefficients and loses to a kernel expansion in q."""
    if fit_inner is None or n_basis is not None:
        return _ripple(jd, r, n_components, n_basis)
    from drake_est.identification.friction.extensions import RippleRegressors, ripple_regressors
    ext = _ripple(jd, r, n_components, RIPPLE_BASIS)
    if ext is None:
        return None
    rr = ripple_regressors(ext.spec)
    const = RippleRegressors(rr.freqs, {**rr.basis_spec, "n_basis": 1, "sign_split": False})
    q, v = jd.q[jd.rows], jd.v[jd.rows]
    C1 = const.regressors(q, v)
    if fit_inner(C1) <= fit_inner(ext.cols[jd.joint]):
        ext.cols = {jd.joint: C1}
        ext.names = [f"c{k}" for k in range(C1.shape[1])]
        ext.spec["_pc"] = const
        ext.evidence["amplitude_slope_vs_speed"] = None
    ext.evidence["amplitude_basis_functions"] = int(ext.cols[jd.joint].shape[1] // (2 * rr.freqs.size))
    return ext


def _ripple(jd, r, n_components=2, n_basis=None):
    from drake_est.errors import DrakeEstError
    from drake_est.spectral.detect import find_periodic_components

    tr = jd.train
    q = jd.q[jd.rows]
    v = jd.v[jd.rows]
    qt, vt, rt = q[tr], v[tr], r[tr]
    span = float(np.ptp(qt))
    if span <= 0:
        return None
    try:
        pc = find_periodic_components(qt, rt, schedule=vt, n_components=n_components, n_basis=n_basis or RIPPLE_BASIS,
                                      f_min=RIPPLE_MIN_CYCLES / span, base=np.column_stack([_sgn(vt), vt]),
                                      max_fft=RIPPLE_MAX_FFT, scan_plans=getattr(jd, "scan_plans", None))
    except DrakeEstError:
        return None
    keep = [i for i in range(pc.n_components) if pc.explained_fraction[i] > 0.01] or [0]
    keep = _not_aliased(pc, keep, qt, vt, rt) 
    C = pc.regressors(q, v, which=keep)
    spec = {"effect": "motor_position_ripple", "frequencies_per_arm_rad": [float(f) for f in pc.freqs[keep]],
            "_pc": pc, "_which": keep}
    f0 = float(pc.freqs[keep[0]])
    ev = {"frequency_per_arm_rad": f0, "frequency_per_arm_rev": f0 * 2 * np.pi,
          "frequencies_per_arm_rad": [float(f) for f in pc.freqs[keep]],
          "explained_fraction_train": [float(x) for x in pc.explained_fraction[keep]],
          "amplitude_slope_vs_speed": None if pc.velocity_trend is None else float(pc.velocity_trend[keep[0]]),
          "rms_amplitude": float(pc.amplitudes[keep[0]])}
    if jd.gear_ratio:
        ev["frequency_per_motor_rev"] = f0 * 2 * np.pi / jd.gear_ratio
    ext = Extension("motor_position_ripple", jd.joint, {jd.joint: C}, [f"c{k}" for k in range(C.shape[1])], spec, ev,
                    obj=pc)
    ext.spec["_pc"] = _Sub(pc, keep)
    return ext


#: half-width, in frequency resolutions (one over the span of the training positions), of the joint search of a
#: ripple's frequencies (:func:`ripple_refined`)
RIPPLE_REFINE_WIDTH = 2.0
#: grid steps per frequency resolution of that search, before a bounded 1-D polish
RIPPLE_REFINE_STEPS = 4
#: most coordinate sweeps of that search
RIPPLE_REFINE_SWEEPS = 3


def ripple_refined(jd, r, ext, width=RIPPLE_REFINE_WIDTH, steps=RIPPLE_REFINE_STEPS, sweeps=RIPPLE_REFINE_SWEEPS):
    """The ripple ``ext`` with its frequencies chosen jointly, by least squares on the training rows of the residual
    ``r`` beside [sign(qd), qd] (the detector's base), each in turn given the others: a scan of +-``width``
    resolutions (1 / the training positions' span) at ``steps`` points per resolution, then a bounded 1-D search,
    for at most ``sweeps`` rounds (Ch. 10's periodogram maximized over all components at once, not greedily).  The
    detector places each component on the residual of those found before it, with a velocity-dependent amplitude
    that can bend a wrong frequency's phase back where the speeds follow the positions; the constant-amplitude
    columns chosen after it keep that frequency, whose phase misfit drifts over the joint's range (loop spec 19128:
    a ripple of 9.708 cycles/rad and its harmonic found at 9.76 and 18.79, training residual 480 against 29.8 at
    the generator's frequencies, where a disturbance in time took the misfit).  Returns a new extension (evidence
    ``jointly_refined_from_frequencies_per_arm_rad``) or ``ext`` when no frequency moves."""
    from drake_est.identification.friction.extensions import RippleRegressors, ripple_regressors
    from drake_est.spectral.lpv import LPVSpectrum
    rr = ripple_regressors(ext.spec)
    tr = jd.train
    q, v = jd.q[jd.rows], jd.v[jd.rows]
    qt, vt, rt = q[tr], v[tr], r[tr]
    span = float(np.ptp(qt))
    if span <= 0 or rr.freqs.size == 0:
        return ext
    res = 1.0 / span
    f = rr.freqs.astype(float).copy()
    B = np.column_stack([_sgn(vt), vt])
    Phi = np.ones((qt.size, 1)) if rr.basis.n_basis == 1 else rr.basis(vt)     # the schedule basis, made once

    def comp(ff):
        """The columns of one component at ``ff`` cycles/rad (those of RippleRegressors, the basis made once)."""
        arg = (qt * (2 * np.pi * ff))[:, None]
        return LPVSpectrum._design_rows(Phi, np.cos(arg), np.sin(arg), None)

    cols = [comp(ff) for ff in f]

    def ess_given(Q, rk, ff):
        """The training sum of squares the component at ``ff`` explains of ``rk`` beyond the columns ``Q`` spans
        (orthonormal), by its Gram matrix (a few columns)."""
        Z = comp(ff)
        Z = Z - Q @ (Q.T @ Z)
        b = Z.T @ rk
        c = np.linalg.lstsq(Z.T @ Z, b, rcond=None)[0]
        return float(b @ c)

    for _ in range(sweeps):
        moved = False
        for k in range(f.size):
            A = np.hstack([B] + [cols[i] for i in range(f.size) if i != k])
            U, sv, _ = np.linalg.svd(A, full_matrices=False)
            Q = U[:, sv > sv[0] * 1e-10]
            rk = rt - Q @ (Q.T @ rt)
            grid = f[k] + res * np.arange(-width * steps, width * steps + 1) / steps
            others = np.delete(f, k)
            grid = grid[(grid > 0) & np.all(np.abs(grid[:, None] - others[None, :]) >= 0.5 * res, axis=1)]
            if not grid.size:
                continue
            e = np.array([ess_given(Q, rk, ff) for ff in grid])
            best = float(grid[int(np.argmax(e))])
            h = res / steps
            opt = scipy.optimize.minimize_scalar(lambda ff: -ess_given(Q, rk, ff), bounds=(best - h, best + h),
                                                 method="bounded", options={"xatol": 1e-7 * best})
            top = float(e.max())
            if -opt.fun > top:
                best, top = float(opt.x), float(-opt.fun)
            if top <= ess_given(Q, rk, f[k]) + 1e-12 * float(rk @ rk):
                continue        # the current frequency is as good
            if best != f[k]:
                moved = moved or abs(best - f[k]) > 0.01 * res     # another sweep only after a move of note
                f[k], cols[k] = best, comp(best)
        if not moved:
            break
    if np.allclose(f, rr.freqs, rtol=0, atol=1e-6 * res):
        return ext
    new_rr = RippleRegressors(f, rr.basis_spec)
    C = new_rr.regressors(q, v)
    spec = {**ext.spec, "frequencies_per_arm_rad": [float(x) for x in f], "_pc": new_rr}
    spec.pop("_which", None)
    ev = {**ext.evidence, "frequency_per_arm_rad": float(f[0]), "frequency_per_arm_rev": float(f[0]) * 2 * np.pi,
          "frequencies_per_arm_rad": [float(x) for x in f],
          "jointly_refined_from_frequencies_per_arm_rad": [float(x) for x in rr.freqs]}
    if jd.gear_ratio:
        ev["frequency_per_motor_rev"] = float(f[0]) * 2 * np.pi / jd.gear_ratio
    return Extension(ext.effect, ext.joint, {jd.joint: C}, [f"c{k}" for k in range(C.shape[1])], spec, ev,
                     obj=ext.obj)


def _not_aliased(pc, keep, q, v, r, min_frac=0.01, n_bins=4, need=3):
    """Drop components that explain the residual at some speeds only.

    Sampling in time aliases a ripple of f cycles/rad seen at speed v to f + m fs / v: over a segment of
    constant speed the alias fits as well as the true frequency.  A real position-periodic effect
    shows at slow and at fast speeds; so a component must explain at least ``min_frac`` of the residual
    variance (beyond [sign(v), v]) in ``need`` of the ``n_bins`` speed quantile bins.  The strongest
    component is kept if none passes."""
    av = np.abs(v)
    edges = np.quantile(av, np.linspace(0, 1, n_bins + 1))
    bins = np.clip(np.searchsorted(edges, av, side="right") - 1, 0, n_bins - 1)
    ok = []
    for i in keep:
        C = pc.regressors(q, v, which=[i])
        passed = 0
        for b in range(n_bins):
            half = bins == b
            if half.sum() < 4 * (C.shape[1] + 2):
                continue
            B = np.column_stack([_sgn(v[half]), v[half]])
            rb = r[half] - B @ np.linalg.lstsq(B, r[half], rcond=None)[0]
            A = np.hstack([B, C[half]])
            rf = r[half] - A @ np.linalg.lstsq(A, r[half], rcond=None)[0]
            if (rb @ rb - rf @ rf) >= min_frac * (rb @ rb) + 2.0 * C.shape[1] * (rf @ rf) / max(half.sum(), 1):
                passed += 1
        if passed >= need:
            ok.append(i)
    return ok or [keep[0]]


def present_at_all_speeds(C, v, r, min_frac=0.01, n_bins=4, need=3):
    """Whether the columns C explain at least ``min_frac`` of the residual variance beyond [sign(v), v]
    (plus an AIC-like margin of 2 d s^2) in ``need`` of ``n_bins`` speed quantile bins (bins with too few
    samples are not counted).  Used for components that must not depend on speed (a time-periodic
    disturbance); the ripple's alias check (:func:`_not_aliased`) applies the same rule per component.
    True (not testable) when the log has one speed level only (the 10-90 % speeds within a factor 1.3)."""
    av = np.abs(v)
    lo, hi = np.quantile(av, [0.1, 0.9])
    if hi < 1.3 * lo:
        return True
    edges = np.quantile(av, np.linspace(0, 1, n_bins + 1))
    bins = np.clip(np.searchsorted(edges, av, side="right") - 1, 0, n_bins - 1)
    passed = 0
    for b in range(n_bins):
        m = bins == b
        if m.sum() < 4 * (C.shape[1] + 2):
            continue
        B = np.column_stack([_sgn(v[m]), v[m]])
        rb = r[m] - B @ np.linalg.lstsq(B, r[m], rcond=None)[0]
        A = np.hstack([B, C[m]])
        rf = r[m] - A @ np.linalg.lstsq(A, r[m], rcond=None)[0]
        if (rb @ rb - rf @ rf) >= min_frac * (rb @ rb) + 2.0 * C.shape[1] * (rf @ rf) / max(m.sum(), 1):
            passed += 1
    return passed >= need


class _Sub:
    """The selected components of a PeriodicComponents (regressors only)."""

    def __init__(self, pc, which):
        self.pc, self.which = pc, which

    def regressors(self, q, v):
        return self.pc.regressors(q, v, which=self.which)


#: shortest time constant [s] of the energy/thermal state scanned by :func:`energy`
THERMAL_MIN_TAU_S = 30.0

#: Algorithm 6 is a fixed-point iteration "until convergence": with ``until_settled``, :func:`energy` runs further
#: passes after its ``n_iter`` ones while the friction power W = |F qd| of the latest estimate still differs from the W
#: the last pass filtered by more than ENERGY_FIXED_POINT_TOL (relative 2-norm), at most ENERGY_FIXED_POINT_MAX_PASSES
#: passes in all.  A drift that takes a large share of the Coulomb level changes the friction power that drives it, and
#: two passes leave its state short of the fixed point (fresh spec 45767: 3.7 % of W still moving).  The search's
#: candidates keep the two passes (ENERGY_FIXED_POINT_RULE off): the further passes act in about half of the kept logs
#: with a law in time, too many to screen; the hundred-and-eighth round runs them where the final model holds an abrupt
#: change beside the drift (:func:`~drake_est.diagnose.core.change_beside_drift_at_fixed_point`).
ENERGY_FIXED_POINT_RULE = False
ENERGY_FIXED_POINT_TOL = 0.01
ENERGY_FIXED_POINT_MAX_PASSES = 8


def energy(jd, r, friction_full, fit_train, n_iter=2, energy_fn=None, until_settled=None):
    """Algorithm 6 with a variable-projection search over tau_e: E = H(s) W with W = |F qd| from
    the current friction estimate, the gain k_e linear; tau_e by training error on a log grid.
    ``energy_fn(t, W, tau_e)``: E of (9.23) when it is not the plain one (several logs: E restarts at 0 at each
    log's first sample, :func:`~drake_est.diagnose.multilog.energy_fn`).  ``until_settled`` (default
    :data:`ENERGY_FIXED_POINT_RULE`): further passes until the friction power settles (Algorithm 6 "until
    convergence", :data:`ENERGY_FIXED_POINT_TOL`)."""
    energy_fn = energy_fn or unit_energy
    if until_settled is None:
        until_settled = ENERGY_FIXED_POINT_RULE
    t = jd.t
    T = float(t[-1] - t[0])
    h = float(np.median(np.diff(t)))
    # a thermal state: the lubricant and gearbox take minutes to warm (Sec. 9.2, Fig. 9.3); a "drift" with a time
    # constant of seconds is a low-pass of the recent speed, which competes with the speed laws (Stribeck) and
    # fits their misfit instead, so the scan starts at THERMAL_MIN_TAU_S
    taus = np.geomspace(min(max(THERMAL_MIN_TAU_S, 0.005 * T, 20 * h), T), 3.0 * T, 28)
    v = jd.v
    F = friction_full
    best = None
    s_used, v_used = _sgn(v)[jd.rows], v[jd.rows]
    passes, moved, first_moved = 0, None, None
    W = np.abs(F * v)
    while True:
        best = None
        for tau in taus:
            E = energy_fn(t, W, tau)
            # LPV form (9.29): k_c(E) and k_v(E), both linear in E (the Coulomb-only form (9.22) leaves the
            # viscous drift of a warming joint to be mistaken for another effect, e.g. an abrupt change)
            Eu = E[jd.rows]
            C = np.column_stack([s_used * Eu, v_used * Eu])
            err, coef = fit_train(C)
            if best is None or err < best[0]:
                best = (err, tau, C, coef, E)
        # fixed-point update of the friction power with the fitted energy term (Algorithm 6)
        F = friction_full + (best[3][0] * _sgn(v) + best[3][1] * v) * best[4]
        passes += 1
        W_next = np.abs(F * v)
        if passes >= n_iter:
            moved = float(np.linalg.norm(W_next - W) / max(float(np.linalg.norm(W)), 1e-300))
            if first_moved is None:
                first_moved = moved
            if (not until_settled or moved <= ENERGY_FIXED_POINT_TOL
                    or passes >= max(n_iter, ENERGY_FIXED_POINT_MAX_PASSES)):
                break
        W = W_next
    err, tau, C, coef, E = best
    spec = {"effect": "energy_dependent_friction", "tau_e": float(tau), "viscous": True}
    ev = {"time_constant_s": float(tau), "gain_k_e": float(coef[0]), "gain_k_e_viscous": float(coef[1]),
          "duration_s": T}
    if passes > n_iter:
        # the passes beyond the fixed number, and how far W still moved after the last one (hundred-and-eighth round)
        ev["fixed_point_passes"] = passes
        ev["fixed_point_w_moved"] = moved
    ext = Extension("energy_dependent_friction", jd.joint, {jd.joint: C}, ["k_e", "k_e_viscous"], spec, ev)
    ext.spec["_W_source"] = "current friction estimate"
    ext.obj = E
    # how far W moved after the fixed passes, whatever the switch (core.energy_fixed_point_gate; not serialized)
    ext.w_moved_after_fixed_passes = first_moved
    return ext


def change_min_length(n_train: int, min_frac: float = 0.1) -> int:
    """The shortest segment [training rows] of an abrupt change's switch: ``min_frac`` of the ``n_train`` training
    rows, at least 10 (:func:`change_point`, and every search or screen of its switches)."""
    return max(10, int(min_frac * n_train))


def extreme_speeds(v):
    """(lowest, highest) |qd| over the nonzero velocities ``v`` [rad/s], the speeds at which a friction law in time
    must still dissipate (``core.negative_friction``); None when no velocity is nonzero."""
    av = np.abs(np.asarray(v, float))
    av = av[av != 0]
    return (float(av.min()), float(av.max())) if av.size else None


def prefix_sums(a) -> np.ndarray:
    """Sums of ``a`` over its first 0, 1, ..., N rows (N + 1 of them, the first all zeros): a segment [i, k)'s sum is
    ``out[k] - out[i]``."""
    a = np.asarray(a, float)
    return np.concatenate([np.zeros((1,) + a.shape[1:]), np.cumsum(a, axis=0)])


def segment_supports(G, speeds) -> np.ndarray:
    """Support of the Coulomb + viscous law kv qd + kc sgn(qd) fitted to rows with Gram matrices ``G`` (..., 2, 2) of
    [qd, sgn(qd)]: the least over ``speeds`` [rad/s] of 1 / (x^T G^-1 x), x = [s, 1], i.e. how many samples' worth
    of information the rows give the law's value at the worst of those speeds (the reciprocal of its leverage); 0
    where G is singular.  The leverage is convex in s, so the extreme speeds of a range stand for all of it."""
    G = np.asarray(G, float)
    shape = G.shape[:-2]
    G = G.reshape(-1, 2, 2)
    X = np.array([[float(s), 1.0] for s in speeds]).T                      # (2, m)
    tr = G[:, 0, 0] + G[:, 1, 1]
    det_ = G[:, 0, 0] * G[:, 1, 1] - G[:, 0, 1] * G[:, 1, 0]
    ok = det_ > 1e-12 * np.maximum(tr, 1e-300) ** 2
    out = np.zeros(G.shape[0])
    if ok.any():
        sol = np.linalg.solve(G[ok], np.broadcast_to(X, (int(ok.sum()),) + X.shape))
        lev = np.einsum("im,nim->nm", X, sol)
        out[ok] = 1.0 / np.maximum(lev.max(axis=1), 1e-300)
    return out.reshape(shape)


def split_supports(v, speeds) -> tuple:
    """(before, after): for every split k = 0..N of the rows with velocities ``v`` (N of them), the support
    (:func:`segment_supports`) of rows [0, k) and of rows [k, N) at ``speeds``."""
    v = np.asarray(v, float)
    P = np.column_stack([v, _sgn(v)])
    cum = prefix_sums(P[:, :, None] * P[:, None, :])
    return segment_supports(cum, speeds), segment_supports(cum[-1] - cum, speeds)


def split_costs(Phi, y) -> np.ndarray:
    """Residual sum of squares of the best single switch of the regression y ~ Phi at each split k = 0..N
    ((7.8) with one change, both segments fitted by least squares; inf where a segment's Gram matrix is singular)."""
    Phi = np.asarray(Phi, float)
    y = np.asarray(y, float)
    p = Phi.shape[1]
    G = prefix_sums(Phi[:, :, None] * Phi[:, None, :])
    B = prefix_sums(Phi * y[:, None])
    yy = prefix_sums(y * y)

    def cost(Gs, Bs, ys):
        out = np.full(Gs.shape[0], np.inf)
        ok = np.abs(np.linalg.det(Gs)) > 1e-12 * np.maximum(np.trace(Gs, axis1=1, axis2=2), 1e-300) ** p
        if ok.any():
            sol = np.linalg.solve(Gs[ok], Bs[ok][:, :, None])[:, :, 0]
            out[ok] = np.maximum(ys[ok] - np.sum(Bs[ok] * sol, axis=1), 0.0)
        return out

    return cost(G, B, yy) + cost(G[-1] - G, B[-1] - B, yy[-1] - yy)


def supported_change(v, Phi, y, k, min_len, speeds, min_support=None):
    """The switch of :func:`change_point` under :data:`CHANGE_SUPPORT_RULE`: ``k`` (the search's own) when both of its
    segments (rows [0, k) and [k, N) of the velocities ``v``) support the friction law at ``speeds``
    (:func:`split_supports`, at least ``min_support``, default :data:`MIN_CHANGE_SUPPORT`), else the least-cost
    split (:func:`split_costs`) among those of segments of at least ``min_len`` rows that do; None when none does."""
    m = MIN_CHANGE_SUPPORT if min_support is None else min_support
    before, after = split_supports(v, speeds)
    ok = (before >= m) & (after >= m)
    if ok[k]:
        return int(k)
    n = len(v)
    ok[:max(int(min_len), 1)] = False
    ok[max(n - int(min_len), 0) + 1:] = False
    if not ok.any():
        return None
    c = np.where(ok, split_costs(Phi, y), np.inf)
    if not np.isfinite(c).any():
        return None
    return int(np.argmin(c))


def change_point(jd, r, min_frac=0.1, smooth_alternative=False, energy_cols=None):
    """Abrupt change of the friction parameters (Ch. 7): the best single switch of
    [qd, sign(qd)] parameters over the training samples by dynamic programming (7.8).  With
    ``smooth_alternative`` None when a smooth (quadratic in time) drift of the same parameters fits the
    training residual as well by AIC (not abrupt).  ``energy_cols``: the columns [sign(qd) E, qd E] of an accepted
    energy-dependent friction (at the used rows); the smooth alternative then also holds their second order in the
    state, [sign(qd) E^2, qd E^2] (a friction law of another shape in E than the linear (9.23), e.g. a viscous
    coefficient exponential in the temperature, leaves a misfit that follows the warm-up and looks like a step)."""
    from drake_est.errors import DrakeEstError
    from drake_est.identification.ltv import tv_regression_segments

    tr = jd.train
    rows = jd.rows
    v = jd.v[rows]
    Phi = np.column_stack([v, _sgn(v)])
    try:
        res = tv_regression_segments(Phi[tr], r[tr], 1, min_length=change_min_length(tr.sum(), min_frac))
    except DrakeEstError:
        return None
    k = res.change_times[0]
    speeds = extreme_speeds(v) if CHANGE_SUPPORT_RULE else None
    if speeds is not None:
        k = supported_change(v[tr], Phi[tr], r[tr], k, change_min_length(tr.sum(), min_frac), speeds)
        if k is None:
            return None
    # a moved switch's segments are fitted again by change_at_split
    return change_at_split(jd, r, k, res.params if k == res.change_times[0] else None, smooth_alternative,
                           energy_cols)


def joint_split_costs(X, C, y, min_len: int) -> np.ndarray:
    """Residual sum of squares of y ~ [X, C 1(row >= k)] at each split k = 0..N of the N rows (in time order), X and
    the switched columns C fitted jointly by least squares ((7.8) with one change, beside the rest of a model rather
    than on its residual); inf for the splits with a segment shorter than ``min_len`` rows or a singular system.
    With Q an orthonormal basis of X's column space, each split's cost is RSS_X - b_k^T G_k^-1 b_k, where
    G_k = C_k^T (I - Q Q^T) C_k and b_k = C_k^T (y - Q Q^T y) come from suffix sums over the rows (one SVD and a 2 x 2
    solve per split).  Q holds the left singular vectors of X above a relative tolerance, so collinear columns of X
    (which the model's fit holds apart with its ridge) do not project out directions X does not span."""
    X = np.asarray(X, float)
    C = np.asarray(C, float)
    y = np.asarray(y, float)
    n, c = C.shape
    out = np.full(n + 1, np.inf)
    lo, hi = max(int(min_len), 1), n - max(int(min_len), 1)
    if hi < lo:
        return out
    U, sv, _ = np.linalg.svd(X, full_matrices=False)
    tol = (sv[0] if sv.size else 0.0) * max(X.shape) * np.finfo(float).eps
    Q = U[:, sv > tol]
    ry = y - Q @ (Q.T @ y)
    rss_x = float(ry @ ry)

    def suffix(a):
        return np.concatenate([np.cumsum(a[::-1], axis=0)[::-1], np.zeros((1,) + a.shape[1:])])

    QC = suffix(Q[:, :, None] * C[:, None, :])                        # (n + 1, p, c): Q^T C_k
    G = suffix(C[:, :, None] * C[:, None, :]) - np.einsum("kpc,kpd->kcd", QC, QC)
    b = suffix(C * ry[:, None])
    ks = np.arange(lo, hi + 1)
    Gk, bk = G[ks], b[ks]
    tr = np.trace(Gk, axis1=1, axis2=2)
    ok = np.abs(np.linalg.det(Gk)) > 1e-12 * np.maximum(tr, 1e-300) ** c
    if ok.any():
        sol = np.linalg.solve(Gk[ok], bk[ok][:, :, None])[:, :, 0]
        out[ks[ok]] = np.maximum(rss_x - np.sum(bk[ok] * sol, axis=1), 0.0)
    return out


def change_point_beside(jd, X, r_p, min_frac=0.1, smooth_alternative=False, energy_cols=None):
    """An abrupt change of joint ``jd``'s Coulomb and viscous friction (Ch. 7) whose switch is chosen jointly with
    the rest of a model (:func:`joint_split_costs` on the training rows: the joint's measured torque ``jd.y`` on ``X``,
    the model's other columns at the used rows, and [qd, sign(qd)] after the switch) rather than on the model's
    residual, where the rest of the model, fitted without the change, has taken part of the step (loop spec 41128: a
    ripple of 64 coefficients fitted before the change holds part of it, and the change found on its residual sits at
    44.1 s beside the generator's 63.0 s).  ``r_p``: the change's partial residual at the used rows (its segments'
    parameters, evidence only).  None where no split identifies both segments (:func:`change_at_split`)."""
    tr = jd.train
    v = jd.v[jd.rows]
    C = np.column_stack([v, _sgn(v)])[tr]
    costs = joint_split_costs(np.asarray(X, float)[tr], C, jd.y[tr], change_min_length(int(tr.sum()), min_frac))
    if not np.isfinite(costs).any():
        return None
    return change_at_split(jd, r_p, int(np.argmin(costs)), None, smooth_alternative, energy_cols)


def change_at_split(jd, r, k, seg_params=None, smooth_alternative=False, energy_cols=None):
    """The abrupt-change candidate of :func:`change_point` with its switch between training rows ``k - 1`` and ``k``
    of joint ``jd`` (``r``: the residual at the used rows; ``seg_params``: the segments' [kv, kc] on it, fitted here
    when None): None when a segment does not identify [kv, kc] or, with ``smooth_alternative``, when a smooth drift
    fits the training residual as well by AIC."""
    tr = jd.train
    rows = jd.rows
    v = jd.v[rows]
    Phi = np.column_stack([v, _sgn(v)])
    if seg_params is None:
        P, y = Phi[tr], r[tr]
        seg_params = np.array([np.linalg.lstsq(P[s], y[s], rcond=None)[0] for s in (slice(0, k), slice(k, None))])
    # both segments must identify [kv, kc] (e.g. not a single velocity level after the change)
    for seg in (slice(0, k), slice(k, None)):
        P = Phi[tr][seg]
        sv = np.linalg.svd(P / np.sqrt(max(len(P), 1)), compute_uv=False)
        if sv.size < 2 or sv[-1] < 1e-3 * sv[0]:
            return None
    ttr = jd.t[rows][tr]
    tc = float(0.5 * (ttr[k - 1] + ttr[k]))
    H = (jd.t[rows] >= tc).astype(float)
    C = np.column_stack([v * H, _sgn(v) * H])
    # with ``smooth_alternative`` (an energy drift is already in the model, so its misfit is smooth in time):
    # "abrupt" must beat a smooth drift, [qd, sign(qd)] times a quadratic in time (4 parameters; the step has
    # 2 + its change time), by AIC on the training residual.  Without an accepted drift model the energy
    # candidate itself is the smooth competitor in the held-out comparison.
    if not smooth_alternative:
        spec = {"effect": "abrupt_change", "t_change": tc}
        ev = {"t_change_s": tc, "segment_params_train": seg_params.tolist()}
        return Extension("abrupt_change", jd.joint, {jd.joint: C}, ["dkv_after", "dkc_after"], spec, ev)
    tt = jd.t[rows]
    s_ = (tt - tt[0]) / max(float(np.ptp(tt)), 1e-12)
    D = np.column_stack([v * s_, _sgn(v) * s_, v * s_ ** 2, _sgn(v) * s_ ** 2])
    if energy_cols is not None:
        E = np.abs(np.asarray(energy_cols, float)[:, 0])
        E = E / max(float(E.max()), 1e-300)
        # the accepted law's own columns too: r is orthogonal to them on the training rows, and the second-order
        # part alone would have to reproduce that projection
        D = np.hstack([D, np.asarray(energy_cols, float), np.asarray(energy_cols, float) * E[:, None]])
    aic = []
    for X, k_ in ((C, 3), (D, D.shape[1])):
        A = np.hstack([Phi, X])[tr]
        e = r[tr] - A @ np.linalg.lstsq(A, r[tr], rcond=None)[0]
        aic.append(tr.sum() * np.log(max(float(e @ e), 1e-300)) + 2 * k_)
    if aic[1] <= aic[0]:
        return None
    spec = {"effect": "abrupt_change", "t_change": tc}
    ev = {"t_change_s": tc, "segment_params_train": seg_params.tolist()}
    return Extension("abrupt_change", jd.joint, {jd.joint: C}, ["dkv_after", "dkc_after"], spec, ev)


def coupling(jd, r, prep):
    """Gear coupling (9.12): the velocities (linear and sign) of the joints coupled to this one."""
    from drake_est.diagnose.nominal import coupled_joints
    others = coupled_joints(jd.joint, list(prep.joints), prep.meta.get("robot_meta"))
    if not others:
        return None
    rows = jd.rows
    cols = []
    names = []
    use = []
    for i in others:
        vi = prep.log.dq[:, prep.log.col(i)][rows]
        if np.mean(np.abs(vi) > 0.05 * np.quantile(np.abs(vi), 0.95)) < 0.2:
            continue
        cols += [vi, _sgn(vi)]
        names += [f"kv_joint{i}", f"kc_joint{i}"]
        use.append(i)
    if not use:
        return None
    spec = {"effect": "gear_coupling", "coupled_joints": use}
    return Extension("gear_coupling", jd.joint, {jd.joint: np.column_stack(cols)}, names, spec,
                     {"coupled_joints": use})


#: [N m per kg] RMS gravity torque of 1 kg at the flange on some diagnosed joint below which the payload
#: detector does not apply: a payload is seen through gravity; without gravity torque on a diagnosed joint
#: (e.g. only the vertical axis 1 moves) only its inertia would show, which the data selection (9.9)
#: (small accelerations) does not excite
PAYLOAD_MIN_GRAVITY = 0.1
#: 1 kg point masses at these offsets in the flange frame [m]: ten generic points, so that the
#: differences ID(with point mass) - ID(nominal) span the ten inertial parameters of any rigid payload
#: (mass, first moments, second moments; inverse dynamics is linear in them)
PAYLOAD_COMS = ((0.0, 0.0, 0.0), (0.1, 0.0, 0.0), (0.0, 0.1, 0.0), (0.0, 0.0, 0.1), (0.1, 0.1, 0.0),
                (0.1, 0.0, 0.1), (0.0, 0.1, 0.1), (0.2, 0.0, 0.0), (0.0, 0.2, 0.0), (0.0, 0.0, 0.2))


def payload(prep):
    """Unmodeled flange mass: torques of Drake's inverse dynamics with 1 kg at a few COM offsets
    at the flange minus the nominal, one shared coefficient each (gravity + inertia)."""
    if prep.robot is None:
        return None
    from drake_est.robots import RobotModel
    rows = prep.meta["id_rows"]
    ID0 = prep.meta["id_values"]
    regs = []
    for com in PAYLOAD_COMS:
        try:
            if prep.robot_kind == "irb140":
                m = RobotModel.irb140(payload=(1.0, com))
            else:
                m = RobotModel(prep.robot.urdf, flange_frame=prep.robot.flange.name(), payload=(1.0, com))
        except Exception:  # noqa: BLE001 - models without a usable flange: no payload detector
            return None
        if not regs:
            m_g = m
            Gs = [m_g.gravity_torques(q) - prep.robot.gravity_torques(q)
                  for q in prep.q_full[rows[:: max(1, rows.size // 200)]]]
            grav = max(float(np.sqrt(np.mean(np.array(Gs)[:, prep.robot_cols[j]] ** 2))) for j in prep.joints)
            if grav < PAYLOAD_MIN_GRAVITY:
                return None
        regs.append(m.inverse_dynamics_batch(prep.q_full[rows], prep.v_full[rows], prep.a_full[rows]) - ID0)
    pos = {int(rw): k for k, rw in enumerate(rows)}
    cols = {}
    for j, jd in prep.joints.items():
        idx = np.array([pos[int(rw)] for rw in jd.rows])
        c = prep.robot_cols[j]
        cols[j] = np.column_stack([R[idx, c] for R in regs])
    scale = {j: float(np.sqrt(np.mean(C**2))) for j, C in cols.items()}
    if max(scale.values()) < 1e-9:
        return None
    j0 = max(scale, key=scale.get)
    spec = {"effect": "payload", "coms_m": [list(c) for c in PAYLOAD_COMS]}
    return Extension("payload", j0, cols, [f"m_at_com{k}" for k in range(len(PAYLOAD_COMS))], spec,
                     {"regressor_rms_per_kg": scale})


def _rotor_of(prep):
    meta = prep.meta.get("robot_meta")
    if meta is None:
        return None
    return (meta.gear_ratios, meta.rotor_inertias)


#: Stribeck shape exponents delta tried (Sec. 9.1: 1 Tustin/exponential, 2 Gaussian)
STRIBECK_DELTAS = (1.0, 2.0)
#: a Stribeck velocity vs is identifiable when at least this fraction of the training samples move
#: slower than 2 vs (else the exponential is indistinguishable from a constant over the data)
STRIBECK_MIN_LOW = 0.05


def stribeck_speeds(v_sel, falling: bool = False):
    """Grid of Stribeck velocities vs over which the selected speeds can identify the term: from half the
    slowest selected speed to a third of the 95 % speed (log spaced); up to three times the 95 % speed when the
    friction falls with speed over the whole range (``falling``: the nominal viscous coefficient is held at
    its bound 0), where the data hold only the hump's falling flank (a Stribeck speed beyond the data: the
    friction still bends down over them, by (q95 / vs)^2 >= 1/9 of ks for a flat-topped law) and a viscous
    term cannot take it."""
    av = np.abs(v_sel)
    lo, hi = float(np.quantile(av, 0.02)), float(np.quantile(av, 0.95))
    if not (hi > 0 and lo > 0) or hi / lo < 3.0:
        return np.array([])
    top = 3.0 * hi if falling else hi / 3.0
    return np.geomspace(0.5 * lo, top, 22 if falling else 14)


def stribeck(jd, r, fit_inner, falling: bool = False):
    """Stribeck friction (Sec. 9.1, (9.4)): kc + ks exp(-|qd/vs|^delta), i.e. one extra column
    sign(qd) exp(-|qd/vs|^delta) with ks linear; vs and delta chosen by the inner split.  None when the
    selected speeds span less than a factor 3 (no low-speed data: untestable, see next_experiment).
    ``falling``: see :func:`stribeck_speeds`."""
    v = jd.v[jd.rows]
    grid = stribeck_speeds(v[jd.train], falling)
    if grid.size == 0:
        return None
    best = None
    av = np.abs(v[jd.train])
    shapes = [(vs, delta) for delta in STRIBECK_DELTAS for vs in grid if np.mean(av < 2 * vs) >= STRIBECK_MIN_LOW]

    def trial(shape):
        """Inner-split error and columns of one (vs, delta); ks >= 0: a friction excess at standstill."""
        C = jd.cached_columns(("stribeck", float(shape[0]), float(shape[1])),
                              lambda: stribeck_columns(v, {"vs": shape[0], "delta": shape[1]}, _sgn))
        return fit_inner(C, nonneg=True), C
    for (vs, delta), (err, C) in zip(shapes, pmap(trial, shapes)):      # the grid's trials at once, chosen in order
        if best is None or err < best[0]:
            best = (err, vs, delta, C)
    if best is None:
        return None
    err0, vs, delta, C = best
    # the grid is 24 % apart in vs: a large hump (ks many times the noise) fitted with a vs that far off leaves
    # a speed-shaped misfit that later candidates would be named for; refine (log vs, delta) continuously from
    # the best grid point (Nelder-Mead on the same inner-split error, vs kept inside the grid, delta in [0.5, 3])
    lo_l, hi_l = float(np.log(grid[0])), float(np.log(grid[-1]))

    def inner_err(x):
        lv, d = float(np.clip(x[0], lo_l, hi_l)), float(np.clip(x[1], 0.5, 3.0))
        return fit_inner(stribeck_columns(v, {"vs": np.exp(lv), "delta": d}, _sgn), nonneg=True)

    import scipy.optimize
    opt = scipy.optimize.minimize(inner_err, [np.log(vs), delta], method="Nelder-Mead",
                                  options={"maxiter": 60, "xatol": 1e-3, "fatol": 1e-9 * max(err0, 1e-300),
                                           "initial_simplex": [[np.log(vs), delta], [np.log(vs) + 0.1, delta],
                                                               [np.log(vs), delta + 0.25]]})
    if opt.fun < err0:
        vs, delta = float(np.exp(np.clip(opt.x[0], lo_l, hi_l))), float(np.clip(opt.x[1], 0.5, 3.0))
        C = stribeck_columns(v, {"vs": vs, "delta": delta}, _sgn)
    err_p = min(float(opt.fun), err0)
    speed_range = [float(np.min(np.abs(v))), float(np.max(np.abs(v)))]
    # a rise towards standstill of another shape (e.g. a Lorentzian ks / (1 + (qd/vs)^2), whose tail one
    # exponential cannot follow, and whose misfit a position load then takes where speed and position go together):
    # a basis expansion in |qd| (issue 16: "a basis expansion in |qd| when the shape is not Stribeck-like"), kept
    # when it beats the parametric law on the same inner split
    basis = None
    # a heavy tail reaches the faster samples: the basis speeds go up to where the slowest kernel has fallen to 5 %
    # at the 95 % speed (a third of it for exp(-|qd|/c), 1/sqrt(3) for exp(-(qd/c)^2); slower ones would be a second
    # Coulomb/viscous pair).  Two kernels: exponentials (a cusp at standstill) and Gaussians (flat at standstill, whose
    # nonnegative mixtures hold the Lorentzian ks / (1 + (qd/vs)^2) that exponentials cannot follow near zero)
    # When the friction falls over the whole selected range (``falling``) the data hold only the hump's flank and
    # the slowest kernel reaches the 95 % speed itself, as the parametric grid does.
    q95 = float(np.quantile(av, 0.95))
    tops = (("exp", q95), ("gauss", q95)) if falling else (("exp", q95 / 3.0), ("gauss", q95 / np.sqrt(3.0)))
    bases = [(kernel, np.geomspace(grid[0], max(top, grid[-1]), K)) for kernel, top in tops
             for K in STRIBECK_BASIS_SIZES]

    def basis_trial(b):
        """Inner-split error and columns of one basis (kernel, speeds)."""
        Cb = jd.cached_columns(("stribeck_basis", b[0], tuple(float(x) for x in b[1])),
                               lambda: stribeck_columns(v, {"basis_speeds": b[1], "basis_kernel": b[0]}, _sgn))
        return fit_inner(Cb, nonneg=True), Cb
    for (kernel, sp), (e, Cb) in zip(bases, pmap(basis_trial, bases)):
        if e < err_p and (basis is None or e < basis[0]):
            basis = (e, sp, Cb, kernel)
    if basis is not None:
        _, sp, Cb, kernel = basis
        spec = {"effect": "stribeck", "basis_speeds": [float(x) for x in sp], "basis_kernel": kernel}
        shape = "exponentials exp(-|qd|/c_k)" if kernel == "exp" else "Gaussians exp(-(qd/c_k)^2)"
        ev = {"shape": f"basis of {sp.size} {shape} in |qd|", "basis_speeds": spec["basis_speeds"],
              "basis_kernel": kernel, "inner_error_parametric": err_p, "inner_error_basis": float(basis[0]),
              "speed_range_selected": speed_range}
        return Extension("stribeck", jd.joint, {jd.joint: Cb}, [f"ks_{k}" for k in range(sp.size)], spec, ev)
    spec = {"effect": "stribeck", "vs": float(vs), "delta": float(delta)}
    ev = {"stribeck_velocity": float(vs), "shape_exponent": float(delta), "speed_range_selected": speed_range}
    return Extension("stribeck", jd.joint, {jd.joint: C}, ["ks"], spec, ev)


#: sizes of the Stribeck basis expansion in |qd| tried against the parametric law (:func:`stribeck`)
STRIBECK_BASIS_SIZES = (2, 3, 4, 5, 6)


def stribeck_ks_vs(spec, coef):
    """(ks, vs) of a fitted Stribeck extension: the friction excess at standstill and the speed where it has
    fallen to ks / e (for the parametric law exp(-|qd/vs|^delta) that is its vs; None if it never falls so far
    within ten times the largest basis speed)."""
    if not spec.get("basis_speeds"):
        return float(np.atleast_1d(coef)[0]), float(spec["vs"])
    vv = np.linspace(0.0, 10.0 * float(max(spec["basis_speeds"])), 4001)
    g = stribeck_curve(spec, coef, vv)
    ks = float(g[0])
    below = np.flatnonzero(np.abs(g) <= abs(ks) / np.e)
    return ks, (float(vv[below[0]]) if below.size else None)


def stribeck_curve(spec, coef, speeds):
    """The fitted friction excess [torque] at the (nonnegative) ``speeds`` of a Stribeck extension."""
    return stribeck_columns(np.abs(np.asarray(speeds, float)), spec, np.ones_like) @ np.atleast_1d(coef)


#: a line of the motion's own spectrum (qd(t) or |qd|(t)) counts when its amplitude is at least this share of the
#: strongest line (:func:`motion_lines_hz`)
MOTION_LINE_SHARE = 0.25


#: ... and its position swing at that frequency at least this share of the position range
MOTION_LINE_SWING = 0.01


def motion_lines_hz(jd, share: float = MOTION_LINE_SHARE, swing: float = MOTION_LINE_SWING) -> np.ndarray:
    """Frequencies [Hz] of the strong lines of the motion itself: local maxima of the amplitude spectrum of qd(t)
    and of |qd|(t) (whole log, Hann window) with at least ``share`` of the strongest one's amplitude, where the
    position also swings by at least ``swing`` of its range (a least-squares sinusoid of q at that frequency).
    Every state-dependent misfit g(q, qd) of the model repeats with the motion, so a residual periodic at one of
    these frequencies cannot be told from such a misfit: it is no evidence of a disturbance from outside the axis.
    (A disturbance the servo does not fully reject moves the axis at its own frequency too, but only by a small
    position swing: that line is not the motion's.)  Kept in ``jd.motion_lines`` where ``jd`` has that cache (a
    :class:`~drake_est.diagnose.nominal.JointData`), with the t, q, v objects they came from."""
    cache = getattr(jd, "motion_lines", None)
    key = (float(share), float(swing))
    src = (jd.t, getattr(jd, "q", None), jd.v)
    if cache is not None and key in cache and all(x is y for x, y in zip(cache[key][0], src)):
        return cache[key][1].copy()
    lines = _motion_lines_hz(jd, share, swing)
    if cache is not None:
        cache[key] = (src, lines.copy())
    return lines


def _motion_lines_hz(jd, share, swing) -> np.ndarray:
    """The lines of :func:`motion_lines_hz`, computed."""
    v = np.asarray(jd.v, float)
    if v.size < 16:
        return np.array([])
    t = np.asarray(jd.t, float)
    q = np.asarray(jd.q, float) if getattr(jd, "q", None) is not None else None
    h = float(np.median(np.diff(t)))
    F = np.fft.rfftfreq(v.size, h)
    w = np.hanning(v.size)
    cand = []
    for x in (v - v.mean(), np.abs(v) - np.abs(v).mean()):
        A = np.abs(np.fft.rfft(x * w))
        A[0] = 0.0
        top = float(A.max())
        if top <= 0:
            continue
        pk = np.flatnonzero((A[1:-1] >= A[:-2]) & (A[1:-1] >= A[2:]) & (A[1:-1] >= share * top)) + 1
        cand += F[pk].tolist()
    out = []
    span = float(np.ptp(q)) if q is not None else 0.0
    for f in np.unique(np.asarray(cand, float)):
        if q is not None and span > 0:
            wt = 2 * np.pi * f * t
            B = np.column_stack([np.ones_like(t), t - t.mean(), np.cos(wt), np.sin(wt)])
            c = np.linalg.lstsq(B, q, rcond=None)[0]
            if np.hypot(c[2], c[3]) < swing * span:
                continue
        out.append(f)
    return np.asarray(out, float)


#: a harmonic 2f or 3f of a time-periodic disturbance joins it when a partial F-test of its cos/sin pair on the
#: training residual gives a p-value below this
HARMONIC_P = 1e-6


def _tp_basis(t, freqs):
    """[1, cos 2 pi f_k t ..., sin 2 pi f_k t ...] (columns of a time-periodic disturbance beside an offset)."""
    W = 2 * np.pi * np.outer(t, np.asarray(freqs, float))
    return np.hstack([np.ones((t.size, 1)), np.cos(W), np.sin(W)])


def _tp_columns(t, freqs):
    """The columns [cos 2 pi f_k t ..., sin 2 pi f_k t ...] of a time-periodic disturbance at times ``t``."""
    W = 2 * np.pi * np.outer(t, np.asarray(freqs, float))
    return np.hstack([np.cos(W), np.sin(W)])


def _tp_names(n):
    """Coefficient names of :func:`_tp_columns` for ``n`` frequencies (``a_cos``, ``a_sin`` for one)."""
    return [f"a_cos_{i + 1}" for i in range(n)] + [f"a_sin_{i + 1}" for i in range(n)] if n > 1 else ["a_cos", "a_sin"]


def motion_line_band_hz(jd) -> float:
    """Half-width [Hz] of the band around each line of the motion (:func:`motion_lines_hz`) that counts as that line:
    two resolution bins of the whole log, 2 / T."""
    return 2.0 / max(float(np.ptp(jd.t)), 1e-12)


def _tp_basis_beside(tt, freqs, X=None):
    """:func:`_tp_basis` with other columns ``X`` (rows of ``tt``) before it (None: the basis alone)."""
    B = _tp_basis(tt, freqs)
    return B if X is None else np.hstack([X, B])


def _harmonics(tt, rt, f, freqs, h, skip=(), X=None):
    """``freqs`` (which hold the fundamental ``f`` [Hz]) with each harmonic 2f, 3f below 0.45 / h [Hz] added that
    lowers the residual ``rt`` at times ``tt`` by a partial F-test at p < :data:`HARMONIC_P`; harmonics within
    ``skip``'s frequency bands ((lo, hi) pairs) are not tried.  ``X``: other columns (rows of ``tt``) fitted beside
    the disturbance in every test (None: the offset only)."""
    import scipy.stats
    freqs = list(freqs)
    B = _tp_basis_beside(tt, freqs, X)
    e_cur = rt - B @ np.linalg.lstsq(B, rt, rcond=None)[0]
    for k in (2, 3):
        fk = k * f
        if fk >= 0.45 / h:
            break
        if any(abs(fk - x) <= 1e-9 * f for x in freqs) or any(lo <= fk <= hi for lo, hi in skip):
            continue
        Bk = _tp_basis_beside(tt, freqs + [fk], X)
        ek = rt - Bk @ np.linalg.lstsq(Bk, rt, rcond=None)[0]
        rss0, rss1 = float(e_cur @ e_cur), float(ek @ ek)
        dof = max(tt.size - Bk.shape[1], 1)
        F = ((rss0 - rss1) / 2.0) / max(rss1 / dof, 1e-300)
        if F > 0 and scipy.stats.f.sf(F, 2, dof) < HARMONIC_P:
            freqs.append(fk)
            e_cur = ek
    return freqs


def time_periodic_refit(jd, r_p, ext, X=None, key: str = "refitted_from_frequency_hz", skip_motion_lines=True):
    """A time-periodic disturbance ``ext`` estimated again on its *partial* residual ``r_p`` (the current residual
    plus its own part) once later findings are in the model: when it was accepted, a larger unmodeled effect (a
    position friction, say) dominated the residual, which biased its frequency and hid its harmonics, and a
    harmonic left out is later taken for another effect.  The fundamental f is refined by a bounded scalar
    search over f +- 1 / (4 T) (T: training span; the harmonic orders kept), then the harmonics 2f, 3f are chosen
    again from none, as in :func:`time_periodic` (those at the motion's own lines, :func:`motion_lines_hz`, are not
    tried: there a state-dependent misfit repeats with the motion): one taken on the dominated residual, where its
    test sat at the threshold, goes when the partial residual does not hold it (loop spec 471: 3f at p = 9.8e-7
    beside a position friction, none once the friction is in).  Returns the new Extension (its evidence holds the
    old frequency under ``key``), or None when nothing moved.

    ``X``: the joint's other columns (rows of ``jd``; the model without ``ext``), fitted beside the disturbance at
    every trial frequency and in every harmonic's test (variable projection), for a disturbance at a line of the motion
    (:func:`time_periodic_at_motion_line`): there the model's own columns (sign qd, qd) take part of a slow
    disturbance, and the frequency that fits the residual alone is off (0.0602 Hz for 0.06 Hz in a 120 s log, where
    the full model's optimum is 0.05999 Hz); the phase misfit that leaves grows along the log and a position
    friction is named for it.  ``skip_motion_lines``: False tries harmonics at the motion's lines too (as
    :func:`time_periodic_at_motion_line`'s own candidate does)."""
    import scipy.optimize
    tr = jd.train
    t = jd.t[jd.rows]
    tt, rt = t[tr], np.asarray(r_p, float)[tr]
    T = float(np.ptp(tt))
    fr = [float(x) for x in ext.spec["frequencies_hz"]]
    if T <= 0 or tt.size < 50 or not fr:
        return None
    f0 = fr[0]
    orders = [x / f0 for x in fr]
    h = float(np.median(np.diff(jd.t)))
    Xt = None if X is None else np.asarray(X, float)[tr]

    def rss(f):
        B = _tp_basis_beside(tt, [o * f for o in orders], Xt)
        e = rt - B @ np.linalg.lstsq(B, rt, rcond=None)[0]
        return float(e @ e)

    half = 0.25 / T
    res = scipy.optimize.minimize_scalar(rss, bounds=(max(f0 - half, 0.5 * f0), f0 + half), method="bounded",
                                         options={"xatol": 1e-4 / T})
    f = float(res.x) if res.success and rss(float(res.x)) < rss(f0) else f0
    band = motion_line_band_hz(jd)
    skip = [(fl - band, fl + band) for fl in (motion_lines_hz(jd) if skip_motion_lines else ())]
    freqs = _harmonics(tt, rt, f, [f], h, skip, X=Xt)
    same_orders = sorted(round(x / f) for x in freqs) == sorted(round(o) for o in orders)
    if same_orders and abs(f - f0) <= 1e-3 / T:
        return None
    C, names = _tp_columns(t, freqs), _tp_names(len(freqs))
    spec = {**ext.spec, "frequencies_hz": freqs}
    ev = {**ext.evidence, "frequency_hz": f, "harmonics_hz": freqs[1:], key: f0}
    return Extension("time_periodic_disturbance", jd.joint, {jd.joint: C}, names, spec, ev)


def time_periodic_at_motion_line(jd, r, min_periods: float = 4.0):
    """The time-periodic candidate at the strongest frequency of the whole scan when that frequency lies at a line
    of the motion (within two resolution bins, :func:`motion_lines_hz`), which :func:`time_periodic` does not scan;
    None when the whole scan's peak is elsewhere (then it is :func:`time_periodic`'s own candidate).  A disturbance
    slower than a few tenths of a hertz lies at such a line whenever the moves are point to point (their lines are
    dense there): skipped, it was never a candidate, and a position law took its place (a 0.04 Hz disturbance in a
    120 s loop log).  At a line a state-dependent misfit looks periodic in time too, so the search offers this
    candidate only where the nominal residual shows one (:func:`~drake_est.diagnose.core.motion_line_gate`) and holds
    it against a free function of the state and its reversals
    (:func:`~drake_est.diagnose.competition.survives_state_law`) and across the halves of the log
    (:func:`~drake_est.diagnose.competition.holds_across_halves`).  Its evidence carries ``at_motion_line_hz``, the
    line."""
    e = time_periodic(jd, r, skip_motion_lines=False, min_periods=min_periods)
    if e is None:
        return None
    f = float(e.evidence["frequency_hz"])
    lines = motion_lines_hz(jd)
    near = lines[np.abs(lines - f) <= motion_line_band_hz(jd)] if lines.size else lines
    if near.size == 0:
        return None
    e.evidence["at_motion_line_hz"] = float(near[np.argmin(np.abs(near - f))])
    return e


def time_periodic(jd, r, n_components=1, skip_motion_lines=True, min_periods: float = 4.0):
    """A torque periodic in *time* (pump, fan, neighbouring machine): the least-squares periodogram of
    the training residual over time (the spectral tools of Ch. 10 with time as the sampling location,
    :func:`~drake_est.spectral.detect.fft_scan`), beyond [sign(qd), qd]; the strongest frequency f [Hz]
    gives columns cos, sin(2 pi f t).  Unlike the motor ripple its frequency does not scale with speed,
    so on logs with several speeds the two are told apart by the held-out comparison.  ``skip_motion_lines``:
    frequencies of the motion's own strong lines are not scanned (:func:`motion_lines_hz`; off where any
    periodic structure is wanted, e.g. the periodic nuisance of :mod:`~drake_est.diagnose.competition`).
    ``min_periods``: the lowest frequency scanned, in periods of the training span (4 for the disturbance itself)."""
    from drake_est.errors import DrakeEstError
    from drake_est.spectral.detect import fft_scan

    tr = jd.train
    t = jd.t[jd.rows]
    v = jd.v[jd.rows]
    tt, rt = t[tr], r[tr]
    T = float(np.ptp(tt))
    if T <= 0 or tt.size < 50:
        return None
    from drake_est.spectral.detect import BINS_PER_PERIOD
    h = float(np.median(np.diff(jd.t)))
    max_fft = 1 << 20
    f_max = min(0.45 / h, 0.98 * max_fft / (4.0 * T * BINS_PER_PERIOD))
    try:
        freqs, ess = fft_scan(tt, rt, Phi=np.column_stack([np.ones_like(tt)]), f_max=f_max,
                              f_min=float(min_periods) / T, max_fft=max_fft)
    except DrakeEstError:
        return None
    if freqs.size == 0:
        return None
    # frequencies of the motion's own strong lines (within two resolution bins, 1 / T) are not scanned: there a
    # state-dependent misfit repeats with the motion and looks periodic in time (motion_lines_hz)
    ess = np.asarray(ess, float).copy()
    band = motion_line_band_hz(jd)
    for fl in (motion_lines_hz(jd) if skip_motion_lines else ()):
        ess[np.abs(freqs - fl) <= band] = -np.inf
    if not np.isfinite(ess).any():
        return None
    f = float(freqs[int(np.argmax(ess))])
    # refine the frequency off the scan grid (least squares over a fine local grid, +- one grid step)
    df = float(freqs[1] - freqs[0]) if freqs.size > 1 else 0.0
    if df > 0:
        best = None
        for fc in f + df * np.linspace(-1, 1, 41):
            wc = 2 * np.pi * fc * tt
            B = np.column_stack([np.ones_like(tt), np.cos(wc), np.sin(wc)])
            e = rt - B @ np.linalg.lstsq(B, rt, rcond=None)[0]
            if best is None or e @ e < best[0]:
                best = (float(e @ e), float(fc))
        f = best[1]
    w = 2 * np.pi * f * t
    C = np.column_stack([np.cos(w), np.sin(w)])
    # a disturbance from outside the axis does not know the axis' speed: it must be present at (nearly) every
    # speed; a motion-locked error that a sinusoid in time happens to fit shows at some speeds only
    if not present_at_all_speeds(C[tr], v[tr], rt):
        return None
    B = np.column_stack([np.ones_like(tt), C[tr]])
    c = np.linalg.lstsq(B, rt, rcond=None)[0]
    amp = float(np.hypot(c[1], c[2]))
    # a pump or a fan is rarely a pure sinusoid: its harmonics 2f, 3f (below Nyquist) join the candidate when
    # each lowers the training residual by a partial F-test at p < HARMONIC_P; left out, a harmonic stays in the
    # residual and is later taken for another effect
    freqs_h = _harmonics(tt, rt, f, [f], h)
    if len(freqs_h) > 1:
        C = _tp_columns(t, freqs_h)
    spec = {"effect": "time_periodic_disturbance", "frequencies_hz": freqs_h}
    ev = {"frequency_hz": f, "amplitude_train": amp, "harmonics_hz": freqs_h[1:],
          "speed_levels_rad_s": [float(x) for x in np.quantile(np.abs(v), [0.1, 0.5, 0.9])]}
    return Extension("time_periodic_disturbance", jd.joint, {jd.joint: C}, _tp_names(len(freqs_h)), spec, ev)
