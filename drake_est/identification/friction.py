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
:class:`CoupledJoint`             ``sign(dq_k)``, ``dq_k`` of gear-coupled     (9.12)
                                  wrist joints
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

from abc import ABC, abstractmethod

import copy
from dataclasses import dataclass, field

import numpy as np

from drake_est.bfe import BasisFunctionExpansion
from drake_est.regression import check_excitation, ridge_cv, ridge_fit, ridge_gram_dof, ridge_gram_solve
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

class Term(ABC):
    """A group of regressor columns. Subclasses implement :meth:`columns` and :meth:`names`."""

    kind = "term"
    penalized = False  # ridge penalty applies to these columns
    needs_energy = False

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
    """0-based columns k != joint with a nonzero coupling entry in row ``joint`` of the
    motor-from-arm matrix (lower-triangular wrist structure of Eq. (9.10))."""
    N = np.asarray(motor_from_arm, dtype=float)
    return [k for k in range(N.shape[1]) if k != joint and N[joint, k] != 0.0]


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
    if kind == "coupled_joint":
        return CoupledJoint(d["k"], d.get("motor_from_arm"), d.get("motor_side", False), d.get("label"))
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


# --------------------------------------------------------------------------- fast ridge for CV

def _gram_ridge(G, b, lam, pen):
    """Cholesky ridge of :mod:`drake_est.regression` (kept name; jitter 1e-10 x mean diagonal)."""
    return ridge_gram_solve(G, b, lam, pen)


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
    def fit(self, Q, DQ, y, E=None, mask=None, lams=None, solver: str = "auto"):
        """Least-squares fit of the linear parameters to the friction torque ``y``
        (measured torque minus any rigid-body torque you know). ``E`` is the energy
        signal if the model has an energy expansion; ``mask`` selects samples.
        ``lams``: candidate penalties per sample (scaled by the number of rows).
        ``solver``: "svd" (:func:`drake_est.bfe.ridge_fit`, robust), "cholesky"
        (regularized normal equations, fast) or "auto" (SVD up to 100 columns)."""
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
                grid = np.asarray(lams if lams is not None else np.logspace(-6, 2, 9), float)
                scores = ridge_cv(A, y, grid * A.shape[0], pen)   # penalty grid scaled with the rows
                lam = float(grid[int(np.argmin(scores))] * A.shape[0])
                self.info["lam_selected_by"] = "5-fold contiguous cross-validation"
            else:
                lam = float(self.lam)
        else:
            lam = 0.0
        if solver == "auto":
            solver = "svd" if A.shape[1] <= 100 else "cholesky"
        if solver == "svd" or lam == 0.0:
            res = ridge_fit(A, y, lam, penalize=pen if lam > 0 else None)
            coef, dof, rank = res.coef, res.dof, res.rank
        elif solver == "cholesky":
            G = A.T @ A
            coef = ridge_gram_solve(G, A.T @ y, lam, pen)
            dof = ridge_gram_dof(G, lam, pen)
            rank = A.shape[1]
        else:
            raise DrakeEstError(f"unknown solver '{solver}' (use 'auto', 'svd' or 'cholesky')")

        class _R:  # minimal result record
            pass
        res = _R()
        res.coef, res.dof, res.rank = coef, dof, rank
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
    if ddq is None and a_max is not None and np.isinf(a_max):
        DDQ = np.zeros_like(DQ)
    elif ddq is None:
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
                n_energy: int = 3, joint_numbers=None) -> JointFriction:
    """An unfitted :class:`JointFriction` of the named structure.

    * ``nominal``: (9.1)-(9.3);
    * ``position``: nominal + normalized Gaussian RBFs in arm position, split by sign of v (9.16);
    * ``motor``: nominal + RBFs in motor position x velocity (36 x 6 as in Sec. 9.6), needs ``gear_ratio``;
    * ``position+motor``: both expansions;
    * ``energy``: nominal + sign(v) E (9.22)-(9.24); fit with :func:`drake_est.identification.energy.fit_energy`;
    * ``position+energy``: position model + energy (Table 9.2, right column);
    * ``pve``: nominal + P x V x E expansion (Sec. 9.6, 40 x 6 x 3 in the thesis) -- E must be estimated first;
    * ``coupled``: nominal + Coulomb/viscous terms of the gear-coupled wrist joints (9.12); ``coupling``
      is the robot's motor-from-arm matrix (q_motor = N q_arm) restricted to the joints in the data;
      ``joint_numbers`` (1-based, per data column) only label the columns."""
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
            raise DrakeEstError("the gear-coupled model needs the coupling (motor-from-arm) matrix of the robot")
        N = np.asarray(coupling, dtype=float)
        if N.shape != (Q.shape[1], Q.shape[1]):
            raise DataError(f"coupling matrix has shape {N.shape} for a log with {Q.shape[1]} joints")
        ks = coupled_joints(N, joint)
        if not ks:
            raise DrakeEstError(f"joint column {joint} is not gear-coupled to any other joint in the coupling matrix")
        for k in ks:
            terms.append(CoupledJoint(k, N, motor_side=False, label=f"q{(k + 1) if joint_numbers is None else joint_numbers[k]}"))
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


# --------------------------------------------------------------------------- from a log to a validated model

@dataclass
class FrictionResult:
    """Result of :func:`fit_friction`: the fitted model, the data selection, and the
    metrics on the training block and on the held-out validation block."""

    model: JointFriction
    selection: Selection
    train: dict
    validation: dict
    structure: dict
    arrays: dict = field(default_factory=dict, repr=False)  # t, q, dq, y, yhat, masks (for plots)

    def to_dict(self) -> dict:
        return {"model": self.model.to_dict(), "selection": self.selection.to_dict(), "train": self.train,
                "validation": self.validation, "structure": self.structure}


def _cv_subsample(idx: np.ndarray, max_rows: int = 3000) -> np.ndarray:
    step = max(1, int(np.ceil(idx.size / max_rows)))
    return idx[::step]


def _choose_structure(model_name, Q, DQ, y, joint, fit_idx, build_kw, candidates):
    """Pick (n_position, width_factor) of a position expansion by 5-fold contiguous CV."""
    sub = _cv_subsample(fit_idx, 8000)
    best, table = None, []
    for n, wf in candidates:
        m = build_model(model_name, Q[fit_idx], DQ[fit_idx], joint=joint, n_position=n, width_factor=wf,
                        **build_kw)
        A, _ = m.regressors(Q[sub], DQ[sub])
        if A.shape[0] < 2 * A.shape[1]:
            continue
        pen = m.penalize
        errs = ridge_cv(A, y[sub], np.array([1e-5, 1e-3, 1e-1]) * sub.size, pen)
        e = float(np.min(errs))
        table.append({"n_position": n, "width_factor": wf, "cv_mse": e})
        if best is None or e < best[0]:
            best = (e, n, wf)
    if best is None:
        raise IdentifiabilityError(f"too few samples ({fit_idx.size}) for any position basis; use a longer log")
    return best[1], best[2], table


def fit_friction(t, Q, DQ, y, model: str = "nominal", joint: int = 0, ddq=None, holdout: float = 0.3,
                 nominal: str = "asymmetric", gear_ratio: float | None = None, coupling=None,
                 n_position: int | None = None, width_factor: float | None = None, n_motor: int = 36,
                 n_velocity: int = 6, selection: Selection | None = None, v_min=None, a_max=None,
                 energy_iters: int = 50, energy_init=None, truth: dict | None = None, joint_number=None,
                 joint_numbers=None, gravity: bool = False, energy_power: str = "measured") -> FrictionResult:
    """Fit the named model (see :func:`build_model`) to the friction torque ``y`` of
    data column ``joint`` and validate it on a held-out block.

    * ``y`` is the measured torque minus what the rigid-body model explains (or the
      raw torque for a single joint at constant velocity, (9.9));
    * samples are selected by :func:`select_steady` (or the given ``selection``);
    * the last ``holdout`` fraction of the log is held out; all fitting (including
      the choice of penalty/basis by cross-validation) uses the first part only;
    * energy models are fitted by Algorithm 6 and validated by simulating E forward
      over the whole log from the model alone (W = |F^ v|), so validation never
      sees measured torque.
    ``truth`` (names -> values) adds NPE (9.28) to the metrics. ``energy_power``: see
    :func:`drake_est.identification.energy.fit_energy`."""
    t = np.asarray(t, float).ravel()
    Q, DQ = _cols(Q, "q"), _cols(DQ, "dq")
    y = np.asarray(y, float).ravel()
    N = t.size
    if Q.shape[0] != N or DQ.shape[0] != N or y.size != N:
        raise DataError(f"t has {N} samples, q {Q.shape[0]}, dq {DQ.shape[0]}, torque {y.size}")
    if not np.all(np.isfinite(y)) or not np.all(np.isfinite(DQ)):
        raise DataError("torque or velocity contains NaN/inf")
    if N < 20:
        raise IdentifiabilityError(f"only {N} samples; too few to identify a friction model")
    if selection is None:
        selection = select_steady(DQ[:, joint], None if ddq is None else _cols(ddq, "ddq")[:, joint], t=t,
                                  v_min=v_min, a_max=a_max)
    sel = selection.mask
    train_idx, val_idx = split_holdout(N, holdout)
    in_train = np.zeros(N, bool)
    in_train[train_idx] = True
    fit_mask = sel & in_train
    val_mask = sel & ~in_train
    if fit_mask.sum() == 0:
        raise IdentifiabilityError(f"no samples left for identification: {selection.summary()}")
    if val_mask.sum() == 0:
        raise IdentifiabilityError("no selected samples in the held-out block; use a longer log or a smaller holdout")
    build_kw = dict(nominal=nominal, gear_ratio=gear_ratio, coupling=coupling, n_motor=n_motor,
                    n_velocity=n_velocity, joint_number=joint_number, joint_numbers=joint_numbers, gravity=gravity)
    structure = {"model": model, "nominal": nominal}
    base = model.replace("+energy", "") if model.endswith("+energy") else model
    if "position" in model and (n_position is None or width_factor is None):
        fit_idx = np.flatnonzero(fit_mask)
        cands = [(n, w) for n in ((n_position,) if n_position else (10, 20, 30))
                 for w in ((width_factor,) if width_factor else (1.0, 2.0))]
        n_position, width_factor, table = _choose_structure(base, Q, DQ, y, joint, fit_idx, build_kw, cands)
        structure["position_cv"] = table
    n_position = n_position or 16
    width_factor = width_factor or 1.0
    structure.update({"n_position": n_position, "width_factor": width_factor})
    # the grid spans the training data
    m = build_model(model, Q[fit_mask], DQ[fit_mask], joint=joint, n_position=n_position,
                    width_factor=width_factor, **build_kw)
    if m.energy is not None:
        from drake_est.identification.energy import fit_energy

        g0, t0 = (None, None) if energy_init is None else energy_init
        tr = slice(0, int(train_idx[-1]) + 1)
        if m.has_bfe and energy_init is None:
            # Sec. 9.4: estimate E with the simple nominal model first; start the extended model from it and
            # from the torque-envelope guess (9.27), and keep the run with the lower training output error
            # (a flexible expansion fitted before E is known can absorb the warm-up transient)
            m0 = build_model("energy", Q[fit_mask], DQ[fit_mask], joint=joint, **build_kw)
            e0 = fit_energy(m0, t[tr], Q[tr], DQ[tr], y[tr], mask=sel[tr], n_iter=energy_iters, power=energy_power)
            starts = [(m0.energy.gain, m0.energy.time_constant), (e0.initial["gain"], e0.initial["time_constant"])]
            structure["energy_stage1"] = {"gain": starts[0][0], "time_constant": starts[0][1], "initial": e0.initial}
            best = None
            for g0, t0 in starts:
                mc = m.copy()
                efc = fit_energy(mc, t[tr], Q[tr], DQ[tr], y[tr], mask=sel[tr], gain0=g0, tau0=t0,
                                 n_iter=energy_iters, power=energy_power)
                score = efc.history[-1]["rmse"]
                if best is None or score < best[0]:
                    best = (score, mc, efc)
            _, m, ef = best
        else:
            ef = fit_energy(m, t[tr], Q[tr], DQ[tr], y[tr], mask=sel[tr], gain0=g0, tau0=t0, n_iter=energy_iters,
                            power=energy_power)
        structure["energy_initial"] = ef.initial
        structure["energy_history"] = ef.history
        E_model = m.simulate_energy(Q, DQ)
        yhat = m.predict(Q, DQ, E_model)
        arrays_E = E_model
    else:
        m.fit(Q, DQ, y, mask=fit_mask)
        yhat = m.predict(Q, DQ)
        arrays_E = None
    p = m.n_params + (2 if m.energy is not None else 0)
    dof = m.info.get("dof", p) + (2 if m.energy is not None else 0)
    params = m.params()
    tr_metrics = evaluate(y[fit_mask], yhat[fit_mask], int(round(dof)), truth, params)
    va_metrics = evaluate(y[val_mask], yhat[val_mask], int(round(dof)), truth, params)
    structure["n_params"] = p
    structure["effective_params"] = float(dof)
    arrays = {"t": t, "q": Q[:, joint], "dq": DQ[:, joint], "y": y, "yhat": yhat, "selected": sel,
              "train": in_train, "E": arrays_E}
    return FrictionResult(model=m, selection=selection, train=tr_metrics, validation=va_metrics,
                          structure=structure, arrays=arrays)


def friction_target(log, joint_col: int, robot=None, inertia: bool = True):
    """The friction torque y of one joint from a :class:`drake_est.data.Log`: the
    measured torque minus the rigid-body torque when ``robot`` (a
    :class:`drake_est.robots.RobotModel` covering all logged joints) is given:
    ID(q, dq, ddq) with ``inertia``, else ID(q, dq, 0) (gravity, Coriolis and
    centrifugal torques only -- for constant-velocity data selected by (9.9), which
    avoids adding the noise of a differentiated acceleration)."""
    if log.tau is None:
        raise DataError("the log has no torque columns (tau<j>); friction cannot be identified")
    y = log.tau[:, joint_col].copy()
    if robot is not None:
        acc = log.ddq if inertia else np.zeros_like(log.q)
        idq = robot.inverse_dynamics_batch(log.q, log.dq, acc)
        y = y - idq[:, joint_col]
    return y


# --------------------------------------------------------------------------- multi-joint: friction + gravity

def gravity_regressor(plant, Q, context=None):
    """Gravity torque regressor of a MultibodyPlant: G(q) = Y(q) theta, linear in the
    mass-moment parameters theta = [m_b, m_b c_b] (4 per body, c_b the centre of mass
    in the body frame). For a body with origin Jacobian Jv and angular Jacobian Jw,
    the holding torque is G_b = -(Jv^T g m_b + Jw^T ((R m_b c_b) x g)).

    Returns (Y of shape (N, n, 4 B), names). Many columns are not identifiable from
    gravity alone (e.g. the base body's); :func:`fit_multi_joint` regularizes them."""
    from pydrake.multibody.tree import JacobianWrtVariable

    Q = _cols(Q, "q")
    ctx = context or plant.CreateDefaultContext()
    g = plant.gravity_field().gravity_vector()
    W = plant.world_frame()
    from pydrake.multibody.tree import BodyIndex

    bodies = [plant.get_body(BodyIndex(i)) for i in range(plant.num_bodies())
              if BodyIndex(i) != plant.world_body().index()]
    n = plant.num_velocities()
    if Q.shape[1] != plant.num_positions():
        raise DataError(f"plant has {plant.num_positions()} positions, data has {Q.shape[1]}")
    Y = np.zeros((Q.shape[0], n, 4 * len(bodies)))
    names = []
    for b in bodies:
        names += [f"m_{b.name()}", f"mcx_{b.name()}", f"mcy_{b.name()}", f"mcz_{b.name()}"]
    for k in range(Q.shape[0]):
        plant.SetPositions(ctx, Q[k])
        for bi, b in enumerate(bodies):
            F = b.body_frame()
            Jv = plant.CalcJacobianTranslationalVelocity(ctx, JacobianWrtVariable.kV, F, np.zeros(3), W, W)
            Jw = plant.CalcJacobianAngularVelocity(ctx, JacobianWrtVariable.kV, F, W, W)
            R = F.CalcRotationMatrixInWorld(ctx).matrix()
            Y[k, :, 4 * bi] = -(Jv.T @ g)
            for c in range(3):
                Y[k, :, 4 * bi + 1 + c] = -(Jw.T @ np.cross(R[:, c], g))
    return Y, names


@dataclass
class MultiJointFit:
    """Result of :func:`fit_multi_joint`."""

    models: list            # JointFriction per joint column
    gravity_coef: np.ndarray
    gravity_names: list
    gravity_rank: int
    train: dict
    validation: dict

    def gravity(self, Y) -> np.ndarray:
        return np.asarray(Y) @ self.gravity_coef


def fit_multi_joint(Q, DQ, TAU, Y, joints=None, nominal: str = "viscous", mask=None, holdout: float = 0.3,
                    lam_gravity: float = 1e-6, gravity_names=None):
    """All joints at once (Sec. 9.2, "Estimation in multi-joint robots"): friction of
    each joint in ``joints`` (0-based columns, default all) together with a gravity
    model G(q) = Y(q) theta shared by all joints:

        tau_j = F_j(q, dq) + [Y(q) theta]_j        for every joint j.

    ``TAU``: (N, n) torque minus any known inertial/Coriolis torque; ``Y``: (N, n, p)
    from :func:`gravity_regressor`. The gravity parameters carry a tiny ridge penalty
    (``lam_gravity`` per row) so that unidentifiable combinations stay finite; their
    numerical rank is reported. Samples in ``mask`` (N,) or (N, n) are used; the
    last ``holdout`` fraction is held out."""
    Q, DQ, TAU = _cols(Q, "q"), _cols(DQ, "dq"), _cols(TAU, "tau")
    N, n = Q.shape
    Y = np.asarray(Y, float)
    if Y.shape[:2] != (N, n):
        raise DataError(f"gravity regressor has shape {Y.shape}, expected ({N}, {n}, p)")
    joints = list(range(n)) if joints is None else list(joints)
    M = np.ones((N, n), bool) if mask is None else np.asarray(mask, bool)
    if M.ndim == 1:
        M = np.repeat(M[:, None], n, axis=1)
    train_idx, val_idx = split_holdout(N, holdout)
    models = [JointFriction(nominal_terms(nominal), joint=j, lam=0.0, name="nominal") for j in joints]
    blocks = [m.regressors(Q, DQ)[0] for m in models]
    p_f = [b.shape[1] for b in blocks]
    P = sum(p_f) + Y.shape[2]

    def stack(idx):
        rows, ys = [], []
        off = 0
        for jj, (j, B) in enumerate(zip(joints, blocks)):
            use = idx[M[idx, j]]
            A = np.zeros((use.size, P))
            A[:, off:off + p_f[jj]] = B[use]
            A[:, sum(p_f):] = Y[use, j, :]
            rows.append(A)
            ys.append(TAU[use, j])
            off += p_f[jj]
        return np.vstack(rows), np.concatenate(ys)

    A, yv = stack(train_idx)
    if A.shape[0] < P:
        raise IdentifiabilityError(f"{A.shape[0]} samples for {P} friction + gravity parameters")
    for jj, (j, B) in enumerate(zip(joints, blocks)):
        use = train_idx[M[train_idx, j]]
        _check_identifiable(B[use], models[jj].names, np.zeros(p_f[jj]), models[jj].terms, DQ[use, j])
    pen = np.r_[np.zeros(sum(p_f)), np.ones(Y.shape[2])]
    # scale gravity columns so that the penalty is relative
    scale = np.r_[np.ones(sum(p_f)), np.maximum(np.linalg.norm(A[:, sum(p_f):], axis=0), 1e-12)]
    res = ridge_fit(A / scale, yv, lam_gravity * A.shape[0], penalize=pen)
    coef = res.coef / scale
    sv = np.linalg.svd(A[:, sum(p_f):] / scale[sum(p_f):], compute_uv=False)
    rank = int(np.sum(sv > 1e-8 * sv[0])) if sv.size else 0
    off = 0
    for jj, m in enumerate(models):
        m.coef = coef[off:off + p_f[jj]]
        off += p_f[jj]
    theta = coef[sum(p_f):]

    def metrics(idx):
        yy, yh = [], []
        for jj, j in enumerate(joints):
            use = idx[M[idx, j]]
            yy.append(TAU[use, j])
            yh.append(models[jj].predict(Q[use], DQ[use]) + Y[use, j, :] @ theta)
        return evaluate(np.concatenate(yy), np.concatenate(yh), sum(p_f) + rank)

    return MultiJointFit(models=models, gravity_coef=theta, gravity_names=list(gravity_names or []), gravity_rank=rank,
                         train=metrics(train_idx), validation=metrics(val_idx))
