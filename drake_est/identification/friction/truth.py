"""The *true* joint friction of the synthetic logs (:mod:`drake_est.synth`), with the hidden effects
of the one effect list (:mod:`drake_est.effects`); its Drake system is
:class:`drake_est.systems.friction.TrueJointFriction` (same ports as ``FrictionModel``)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_est.effects import EFFECTS


@dataclass
class FrictionTruth:
    """True joint friction of all n joints (arm side), with optional hidden effects.

    Nominal part: F = kv v + kc sign(v) (9.2), kc_pos / kc_neg when asymmetric (9.3).
    Effect parameters are dicts keyed by 0-based joint index."""

    kc: np.ndarray
    kv: np.ndarray
    kc_neg: np.ndarray | None = None          # asymmetric Coulomb: level for v < 0
    bumps: dict | None = None                 # j -> (centers, widths, amplitudes)       position dependence
    ripple: dict | None = None                # j -> (gear, harmonic, a0, v_half, phase) motor ripple
    energy: dict | None = None                # j -> (k_e, tau_e)                         energy dependence
    coupling: dict | None = None              # j -> list of (i, kc_i, kv_i)               gear coupling (9.12)
    change: dict | None = None                # j -> (t_change, kc_after, kv_after)        abrupt change
    v_eps: float = 2e-3                       # smoothing of sign() near v = 0 [rad/s]
    active: np.ndarray | None = None          # joints with friction (held joints: None = all)

    def coulomb_level(self, j: int, q: float, v: float, t: float, E: float = 0.0) -> float:
        kc = self.kc[j]
        if self.kc_neg is not None and v < 0:
            kc = self.kc_neg[j]
        if self.change and j in self.change and t >= self.change[j][0]:
            kc = self.change[j][1] * (1.0 if (self.kc_neg is None or v >= 0) else self.kc_neg[j] / self.kc[j])
        level = kc
        if self.bumps and j in self.bumps:
            c, w, a = self.bumps[j]
            level += float(np.sum(a * np.exp(-0.5 * ((q - c) / w) ** 2)))
        return level + E

    def joint_model(self, j: int):
        """Joint ``j``'s (0-based) true friction as a :class:`~.model.JointFriction` of the package's terms
        (evaluate with ``sign_eps = v_eps``): viscous (9.2) and Coulomb (9.1) or direction-dependent
        Coulomb (9.3), each split before/after an abrupt change (:class:`~.terms.TimeSwitched`);
        sign(v) phi_k(q) Gaussian bumps (9.13) and sign(v) E (9.22) as :class:`~.extensions.ExtensionTerm`;
        speed-attenuated motor ripple (:class:`~.terms.SpeedAttenuatedRipple`); gear coupling (9.12) as
        :class:`~.terms.CoupledJoint`. None for a held joint."""
        from drake_est.identification.friction.extensions import ExtensionTerm
        from drake_est.identification.friction.model import JointFriction
        from drake_est.identification.friction.terms import (AsymmetricCoulomb, Coulomb, CoupledJoint,
                                                              SpeedAttenuatedRipple, TimeSwitched, Viscous)
        if self.active is not None and not self.active[j]:
            return None
        asym = self.kc_neg is not None
        coulomb = AsymmetricCoulomb if asym else Coulomb
        kc = [self.kc[j], self.kc_neg[j]] if asym else [self.kc[j]]
        terms, coef = [], []
        if self.change and j in self.change:
            tc, kc_after, kv_after = self.change[j]
            kc_after = [kc_after, kc_after * (self.kc_neg[j] / self.kc[j])] if asym else [kc_after]
            terms += [TimeSwitched(Viscous(), tc, after=False), TimeSwitched(Viscous(), tc),
                      TimeSwitched(coulomb(), tc, after=False), TimeSwitched(coulomb(), tc)]
            coef += [self.kv[j], kv_after, *kc, *kc_after]
        else:
            terms += [Viscous(), coulomb()]
            coef += [self.kv[j], *kc]
        if self.bumps and j in self.bumps:
            c, w, amp = self.bumps[j]
            terms.append(ExtensionTerm({"effect": "position_dependent_friction", "centers": np.asarray(c).tolist(),
                                        "width": np.asarray(w).tolist()}))
            coef += list(np.asarray(amp, float))
        if self.energy and j in self.energy:
            terms.append(ExtensionTerm({"effect": "energy_dependent_friction"}))
            coef.append(1.0)
        if self.ripple and j in self.ripple:
            g, h, a0, vh, ph = self.ripple[j]
            terms.append(SpeedAttenuatedRipple(g, h, vh, ph))
            coef.append(a0)
        if self.coupling and j in self.coupling:
            for i, kci, kvi in self.coupling[j]:
                terms.append(CoupledJoint(i))
                coef += [kci, kvi]
        m = JointFriction(terms, index=j, lam=0.0, energy_additive=False)
        m.coef = np.asarray(coef, float)
        return m

    def torque(self, q, v, t, E=None) -> np.ndarray:
        """Friction torques (n,) [N m] opposing the motion (tau_motor = ID + F): the regressor columns of
        :meth:`joint_model` (sign(v) smoothed to tanh(v / v_eps)) times its coefficients, summed term by
        term in order (the synthetic logs' integration is sensitive to the last bit of F: a BLAS dot
        product over all columns changed the gear-coupling log by 1e-2 N m)."""
        n = len(self.kc)
        Q = np.asarray(q, float).reshape(1, -1)
        V = np.asarray(v, float).reshape(1, -1)
        E = np.zeros(n) if E is None else np.asarray(E, float)
        tt = np.array([float(t)])
        F = np.zeros(n)
        for j in range(n):
            m = self.joint_model(j)
            if m is None:
                continue
            A, _ = m.regressors(Q, V, E[j:j + 1] if m.needs_energy else None, sign_eps=self.v_eps, t=tt)
            f, k = 0.0, 0
            for term in m.terms:
                w = len(term.names())
                block = 0.0
                for c in range(k, k + w):
                    block += A[0, c] * m.coef[c]
                f += block
                k += w
            F[j] = f
        return F

    def energy_rate(self, F, v, E) -> np.ndarray:
        """dE/dt for each joint: (k_e W - E) / tau_e with W = |F v| (9.21), (9.23)."""
        dE = np.zeros(len(E))
        if self.energy:
            for j, (ke, te) in self.energy.items():
                dE[j] = (ke * abs(F[j] * v[j]) - E[j]) / te
        return dE

    def effects(self) -> list:
        """Names (of :data:`drake_est.effects.EFFECTS`) of the friction effects this truth contains."""
        have = {"asymmetric_coulomb": self.kc_neg is not None, "position_dependent_friction": bool(self.bumps),
                "motor_position_ripple": bool(self.ripple), "energy_dependent_friction": bool(self.energy),
                "gear_coupling": bool(self.coupling), "abrupt_change": bool(self.change)}
        return [e for e in EFFECTS if have.get(e, False)]
