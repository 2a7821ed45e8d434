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

    def torque(self, q, v, t, E=None) -> np.ndarray:
        """Friction torques (n,) [N m] opposing the motion (tau_motor = ID + F)."""
        n = len(self.kc)
        F = np.zeros(n)
        E = np.zeros(n) if E is None else E
        for j in range(n):
            if self.active is not None and not self.active[j]:
                continue
            s = np.tanh(v[j] / self.v_eps)
            kv = self.kv[j]
            if self.change and j in self.change and t >= self.change[j][0]:
                kv = self.change[j][2]
            F[j] = kv * v[j] + s * self.coulomb_level(j, q[j], v[j], t, E[j])
            if self.ripple and j in self.ripple:
                g, h, a0, vh, ph = self.ripple[j]
                F[j] += a0 / (1.0 + abs(v[j]) / vh) * np.sin(h * np.mod(g * q[j], 2 * np.pi) + ph)
            if self.coupling and j in self.coupling:
                for i, kci, kvi in self.coupling[j]:
                    F[j] += kvi * v[i] + kci * np.tanh(v[i] / self.v_eps)
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
