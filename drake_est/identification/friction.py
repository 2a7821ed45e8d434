"""Friction models and their identification (thesis Ch. 9).

Sign convention (used everywhere in drake_est): the friction torque ``F`` is the
torque the actuator must supply to overcome friction, so that the measured motor
torque is ``tau = ID(q, dq, ddq) + F`` (Eq. (9.8)); ``F`` has the sign of the
velocity.  The torque friction *exerts on the joint* is ``-F``.

Models are built from *terms*; each term maps the joint data to regressor
columns with names, so every model below is linear in its parameters (except the
energy dynamics, which Algorithm 6 handles in :mod:`drake_est.identification.energy`):

================================  ==========================================  =============
term                              columns                                     Eq.
================================  ==========================================  =============
:class:`Coulomb`                  ``sign(v)``                                 (9.1)
:class:`Viscous`                  ``v``                                       (9.2)
:class:`AsymmetricCoulomb`        ``sign(v+)``, ``sign(v-)``                  (9.3)
:class:`BFETerm` on ``q``         normalized RBFs of arm position, split      (9.13)-(9.16)
                                  by velocity sign
:class:`BFETerm` on ``qm, dq``    RBFs in motor position x velocity,          Sec. 9.6
                                  ``qm = mod(g q, 2 pi)``                     (9.17)-(9.18)
:class:`BFETerm` on ``q, dq, E``  P x V x E expansion                         Sec. 9.4
:class:`CoupledMotor`             ``sign(dqm_k)``, ``dqm_k`` of coupled       (9.12)
                                  wrist motors
:class:`Gravity`                  ``sin q``, ``cos q`` (single joint)         footnote 9.2
================================  ==========================================  =============

``JointFriction`` fits any list of terms to one joint by (ridge) least squares
(Eq. (6.8), solved by SVD in :func:`drake_est.bfe.ridge_fit`, the penalty on
the basis-function weights chosen by cross-validation), predicts, and
serializes to a JSON-able dict (:meth:`JointFriction.to_dict`), which is what
:class:`drake_est.systems.friction.FrictionModel` consumes.

Data selection (9.9): :func:`select_steady` keeps samples with a velocity
significantly different from zero and small acceleration and reports how many
were dropped for each reason.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np

from drake_est.bfe import BasisFunctionExpansion, check_excitation, ridge_fit, select_ridge
from drake_est.errors import DataError, DrakeEstError, IdentifiabilityError
from drake_est.metrics import fpe, fit_percent, mae, npe, rmse

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

class Term:
    """A group of regressor columns. Subclasses implement :meth:`columns`."""

    kind = "term"
    penalized = False  # ridge penalty applies to these columns
    needs_energy = False

    def columns(self, Q, DQ, j: int, E=None, sign_eps: float = 0.0):  # pragma: no cover - interface
        raise NotImplementedError

    def names(self) -> list:  # pragma: no cover - interface
        raise NotImplementedError

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


class CoupledMotor(Term):
    """Coulomb + viscous friction of a coupled wrist motor ``k`` (Eq. (9.12)).

    Motor velocities follow from the arm velocities by q_arm = G q_motor (9.11),
    i.e. dq_motor = G^-1 dq_arm, computed with a linear solve. ``coupling`` is the
    (n, n) matrix G restricted to the joints present in the data, in the same
    column order."""

    kind = "coupled_motor"

    def __init__(self, coupling, motor: int, label: str | None = None):
        self.coupling = np.asarray(coupling, dtype=float)
        if self.coupling.ndim != 2 or self.coupling.shape[0] != self.coupling.shape[1]:
            raise DrakeEstError(f"coupling matrix must be square, got shape {self.coupling.shape}")
        self.motor = int(motor)
        self.label = label or f"m{self.motor + 1}"

    def motor_velocities(self, DQ):
        if DQ.shape[1] != self.coupling.shape[0]:
            raise DataError(f"coupled-motor term needs velocities of all {self.coupling.shape[0]} coupled joints, "
                            f"got {DQ.shape[1]} columns")
        return np.linalg.solve(self.coupling, DQ.T).T

    def columns(self, Q, DQ, j, E=None, sign_eps=0.0):
        vm = self.motor_velocities(DQ)[:, self.motor]
        return np.stack([_sign(vm, sign_eps), vm], axis=1)

    def names(self):
        return [f"kc_{self.label}", f"kv_{self.label}"]

    def to_dict(self):
        return {"kind": self.kind, "coupling": self.coupling.tolist(), "motor": self.motor, "label": self.label}


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


def term_from_dict(d: dict) -> Term:
    kind = d.get("kind")
    simple = {c.kind: c for c in (Coulomb, Viscous, AsymmetricCoulomb, Offset, Gravity)}
    if kind in simple:
        return simple[kind]()
    if kind == "coupled_motor":
        return CoupledMotor(d["coupling"], d["motor"], d.get("label"))
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


# --------------------------------------------------------------------------- the model

class JointFriction:
    """A friction model of one joint, linear in its parameters, optionally with the
    energy state of Eq. (9.22): F = F_n(q, dq[, E]) + sign(v) E.

    Parameters
    ----------
    terms : list of :class:`Term`.
    joint : column of the joint in the (N, n) data arrays handed to fit/predict.
    lam : ridge penalty on penalized (basis-function) columns; "cv" chooses it by
        contiguous 5-fold cross-validation in :meth:`fit`.
    energy : :class:`EnergyDynamics` or None.
    joint_number : the 1-based robot joint number (metadata only).
    """

    def __init__(self, terms, joint: int = 0, lam="cv", energy: EnergyDynamics | None = None,
                 joint_number: int | None = None, name: str = ""):
        self.terms = list(terms)
        if not self.terms:
            raise DrakeEstError("a friction model needs at least one term")
        self.joint = int(joint)
        self.lam = lam
        self.energy = energy
        self.joint_number = joint_number
        self.name = name
        self.coef = None
        self.info = {}

    # ---------------------------------------------------------------- regressors
    @property
    def names(self) -> list:
        return [n for t in self.terms for n in t.names()]

    @property
    def n_params(self) -> int:
        return len(self.names)

    @property
    def penalize(self) -> np.ndarray:
        return np.concatenate([np.full(len(t.names()), 1.0 if t.penalized else 0.0) for t in self.terms])

    @property
    def has_bfe(self) -> bool:
        return any(t.penalized for t in self.terms)

    def regressors(self, Q, DQ, E=None, sign_eps: float = 0.0):
        """Regressor matrix A (N, p) and the column names."""
        Q, DQ = _cols(Q, "q"), _cols(DQ, "dq")
        if Q.shape != DQ.shape:
            raise DataError(f"q has shape {Q.shape} but dq has {DQ.shape}")
        if not 0 <= self.joint < Q.shape[1]:
            raise DataError(f"joint column {self.joint} not in data with {Q.shape[1]} joints")
        A = np.hstack([t.columns(Q, DQ, self.joint, E, sign_eps) for t in self.terms])
        return A, self.names

    # ---------------------------------------------------------------- fitting
    def fit(self, Q, DQ, y, E=None, mask=None, lams=None):
        """Least-squares fit of the linear parameters to the friction torque ``y``
        (measured torque minus any rigid-body torque you know). ``E`` is the energy
        signal if the model has an energy expansion; ``mask`` selects samples."""
        Q, DQ = _cols(Q, "q"), _cols(DQ, "dq")
        y = np.asarray(y, dtype=float).ravel()
        if y.shape[0] != Q.shape[0]:
            raise DataError(f"torque has {y.shape[0]} samples, positions have {Q.shape[0]}")
        A, names = self.regressors(Q, DQ, E)
        if mask is not None:
            A, y = A[mask], y[mask]
        _check_identifiable(A, names, self.penalize, self.terms, DQ[mask, self.joint] if mask is not None
                            else DQ[:, self.joint])
        pen = self.penalize
        if self.has_bfe:
            if isinstance(self.lam, str):
                lam, _ = select_ridge(A, y, lams=lams if lams is not None else np.logspace(-6, 2, 9),
                                      penalize=pen, method="cv", folds=5, contiguous=True)
                self.info["lam_selected_by"] = "5-fold contiguous cross-validation"
            else:
                lam = float(self.lam)
            res = ridge_fit(A, y, lam, penalize=pen)
        else:
            lam = 0.0
            res = ridge_fit(A, y, 0.0)
        self.coef = res.coef
        self.info.update({"lam": float(lam), "dof": res.dof, "rank": res.rank, "n_fit": int(A.shape[0])})
        return self

    # ---------------------------------------------------------------- prediction
    def _check_fitted(self):
        if self.coef is None:
            raise DrakeEstError("friction model is not fitted yet")

    def predict_nominal(self, Q, DQ, E=None, sign_eps: float = 0.0) -> np.ndarray:
        """F_n(q, dq[, E]): the linear part, without the sign(v) E term."""
        self._check_fitted()
        A, _ = self.regressors(Q, DQ, E, sign_eps)
        return A @ self.coef

    def simulate_energy(self, Q, DQ, E0: float | None = None) -> np.ndarray:
        """Run the energy state forward over the samples (assumed uniformly spaced
        at the model's h): W[k] = |F[k] v[k]|, E[k+1] = a E[k] + b W[k]."""
        if self.energy is None:
            raise DrakeEstError("model has no energy dynamics")
        self._check_fitted()
        Q, DQ = _cols(Q, "q"), _cols(DQ, "dq")
        N = Q.shape[0]
        v = DQ[:, self.joint]
        s = np.sign(v)
        a, b = self.energy.pole, self.energy.discrete_gain
        E = np.empty(N)
        e = self.energy.E0 if E0 is None else float(E0)
        if any(t.needs_energy for t in self.terms):
            for k in range(N):
                E[k] = e
                f = float(self.predict_nominal(Q[k:k + 1], DQ[k:k + 1], np.array([e]))[0]) + s[k] * e
                e = a * e + b * abs(f * v[k])
        else:
            Fn = self.predict_nominal(Q, DQ)
            for k in range(N):
                E[k] = e
                e = a * e + b * abs((Fn[k] + s[k] * e) * v[k])
        return E

    def predict(self, Q, DQ, E=None, sign_eps: float = 0.0) -> np.ndarray:
        """Friction torque F [N m]. For an energy model, ``E`` is the energy signal;
        when omitted it is simulated from the data (:meth:`simulate_energy`)."""
        self._check_fitted()
        if self.energy is not None and E is None:
            E = self.simulate_energy(Q, DQ)
        F = self.predict_nominal(Q, DQ, E, sign_eps)
        if self.energy is not None:
            F = F + _sign(_cols(DQ, "dq")[:, self.joint], sign_eps) * np.asarray(E, dtype=float).ravel()
        return F

    # ---------------------------------------------------------------- parameters / io
    def params(self) -> dict:
        """Named parameters (basis-function weights excluded; see ``coef``)."""
        self._check_fitted()
        out = {}
        i = 0
        for t in self.terms:
            for n in t.names():
                if not t.penalized:
                    out[n] = float(self.coef[i])
                i += 1
        if self.energy is not None:
            out["ke"] = self.energy.gain
            out["tau_e"] = self.energy.time_constant
        return out

    def to_dict(self) -> dict:
        self._check_fitted()
        return {"format": "drake_est.friction/1", "name": self.name, "joint": self.joint,
                "joint_number": self.joint_number, "terms": [t.to_dict() for t in self.terms],
                "names": self.names, "coef": np.asarray(self.coef).tolist(), "lam": self.info.get("lam", 0.0),
                "params": self.params(), "energy": None if self.energy is None else self.energy.to_dict(),
                "sign_convention": "tau_measured = ID(q, dq, ddq) + F; F has the sign of the velocity"}

    @classmethod
    def from_dict(cls, d: dict) -> "JointFriction":
        if d.get("format") != "drake_est.friction/1":
            raise DataError("not a drake_est friction model (missing format 'drake_est.friction/1')")
        m = cls([term_from_dict(t) for t in d["terms"]], joint=d.get("joint", 0), lam=d.get("lam", 0.0),
                energy=None if d.get("energy") is None else EnergyDynamics.from_dict(d["energy"]),
                joint_number=d.get("joint_number"), name=d.get("name", ""))
        m.coef = np.asarray(d["coef"], dtype=float)
        if m.coef.size != m.n_params:
            raise DataError(f"friction model has {m.coef.size} coefficients for {m.n_params} regressors")
        return m

    def copy(self) -> "JointFriction":
        return copy.deepcopy(self)

    @classmethod
    def coulomb_viscous(cls, kc, kv, joint: int = 0, kc_minus=None, joint_number=None) -> "JointFriction":
        """A fixed (not fitted) Coulomb + viscous model (9.2), or direction-dependent
        (9.3) when ``kc_minus`` is given (then ``kc`` is kc+)."""
        if kc_minus is None:
            m = cls([Viscous(), Coulomb()], joint=joint, lam=0.0, joint_number=joint_number, name="nominal")
            m.coef = np.array([kv, kc], dtype=float)
        else:
            m = cls([Viscous(), AsymmetricCoulomb()], joint=joint, lam=0.0, joint_number=joint_number,
                    name="nominal-asymmetric")
            m.coef = np.array([kv, kc, kc_minus], dtype=float)
        return m


def _check_identifiable(A, names, pen, terms, v):
    """Name why a model cannot be identified, instead of a singular-matrix error."""
    N, p = A.shape
    if N == 0:
        raise IdentifiabilityError("no samples left for identification (all dropped by the selection (9.9))")
    vpos, vneg = int(np.sum(v > 0)), int(np.sum(v < 0))
    needs_both = any(isinstance(t, (AsymmetricCoulomb,)) for t in terms) or any(
        isinstance(t, BFETerm) and t.sign_split for t in terms)
    if needs_both and (vpos < 3 or vneg < 3):
        raise IdentifiabilityError(
            f"velocity is not excited in both directions ({vpos} samples with v > 0, {vneg} with v < 0); "
            f"direction-dependent friction cannot be identified")
    speeds = np.unique(np.round(np.abs(v), 6))
    has_kv = any(isinstance(t, Viscous) for t in terms)
    has_kc = any(isinstance(t, (Coulomb, AsymmetricCoulomb)) for t in terms)
    if has_kv and has_kc and np.ptp(np.abs(v)) <= 1e-3 * max(np.max(np.abs(v)), 1e-12):
        raise IdentifiabilityError(
            f"velocity is not excited: the log holds a single speed (|v| = {np.max(np.abs(v)):.4g} rad/s, "
            f"{speeds.size} distinct value(s)); Coulomb and viscous friction cannot be separated")
    n_pen = int(np.sum(pen > 0))
    n_free = p - n_pen
    if N < max(2 * p, p + 10) and n_pen:
        raise IdentifiabilityError(
            f"too few samples for the requested basis: {N} samples for {p} parameters "
            f"({n_pen} basis-function weights); use fewer basis functions or a longer log")
    # unpenalized part must be identifiable on its own (penalized part is regularized)
    free = pen == 0
    if n_free:
        check_excitation(A[:, free], [n for n, f in zip(names, free) if f])
        if N < n_free + 2:
            raise IdentifiabilityError(f"{N} samples are too few for the {n_free} friction parameters")


# --------------------------------------------------------------------------- data selection (9.9)

@dataclass
class Selection:
    """Samples kept for identification and why others were dropped."""

    mask: np.ndarray
    v_min: float
    a_max: float
    n_total: int
    n_low_velocity: int
    n_accelerating: int
    n_kept: int
    extra: dict = field(default_factory=dict)

    def summary(self) -> str:
        return (f"kept {self.n_kept} of {self.n_total} samples (9.9): dropped {self.n_low_velocity} with "
                f"|v| <= {self.v_min:.3g} rad/s and {self.n_accelerating} more with |a| >= {self.a_max:.3g} rad/s^2")

    def to_dict(self):
        return {"n_total": self.n_total, "n_kept": self.n_kept, "n_low_velocity": self.n_low_velocity,
                "n_accelerating": self.n_accelerating, "v_min": self.v_min, "a_max": self.a_max}


def select_steady(dq, ddq=None, t=None, v_min: float | None = None, a_max: float | None = None,
                  v_rel: float = 0.05, a_factor: float = 5.0) -> Selection:
    """Samples that approximately satisfy (9.9): moving (C(p, v) v small is not
    checked; run one joint at a time) at nearly constant velocity.

    Thresholds (documented defaults):

    * ``v_min``: |v| must exceed ``v_rel`` (5 %) of the 99th percentile of |v|,
      and at least 1e-3 rad/s -- near-zero velocities have an uncertain sign
      and bias the Coulomb estimate (Sec. 9.2).
    * ``a_max``: |a| must be below ``a_factor`` (5) times the median |a| of the
      moving samples, and at least 0.02 rad/s^2 -- at constant-velocity segments
      the median |a| is the differentiation noise, so this drops the
      accelerating transitions whose inertial torque M a would bias the fit.

    ``dq``, ``ddq`` are (N,) or (N, n); with several joints a sample is kept when
    every joint satisfies the thresholds that apply to the moving joints (a
    joint whose |v| never exceeds v_min is treated as standing still and only
    its acceleration is checked)."""
    DQ = _cols(dq, "dq")
    N = DQ.shape[0]
    if ddq is None:
        if t is None:
            raise DataError("select_steady needs the acceleration ddq or the time vector t to compute it")
        DDQ = np.gradient(DQ, np.asarray(t, dtype=float), axis=0)
    else:
        DDQ = _cols(ddq, "ddq")
        if DDQ.shape != DQ.shape:
            raise DataError(f"ddq has shape {DDQ.shape}, dq has {DQ.shape}")
    absv = np.abs(DQ)
    vmax = np.quantile(absv, 0.99, axis=0)
    vmin = np.maximum(v_rel * vmax, 1e-3) if v_min is None else np.full(DQ.shape[1], float(v_min))
    moving_joint = vmax > vmin
    low = np.zeros(N, bool)
    for c in range(DQ.shape[1]):
        if moving_joint[c]:
            low |= absv[:, c] <= vmin[c]
    if a_max is None:
        moving = ~low
        base = np.median(np.abs(DDQ[moving]), axis=0) if np.any(moving) else np.zeros(DQ.shape[1])
        amax = np.maximum(a_factor * base, 0.02)
    else:
        amax = np.full(DQ.shape[1], float(a_max))
    acc = np.any(np.abs(DDQ) >= amax, axis=1) & ~low
    mask = ~low & ~acc
    return Selection(mask=mask, v_min=float(np.max(vmin)), a_max=float(np.max(amax)), n_total=N,
                     n_low_velocity=int(low.sum()), n_accelerating=int(acc.sum()), n_kept=int(mask.sum()))


# --------------------------------------------------------------------------- model builders

NOMINAL_KINDS = ("coulomb", "viscous", "asymmetric")


def nominal_terms(kind: str = "asymmetric", gravity: bool = False, offset: bool = False) -> list:
    """Terms of the nominal model: "coulomb" (9.1), "viscous" (9.2) or "asymmetric" (9.3)."""
    if kind == "coulomb":
        terms = [Coulomb()]
    elif kind == "viscous":
        terms = [Viscous(), Coulomb()]
    elif kind == "asymmetric":
        terms = [Viscous(), AsymmetricCoulomb()]
    else:
        raise DrakeEstError(f"unknown nominal friction model '{kind}'; choose one of {NOMINAL_KINDS}")
    if gravity:
        terms.append(Gravity())
    if offset:
        terms.append(Offset())
    return terms


MODELS = ("nominal", "position", "motor", "position+motor", "energy", "position+energy", "pve", "coupled")


def build_model(model: str, Q, DQ, joint: int = 0, nominal: str = "asymmetric", gear_ratio: float | None = None,
                coupling=None, n_position: int = 12, n_motor: int = 36, n_velocity: int = 6,
                width_factor: float = 1.0, gravity: bool = False, lam="cv", joint_number=None,
                n_energy: int = 3) -> JointFriction:
    """An unfitted :class:`JointFriction` of the named structure.

    * ``nominal``: (9.1)-(9.3);
    * ``position``: nominal + normalized Gaussian RBFs in arm position, split by sign of v (9.16);
    * ``motor``: nominal + RBFs in motor position x velocity (36 x 6 as in Sec. 9.6), needs ``gear_ratio``;
    * ``position+motor``: both expansions;
    * ``energy``: nominal + sign(v) E (9.22)-(9.24); fit with :func:`drake_est.identification.energy.fit_energy`;
    * ``position+energy``: position model + energy (Table 9.2, right column);
    * ``pve``: nominal + P x V x E expansion (Sec. 9.6, 40 x 6 x 3 in the thesis) -- E must be estimated first;
    * ``coupled``: nominal + coupled wrist motors (9.12), needs ``coupling`` (q_arm = G q_motor) for
      the joints in the data."""
    Q, DQ = _cols(Q, "q"), _cols(DQ, "dq")
    terms = nominal_terms(nominal, gravity=gravity)
    if model not in MODELS:
        raise DrakeEstError(f"unknown friction model '{model}'; choose one of {', '.join(MODELS)}")
    if model in ("position", "position+motor", "position+energy"):
        terms.append(BFETerm.from_data(["q"], Q, DQ, joint, n_position, width_factor, label="pos"))
    if model in ("motor", "position+motor"):
        if not gear_ratio:
            raise DrakeEstError("the motor-position model needs the gear ratio (--gear-ratio or robot metadata)")
        terms.append(BFETerm.from_data(["qm", "dq"], Q, DQ, joint, [n_motor, n_velocity], width_factor,
                                       gear_ratio=gear_ratio, label="motor"))
    if model == "coupled":
        if coupling is None:
            raise DrakeEstError("the gear-coupled model needs the coupling matrix G (q_arm = G q_motor)")
        G = np.asarray(coupling, dtype=float)
        if G.shape != (Q.shape[1], Q.shape[1]):
            raise DataError(f"coupling matrix has shape {G.shape} for a log with {Q.shape[1]} joints")
        for k in range(G.shape[1]):
            if k != joint and G[joint, k] != 0.0:
                terms.append(CoupledMotor(G, k))
    energy = None
    if model in ("energy", "position+energy"):
        energy = EnergyDynamics(gain=0.0, time_constant=1.0, h=1.0)  # placeholder, set by fit_energy
    m = JointFriction(terms, joint=joint, lam=lam, energy=energy, joint_number=joint_number, name=model)
    m.info["n_energy"] = n_energy
    m.info["n_position"] = n_position
    m.info["width_factor"] = width_factor
    return m


def add_energy_expansion(model: JointFriction, Q, DQ, E, n=(40, 6, 3), width_factor=1.0) -> JointFriction:
    """Replace a fitted energy model's sign(v) E term by a P x V x E expansion (Sec. 9.6)."""
    terms = [t for t in model.terms if not isinstance(t, BFETerm)]
    terms.append(BFETerm.from_data(["q", "dq", "E"], Q, DQ, model.joint, list(n), width_factor, E=E, label="pve"))
    return JointFriction(terms, joint=model.joint, lam=model.lam, energy=None, joint_number=model.joint_number,
                         name="pve")


# --------------------------------------------------------------------------- metrics

def evaluate(y, yhat, n_params: int, truth: dict | None = None, params: dict | None = None) -> dict:
    """Validation metrics (Johansson 1993): Fit (%), FPE, RMSE, MAE, and NPE (9.28)
    over the parameters present in both ``truth`` and ``params``."""
    y = np.asarray(y, float).ravel()
    yhat = np.asarray(yhat, float).ravel()
    out = {"fit": fit_percent(y, yhat), "fpe": fpe(y, yhat, n_params), "rmse": rmse(y, yhat),
           "mae": mae(y, yhat), "n": int(y.size), "n_params": int(n_params)}
    if truth and params:
        keys = [k for k in truth if k in params and truth[k] != 0]
        if keys:
            out["npe"] = npe([params[k] for k in keys], [truth[k] for k in keys])
            out["npe_params"] = keys
    return out


def split_holdout(n: int, frac: float = 0.3, where: str = "end"):
    """Indices of a contiguous training block and a held-out validation block."""
    if not 0 < frac < 1:
        raise DrakeEstError(f"validation fraction must be in (0, 1), got {frac}")
    cut = int(round(n * (1 - frac)))
    idx = np.arange(n)
    if where == "end":
        return idx[:cut], idx[cut:]
    if where == "start":
        k = n - cut
        return idx[k:], idx[:k]
    raise DrakeEstError(f"unknown hold-out position '{where}'")
