"""Friction terms (thesis Ch. 9): each maps joint data to named regressor columns, linear in
its parameters; and the energy dynamics E = G(s) W of Sec. 9.4."""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from drake_est.bfe import BasisFunctionExpansion
from drake_est.errors import DataError, DrakeEstError

TWO_PI = 2.0 * np.pi


# --------------------------------------------------------------------------- helpers

def _cols(X, name: str) -> np.ndarray:
    X = np.asarray(X, dtype=float)
    if X.ndim == 1:
        X = X[:, None]
    if X.ndim != 2:
        raise DataError(f"{name} must be (N,) or (N, n_joints), got shape {X.shape}")
    return X


def _sign(v, eps: float = 0.0) -> np.ndarray:
    """sign(v) with sign(0) = 0 (Sec. 9.1); ``eps > 0`` gives the smooth tanh(v/eps) used in simulation."""
    if eps > 0:
        return np.tanh(v / eps)
    return np.sign(v)


def motor_position(q, gear_ratio: float) -> np.ndarray:
    """Motor angle p_motor = mod(g * p_arm, 2 pi) (Sec. 9.6)."""
    return np.mod(gear_ratio * np.asarray(q, dtype=float), TWO_PI)


# --------------------------------------------------------------------------- terms

class Term(ABC):
    """A group of regressor columns. Subclasses implement :meth:`columns` and :meth:`names`."""

    kind = "term"
    penalized = False  # ridge penalty applies to these columns
    needs_energy = False
    needs_time = False  # columns(..., t=) needs the time (abrupt change)

    @abstractmethod
    def columns(self, Q, DQ, j: int, E=None, sign_eps: float = 0.0):
        """Regressor columns (N, k) of joint index ``j``."""

    @abstractmethod
    def names(self) -> list:
        """Names of the columns."""

    def to_dict(self) -> dict:
        return {"kind": self.kind}


class Coulomb(Term):
    """F = kc sign(v), Eq. (9.1)."""

    kind = "coulomb"

    def columns(self, Q, DQ, j, E=None, sign_eps=0.0):
        return _sign(DQ[:, j], sign_eps)[:, None]

    def names(self):
        return ["kc"]


class Viscous(Term):
    """F = kv v, the viscous part of Eq. (9.2)."""

    kind = "viscous"

    def columns(self, Q, DQ, j, E=None, sign_eps=0.0):
        return DQ[:, j][:, None]

    def names(self):
        return ["kv"]


class AsymmetricCoulomb(Term):
    """F = kc+ sign(v+) + kc- sign(v-), v+ = max(0, v), v- = min(0, v) (Eq. (9.3)).
    Both coefficients are positive for ordinary friction (sign(v-) = -1 for v < 0)."""

    kind = "asymmetric_coulomb"

    def columns(self, Q, DQ, j, E=None, sign_eps=0.0):
        v = DQ[:, j]
        s = _sign(v, sign_eps)
        return np.stack([np.maximum(s, 0.0), np.minimum(s, 0.0)], axis=1)

    def names(self):
        return ["kc+", "kc-"]


class Offset(Term):
    """A constant torque offset (e.g. a torque-sensor bias)."""

    kind = "offset"

    def columns(self, Q, DQ, j, E=None, sign_eps=0.0):
        return np.ones((Q.shape[0], 1))

    def names(self):
        return ["offset"]


class Gravity(Term):
    """Single-joint gravity torque a sin(q) + b cos(q) (footnote to Eq. (9.9))."""

    kind = "gravity"

    def columns(self, Q, DQ, j, E=None, sign_eps=0.0):
        q = Q[:, j]
        return np.stack([np.sin(q), np.cos(q)], axis=1)

    def names(self):
        return ["g_sin", "g_cos"]


class CoupledJoint(Term):
    """Coulomb + viscous friction felt by a wrist joint from the motion of a
    gear-coupled joint ``k`` (Eq. (9.12)): columns sign(dq_k), dq_k.

    Which joints are coupled follows from the coupling matrix (:func:`coupled_joints`);
    with ``motor_side=True`` the motor velocity dq_motor = N dq_arm (row k of the
    motor-from-arm matrix ``N``, Eq. (9.11)) is used instead of the arm velocity."""

    kind = "coupled_joint"

    def __init__(self, k: int, motor_from_arm=None, motor_side: bool = False, label: str | None = None):
        self.k = int(k)
        self.motor_side = bool(motor_side)
        self.N = None if motor_from_arm is None else np.asarray(motor_from_arm, dtype=float)
        if self.motor_side and self.N is None:
            raise DrakeEstError("motor-side coupling needs the motor-from-arm matrix")
        self.label = label or f"q{self.k + 1}"

    def velocity(self, DQ):
        if DQ.shape[1] <= self.k:
            raise DataError(f"coupled term needs the velocity of joint column {self.k}, data has {DQ.shape[1]} joints")
        if self.motor_side:
            if self.N.shape[1] != DQ.shape[1]:
                raise DataError(f"motor-from-arm matrix is {self.N.shape}, data has {DQ.shape[1]} joints")
            return DQ @ self.N[self.k]
        return DQ[:, self.k]

    def columns(self, Q, DQ, j, E=None, sign_eps=0.0):
        vk = self.velocity(DQ)
        return np.stack([_sign(vk, sign_eps), vk], axis=1)

    def names(self):
        return [f"kc_{self.label}", f"kv_{self.label}"]

    def to_dict(self):
        return {"kind": self.kind, "k": self.k, "motor_side": self.motor_side, "label": self.label,
                "motor_from_arm": None if self.N is None else self.N.tolist()}


def coupled_joints(motor_from_arm, joint: int) -> list:
    """Deprecated 0-based form of :func:`drake_est.joints.coupled_joints` (which takes and returns
    1-based joint numbers): 0-based columns k != ``joint`` (a 0-based index) with N[joint, k] != 0."""
    import warnings

    from drake_est.joints import coupled_joints as _coupled
    warnings.warn("identification.friction.coupled_joints takes 0-based indices; use "
                  "drake_est.joints.coupled_joints (1-based joint numbers)", DeprecationWarning, stacklevel=2)
    return [i - 1 for i in _coupled(motor_from_arm, int(joint) + 1)]


class BFETerm(Term):
    """Basis-function expansion (Sec. 6.3) in any of the inputs

    ``"q"`` arm position [rad], ``"qm"`` motor position mod(g q, 2 pi) [rad]
    (periodic), ``"dq"`` velocity [rad/s], ``"E"`` energy signal [N m].

    With ``sign_split`` (default) half of the basis functions are active only
    for positive velocity and half only for negative (Sec. 9.3), so the
    expansion can represent the Coulomb discontinuity. The weights are
    ridge-penalized. Build it with :meth:`from_data`.
    """

    kind = "bfe"
    penalized = True
    INPUTS = ("q", "qm", "dq", "E")

    def __init__(self, inputs, bfe: BasisFunctionExpansion, sign_split: bool = True, gear_ratio: float | None = None,
                 label: str | None = None):
        self.inputs = list(inputs)
        for name in self.inputs:
            if name not in self.INPUTS:
                raise DrakeEstError(f"unknown BFE input '{name}'; choose from {self.INPUTS}")
        if "qm" in self.inputs and not gear_ratio:
            raise DrakeEstError("a motor-position expansion ('qm') needs the gear ratio")
        self.bfe = bfe
        self.sign_split = bool(sign_split)
        self.gear_ratio = None if gear_ratio is None else float(gear_ratio)
        self.label = label or "x".join(self.inputs)
        self.needs_energy = "E" in self.inputs

    def inputs_matrix(self, Q, DQ, j, E=None):
        cols = []
        for name in self.inputs:
            if name == "q":
                cols.append(Q[:, j])
            elif name == "qm":
                cols.append(motor_position(Q[:, j], self.gear_ratio))
            elif name == "dq":
                cols.append(DQ[:, j])
            else:
                if E is None:
                    raise DrakeEstError("this model expands in the energy signal E; estimate it first (Algorithm 6)")
                cols.append(np.asarray(E, dtype=float).ravel())
        return np.stack(cols, axis=1)

    @classmethod
    def from_data(cls, inputs, Q, DQ, j, n, width_factor=1.0, E=None, gear_ratio=None, kernel="gaussian",
                  normalize=True, sign_split=True, label=None):
        """Grid over the data range (motor position: over [0, 2 pi), periodic)."""
        tmp = cls(inputs, BasisFunctionExpansion.uniform(0.0, 1.0, 1), sign_split, gear_ratio, label)
        X = tmp.inputs_matrix(_cols(Q, "q"), _cols(DQ, "dq"), j, E)
        period = [TWO_PI if name == "qm" else None for name in inputs]
        n = np.broadcast_to(np.atleast_1d(n), (len(inputs),)).astype(int)
        bfe = BasisFunctionExpansion.from_data(X, list(n), width_factor=width_factor, kernel=kernel,
                                               normalize=normalize, period=period)
        tmp.bfe = bfe
        return tmp

    def columns(self, Q, DQ, j, E=None, sign_eps=0.0):
        X = self.inputs_matrix(Q, DQ, j, E)
        return self.bfe.features(X, velocity=DQ[:, j], sign_split=self.sign_split)

    def names(self):
        K = self.bfe.n_basis
        if self.sign_split:
            return [f"{self.label}+[{i}]" for i in range(K)] + [f"{self.label}-[{i}]" for i in range(K)]
        return [f"{self.label}[{i}]" for i in range(K)]

    def to_dict(self):
        return {"kind": self.kind, "inputs": self.inputs, "sign_split": self.sign_split,
                "gear_ratio": self.gear_ratio, "label": self.label,
                "bfe": {"centers": [c.tolist() for c in self.bfe.centers], "widths": np.asarray(self.bfe.widths).tolist(),
                        "kernel": self.bfe.kernel, "normalize": bool(self.bfe.normalize),
                        "period": list(self.bfe.period)}}


class SpeedAttenuatedRipple(Term):
    """Motor-position ripple whose amplitude falls with speed (the synthetic truth's ripple, Ch. 10):
    one column sin(h mod(g q, 2 pi) + phase) / (1 + |v| / v_half), coefficient = amplitude at rest [N m].
    ``gear_ratio`` g, ``harmonic`` h per motor revolution, ``v_half`` [rad/s], ``phase`` [rad]."""

    kind = "speed_attenuated_ripple"

    def __init__(self, gear_ratio: float, harmonic: float, v_half: float, phase: float = 0.0):
        self.gear_ratio, self.harmonic = float(gear_ratio), float(harmonic)
        self.v_half, self.phase = float(v_half), float(phase)
        if not self.v_half > 0:
            raise DrakeEstError(f"ripple v_half must be positive, got {v_half}")

    def columns(self, Q, DQ, j, E=None, sign_eps=0.0):
        q, v = Q[:, j], DQ[:, j]
        wave = np.sin(self.harmonic * np.mod(self.gear_ratio * q, TWO_PI) + self.phase)
        return (1.0 / (1.0 + np.abs(v) / self.v_half) * wave)[:, None]

    def names(self):
        return ["ripple_amplitude"]

    def to_dict(self):
        return {"kind": self.kind, "gear_ratio": self.gear_ratio, "harmonic": self.harmonic,
                "v_half": self.v_half, "phase": self.phase}


class TimeSwitched(Term):
    """Another term's columns, active only after (``after=True``: t >= t_switch) or before
    (t < t_switch) a switching time [s]: an abrupt change of friction (Ch. 7, (7.8)) as a term."""

    kind = "time_switched"
    needs_time = True

    def __init__(self, term: Term, t_switch: float, after: bool = True):
        self.term, self.t_switch, self.after = term, float(t_switch), bool(after)
        self.needs_energy = term.needs_energy

    def columns(self, Q, DQ, j, E=None, sign_eps=0.0, t=None):
        if t is None:
            raise DataError("a time-switched friction term needs the time t")
        t = np.broadcast_to(np.asarray(t, float).ravel(), (Q.shape[0],))
        on = (t >= self.t_switch) if self.after else (t < self.t_switch)
        C = self.term.columns(Q, DQ, j, E, sign_eps)
        return np.where(on[:, None], C, 0.0 * C)

    def names(self):
        tag = "after" if self.after else "before"
        return [f"{n}_{tag}" for n in self.term.names()]

    def to_dict(self):
        return {"kind": self.kind, "term": self.term.to_dict(), "t_switch": self.t_switch, "after": self.after}


def term_from_dict(d: dict) -> Term:
    kind = d.get("kind")
    simple = {c.kind: c for c in (Coulomb, Viscous, AsymmetricCoulomb, Offset, Gravity)}
    if kind in simple:
        return simple[kind]()
    if kind == "coupled_joint":
        return CoupledJoint(d["k"], d.get("motor_from_arm"), d.get("motor_side", False), d.get("label"))
    if kind == SpeedAttenuatedRipple.kind:
        return SpeedAttenuatedRipple(d["gear_ratio"], d["harmonic"], d["v_half"], d.get("phase", 0.0))
    if kind == TimeSwitched.kind:
        return TimeSwitched(term_from_dict(d["term"]), d["t_switch"], d.get("after", True))
    if kind == "bfe":
        b = d["bfe"]
        bfe = BasisFunctionExpansion(centers=[np.asarray(c) for c in b["centers"]], widths=b["widths"],
                                     kernel=b["kernel"], normalize=b["normalize"], period=b["period"])
        return BFETerm(d["inputs"], bfe, d["sign_split"], d.get("gear_ratio"), d.get("label"))
    raise DrakeEstError(f"unknown friction term kind '{kind}'")


# --------------------------------------------------------------------------- energy dynamics

@dataclass
class EnergyDynamics:
    """E = G(s) W with G(s) = k_e / (1 + s tau_e) (Eq. (9.23)), W = |F v| (9.21),
    ZOH-sampled with period h: E[k+1] = a E[k] + k_e (1 - a) W[k], a = exp(-h / tau_e),
    i.e. H(z) = k_e (1 - a) / (z - a) (Eq. (9.24)). ``gain`` is the static gain k_e
    [N m per W], ``time_constant`` tau_e [s]."""

    gain: float
    time_constant: float
    h: float
    E0: float = 0.0

    @property
    def pole(self) -> float:
        return float(np.exp(-self.h / self.time_constant))

    @property
    def discrete_gain(self) -> float:
        return float(self.gain * (1.0 - self.pole))

    def filter(self, W) -> np.ndarray:
        """E[k] for k = 0..N-1 from the power W (E[0] = E0)."""
        import scipy.signal

        W = np.asarray(W, dtype=float).ravel()
        a = self.pole
        # E[k] = a E[k-1] + b W[k-1]; zero-state response plus the free response of E0
        out = scipy.signal.lfilter([0.0, self.discrete_gain], [1.0, -a], W)
        if self.E0:
            out = out + self.E0 * a ** np.arange(W.size)
        return out

    def to_dict(self):
        return {"gain": self.gain, "time_constant": self.time_constant, "h": self.h, "E0": self.E0,
                "discrete_pole": self.pole, "discrete_gain": self.discrete_gain}

    @classmethod
    def from_dict(cls, d):
        return cls(gain=float(d["gain"]), time_constant=float(d["time_constant"]), h=float(d["h"]),
                   E0=float(d.get("E0", 0.0)))
