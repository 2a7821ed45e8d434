"""The diagnosis' model extensions as friction terms (thesis Ch. 9-10, issue #18: one friction model).

The detectors of :mod:`drake_est.diagnose.detectors` choose the nonlinear structure of an effect
(kernel centres, ripple frequencies, energy time constant, change time) and describe it by a
JSON-able *spec*; :func:`columns_at` evaluates its regressor columns, which are linear in the
parameters.  :class:`ExtensionTerm` wraps a spec as a :class:`~.terms.Term`, so a diagnosed model
is an ordinary :class:`~.model.JointFriction` (nominal :class:`~.terms.Viscous` +
:class:`~.terms.Coulomb` plus extension terms), saved with ``to_dict`` and simulated by the same
:class:`drake_est.systems.friction.FrictionModel` as ``fit-friction``'s models.

==============================  ==============================================  ============
effect (:mod:`drake_est.effects`)  columns                                      thesis
==============================  ==============================================  ============
position_dependent_friction     sign(qd) phi_k(q), Gaussian kernels in arm q    (9.13)-(9.16)
position_dependent_load         phi_k(q)                                         (added name)
motor_position_ripple           LPV periodic components in q, amplitude(qd)     Ch. 10, (10.5)
energy_dependent_friction       sign(qd) E, E = 1/(tau_e s + 1) |F qd|           (9.21)-(9.24)
asymmetric_coulomb              1[qd < 0]                                         (9.3)
gear_coupling                   qd_i, sign(qd_i) of the coupled joints i         (9.12)
abrupt_change                   [qd, sign(qd)] 1[t >= t_c]                        Ch. 7, (7.8)
==============================  ==============================================  ============

Extensions were identified on moving samples only (|qd| > v_min, (9.9)); an :class:`ExtensionTerm`
with ``v_min`` fades its columns by |tanh(qd / v_min)| towards standstill instead of extrapolating
there, and a ripple term evaluates its speed-dependent amplitude at qd clipped to ``v_range``.
"""
from __future__ import annotations

import numpy as np
import scipy.signal

from drake_est.errors import DataError, DrakeEstError
from drake_est.identification.friction.terms import Term, _sign
from drake_est.identification.friction.terms import term_from_dict as _basic_term_from_dict


def gaussian_features(q, centers, width):
    """Gaussian kernels exp(-(q - c_k)^2 / (2 w^2)) (N, K) (the basis of (9.13))."""
    return np.exp(-0.5 * ((np.asarray(q, float)[:, None] - centers[None, :]) / width) ** 2)


def unit_energy(t, W, tau_e):
    """E with unit static gain: dE/dt = (W - E) / tau_e, zero-order hold, E(0) = 0 (9.23)."""
    h = float(np.median(np.diff(t)))
    a = float(np.exp(-h / tau_e))
    return scipy.signal.lfilter([0.0, 1.0 - a], [1.0, -a], W)


class RippleRegressors:
    """Regressors of selected LPV periodic components (Ch. 10) from JSON-able numbers: frequencies
    [cycles/rad] and the schedule basis over the velocity; the same columns as
    :meth:`drake_est.spectral.detect.PeriodicComponents.regressors`."""

    def __init__(self, freqs, basis: dict):
        from drake_est.spectral.basis import ScheduleBasis
        self.freqs = np.asarray(freqs, float)
        self.basis_spec = dict(basis)
        self.basis = ScheduleBasis(**self.basis_spec)

    @classmethod
    def from_components(cls, pc, which):
        b = pc.basis
        return cls(pc.freqs[list(which)], {"n_basis": b.n_basis, "lo": b.lo, "hi": b.hi,
                                            "sign_split": b.sign_split, "width_factor": b.width_factor})

    def regressors(self, q, v):
        from drake_est.spectral.lpv import LPVSpectrum
        q = np.asarray(q, float).ravel()
        Phi = np.ones((q.size, 1)) if self.basis.n_basis == 1 else self.basis(np.asarray(v, float).ravel())
        arg = np.outer(q, 2 * np.pi * self.freqs)
        return LPVSpectrum._design_rows(Phi, np.cos(arg), np.sin(arg), None)


def stribeck_columns(v, spec, sign=np.sign) -> np.ndarray:
    """The Stribeck term's columns (Sec. 9.1, (9.4)) at velocities ``v``: the parametric law
    sign(qd) exp(-|qd/vs|^delta) (``spec`` with ``vs``, ``delta``; ks linear), or the basis expansion in |qd|
    sign(qd) exp(-|qd| / c_k) for the basis speeds c_k (``spec["basis_speeds"]``; with nonnegative coefficients a
    friction excess that falls with speed from standstill, of any completely monotone shape, as a mixture of
    exponentials), or with ``spec["basis_kernel"] == "gauss"`` the Gaussian kernels sign(qd) exp(-(qd / c_k)^2)
    (a nonnegative mixture of these is any excess completely monotone in qd^2: flat at standstill, e.g. the
    Lorentzian ks / (1 + (qd/vs)^2) = int exp(-s) exp(-s (qd/vs)^2) ds, which no mixture of exponentials follows).  ``sign``: the sign function (a smoothed one for integrators; ``np.ones_like`` gives the
    curve over speeds)."""
    v = np.atleast_1d(np.asarray(v, float))
    s = sign(v)
    if spec.get("basis_speeds") is not None and len(spec["basis_speeds"]):
        x = np.abs(v)[:, None] / np.asarray(spec["basis_speeds"], float)[None, :]
        return s[:, None] * np.exp(-(x * x if spec.get("basis_kernel") == "gauss" else x))
    return (s * np.exp(-np.abs(v / spec["vs"]) ** spec["delta"]))[:, None]


def columns_at(spec, q, v, t, others=None, E_unit=None, sign=None):
    """Columns of an extension at arbitrary samples (arrays (N,) of the joint; ``others``:
    {joint: velocity (N,)} for gear coupling; ``E_unit``: the unit-gain energy state; ``sign``: the
    sign function (a smoothed one for integrators))."""
    kind = spec["effect"]
    sgn = sign or np.sign
    q, v, t = (np.atleast_1d(np.asarray(a, float)) for a in (q, v, t))
    s = sgn(v)
    if kind == "asymmetric_coulomb":
        return (v < 0).astype(float)[:, None]
    if kind == "position_dependent_friction":
        return s[:, None] * gaussian_features(q, np.asarray(spec["centers"]), spec["width"])
    if kind == "position_dependent_load":
        G = gaussian_features(q, np.asarray(spec["centers"]), spec["width"])
        return np.hstack([np.column_stack([np.sin(q), np.cos(q)]), G]) if spec.get("gravity_harmonic") else G
    if kind == "stribeck":
        return stribeck_columns(v, spec, sgn)
    if kind == "time_periodic_disturbance":
        w = 2 * np.pi * np.outer(t, np.asarray(spec["frequencies_hz"], float))
        return np.hstack([np.cos(w), np.sin(w)])
    if kind == "abrupt_change":
        H = (t >= spec["t_change"]).astype(float)
        return np.column_stack([v * H, s * H])
    if kind == "gear_coupling":
        return np.column_stack([c for i in spec["coupled_joints"] for c in (others[i], sgn(others[i]))])
    if kind == "energy_dependent_friction":
        E = np.asarray(E_unit, float)
        if spec.get("viscous"):       # (9.29): the energy changes the viscous as well as the Coulomb level
            return np.column_stack([s * E, v * E])
        return (s * E)[:, None]
    if kind == "motor_position_ripple":
        ev = spec.get("_pc")
        if ev is None:
            ev = RippleRegressors(spec["frequencies_per_arm_rad"], spec["schedule_basis"])
        return ev.regressors(q, v)
    raise DrakeEstError(f"no column evaluator for effect '{kind}'")


def ripple_regressors(spec: dict) -> "RippleRegressors":
    """The :class:`RippleRegressors` of a ripple's spec: its ``_pc``, the detector's selected components (an object
    with ``pc`` and ``which``) or already a :class:`RippleRegressors`."""
    ev = spec["_pc"]
    return RippleRegressors.from_components(ev.pc, ev.which) if hasattr(ev, "pc") else ev


def _public_spec(spec: dict) -> dict:
    """The JSON-able part of a spec (objects under keys starting with '_' dropped, ripple made serializable)."""
    out = {k: v for k, v in spec.items() if not k.startswith("_")}
    if spec.get("effect") == "motor_position_ripple" and "schedule_basis" not in out:
        rr = ripple_regressors(spec)
        out["frequencies_per_arm_rad"] = [float(f) for f in rr.freqs]
        out["schedule_basis"] = rr.basis_spec
    return out


class ExtensionTerm(Term):
    """A diagnosed effect as a friction term: the columns of :func:`columns_at` for ``spec``.

    ``v_min`` [rad/s]: fade the columns by |tanh(qd / v_min)| (None: no fade); ``v_range`` [rad/s]:
    the ripple's amplitude is evaluated at qd clipped to this range; ``coupled_indices``: the data
    columns (0-based indices) holding the velocities of ``spec["coupled_joints"]`` (gear coupling).
    The energy effect reads the unit-gain energy E (``needs_energy``); the abrupt change reads time
    (``needs_time``)."""

    kind = "extension"

    def __init__(self, spec: dict, v_min: float | None = None, v_range=None, coupled_indices=None):
        if spec.get("effect") is None:
            raise DataError("extension spec has no 'effect'")
        self.spec = _public_spec(spec)
        self._evaluator = None
        if self.effect == "motor_position_ripple":
            self._evaluator = RippleRegressors(self.spec["frequencies_per_arm_rad"], self.spec["schedule_basis"])
        self.v_min = None if v_min is None else float(v_min)
        self.v_range = None if v_range is None else (float(v_range[0]), float(v_range[1]))
        self.coupled_indices = None if coupled_indices is None else [int(i) for i in coupled_indices]
        if self.effect == "gear_coupling" and (self.coupled_indices is None
                                               or len(self.coupled_indices) != len(self.spec["coupled_joints"])):
            raise DataError("gear_coupling term needs one coupled index per coupled joint")
        self._n = None

    @property
    def effect(self) -> str:
        return self.spec["effect"]

    @property
    def needs_energy(self) -> bool:
        return self.effect == "energy_dependent_friction"

    @property
    def needs_time(self) -> bool:
        return self.effect in ("abrupt_change", "time_periodic_disturbance")

    def columns(self, Q, DQ, j, E=None, sign_eps=0.0, t=None):
        q, v = Q[:, j], DQ[:, j]
        if self.needs_time and t is None:
            raise DataError(f"the {self.effect} term needs the time t")
        if self.needs_energy and E is None:
            raise DataError(f"the {self.effect} term needs the energy signal E")
        tt = np.zeros(q.size) if t is None else np.broadcast_to(np.asarray(t, float), q.shape)
        vv = np.clip(v, *self.v_range) if (self.v_range is not None and self.effect == "motor_position_ripple") else v
        others = None
        if self.effect == "gear_coupling":
            others = {jn: DQ[:, i] for jn, i in zip(self.spec["coupled_joints"], self.coupled_indices)}
        spec = self.spec if self._evaluator is None else {**self.spec, "_pc": self._evaluator}
        C = columns_at(spec, q, vv, tt, others, E, sign=lambda x: _sign(x, sign_eps))
        if self.v_min is not None:
            C = C * np.abs(np.tanh(v / self.v_min))[:, None]
        self._n = C.shape[1]
        return C

    def names(self):
        n = {"asymmetric_coulomb": 1, "energy_dependent_friction": 2 if self.spec.get("viscous") else 1,
             "abrupt_change": 2, "stribeck": len(self.spec.get("basis_speeds") or [0]),
             "time_periodic_disturbance": 2 * len(self.spec.get("frequencies_hz", [0]))}.get(self.effect)
        if n is None:
            if self.effect in ("position_dependent_friction", "position_dependent_load"):
                n = len(self.spec["centers"]) + (2 if self.spec.get("gravity_harmonic") else 0)
            elif self.effect == "gear_coupling":
                n = 2 * len(self.spec["coupled_joints"])
            elif self.effect == "motor_position_ripple":
                n = 2 * len(self._evaluator.freqs) * self._evaluator.basis.n_basis
        return [f"{self.effect}_{k}" for k in range(n)]

    def to_dict(self):
        return {"kind": self.kind, "spec": self.spec, "v_min": self.v_min,
                "v_range": None if self.v_range is None else list(self.v_range),
                "coupled_indices": self.coupled_indices}

    @classmethod
    def from_dict(cls, d):
        return cls(d["spec"], d.get("v_min"), d.get("v_range"), d.get("coupled_indices"))


def term_from_dict(d: dict) -> Term:
    """Any friction term from its ``to_dict`` (the basic terms and :class:`ExtensionTerm`)."""
    if d.get("kind") == ExtensionTerm.kind:
        return ExtensionTerm.from_dict(d)
    return _basic_term_from_dict(d)
