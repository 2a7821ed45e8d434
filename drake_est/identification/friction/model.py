"""``JointFriction``: a list of terms fitted to one joint by ridge least squares (Eq. (6.8)),
prediction, energy simulation and JSON (de)serialization."""
from __future__ import annotations

import copy

import numpy as np

from drake_est.errors import DataError, DrakeEstError, IdentifiabilityError
from drake_est.joints import index_to_joint, joint_to_index, resolve_index
from drake_est.regression import check_excitation, ridge_cv, ridge_fit, ridge_gram_dof, ridge_gram_solve

from drake_est.identification.friction.extensions import term_from_dict
from drake_est.identification.friction.terms import (AsymmetricCoulomb, BFETerm, Coulomb, EnergyDynamics, Viscous,
                                                     _cols, _sign)

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
    index : 0-based column of the joint in the (N, n) data arrays handed to fit/predict.
    joint : deprecated spelling of ``index`` (a 0-based column; DeprecationWarning) -- in drake_est
        ``joint`` means a 1-based joint number, which is ``joint_number`` here.
    lam : ridge penalty on penalized (basis-function) columns; "cv" chooses it by
        contiguous 5-fold cross-validation in :meth:`fit`.
    energy : :class:`EnergyDynamics` or None.
    joint_number : the 1-based robot joint number (metadata only).
    energy_additive : True (identification, (9.22)): F = F_n + sign(v) E; False (a diagnosed energy
        effect): E is only an input of the terms that read it (``needs_energy``), e.g. sign(v) E with a
        fitted coefficient and a unit-gain ``energy``.
    torque_limit : optional bound |F| <= torque_limit [N m] on the predicted torque (diagnosed models
        clip at 1.5 x the largest torque seen, instead of extrapolating).
    """

    def __init__(self, terms, joint: int | None = None, lam="cv", energy: EnergyDynamics | None = None,
                 joint_number: int | None = None, name: str = "", energy_additive: bool = True,
                 torque_limit: float | None = None, index: int | None = None):
        self.terms = list(terms)
        if not self.terms:
            raise DrakeEstError("a friction model needs at least one term")
        self.index = resolve_index(index, joint, "JointFriction")
        self.lam = lam
        self.energy = energy
        self.joint_number = joint_number
        self.name = name
        self.coef = None
        self.info = {}
        self.energy_additive = bool(energy_additive)
        self.torque_limit = None if torque_limit is None else float(torque_limit)

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

    @property
    def needs_time(self) -> bool:
        return any(t.needs_time for t in self.terms)

    @property
    def needs_energy(self) -> bool:
        return self.energy is not None or any(t.needs_energy for t in self.terms)

    def regressors(self, Q, DQ, E=None, sign_eps: float = 0.0, t=None):
        """Regressor matrix A (N, p) and the column names (``t``: time [s], for terms that need it)."""
        Q, DQ = _cols(Q, "q"), _cols(DQ, "dq")
        if Q.shape != DQ.shape:
            raise DataError(f"q has shape {Q.shape} but dq has {DQ.shape}")
        if not 0 <= self.index < Q.shape[1]:
            raise DataError(f"joint column {self.index} not in data with {Q.shape[1]} joints")
        A = np.hstack([tm.columns(Q, DQ, self.index, E, sign_eps, t=t) if tm.needs_time
                       else tm.columns(Q, DQ, self.index, E, sign_eps) for tm in self.terms])
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
        _check_identifiable(A, names, self.penalize, self.terms, DQ[mask, self.index] if mask is not None
                            else DQ[:, self.index])
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

    def predict_nominal(self, Q, DQ, E=None, sign_eps: float = 0.0, t=None) -> np.ndarray:
        """F_n(q, dq[, E]): the linear part, without the sign(v) E term."""
        self._check_fitted()
        A, _ = self.regressors(Q, DQ, E, sign_eps, t)
        return A @ self.coef

    def simulate_energy(self, Q, DQ, E0: float | None = None) -> np.ndarray:
        """Run the energy state forward over the samples (assumed uniformly spaced
        at the model's h): W[k] = |F[k] v[k]|, E[k+1] = a E[k] + b W[k]."""
        if self.energy is None:
            raise DrakeEstError("model has no energy dynamics")
        self._check_fitted()
        Q, DQ = _cols(Q, "q"), _cols(DQ, "dq")
        N = Q.shape[0]
        v = DQ[:, self.index]
        s = np.sign(v)
        a, b = self.energy.pole, self.energy.discrete_gain
        E = np.empty(N)
        e = self.energy.E0 if E0 is None else float(E0)
        if any(t.needs_energy for t in self.terms):
            for k in range(N):
                E[k] = e
                f = float(self.predict_nominal(Q[k:k + 1], DQ[k:k + 1], np.array([e]))[0])
                f += s[k] * e if self.energy_additive else 0.0
                e = a * e + b * abs(f * v[k])
        else:
            Fn = self.predict_nominal(Q, DQ)
            for k in range(N):
                E[k] = e
                e = a * e + b * abs((Fn[k] + s[k] * e) * v[k])
        return E

    def predict(self, Q, DQ, E=None, sign_eps: float = 0.0, t=None) -> np.ndarray:
        """Friction torque F [N m]. For an energy model, ``E`` is the energy signal;
        when omitted it is simulated from the data (:meth:`simulate_energy`). ``t`` [s]: the time of
        each sample, for terms that need it (abrupt change)."""
        self._check_fitted()
        if self.energy is not None and E is None:
            E = self.simulate_energy(Q, DQ)
        F = self.predict_nominal(Q, DQ, E, sign_eps, t)
        if self.energy is not None and self.energy_additive:
            F = F + _sign(_cols(DQ, "dq")[:, self.index], sign_eps) * np.asarray(E, dtype=float).ravel()
        if self.torque_limit is not None:
            F = np.clip(F, -self.torque_limit, self.torque_limit)
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
        return {"format": "drake_est.friction/2", "name": self.name, "joint": self.joint_number_or_index(),
                "index": self.index, "joint_number": self.joint_number, "terms": [t.to_dict() for t in self.terms],
                "names": self.names, "coef": np.asarray(self.coef).tolist(), "lam": self.info.get("lam", 0.0),
                "params": self.params(), "energy": None if self.energy is None else self.energy.to_dict(),
                "sign_convention": "tau_measured = ID(q, dq, ddq) + F; F has the sign of the velocity",
                **({} if self.energy_additive else {"energy_additive": False}),
                **({} if self.torque_limit is None else {"torque_limit": self.torque_limit})}

    @classmethod
    def from_dict(cls, d: dict) -> "JointFriction":
        fmt = d.get("format")
        if fmt == "drake_est.friction/2":     # "joint": 1-based joint number, "index": 0-based data column
            index = int(d.get("index", joint_to_index(d.get("joint", 1), None, "model 'joint'")))
        elif fmt == "drake_est.friction/1":   # before issue #18: "joint" was the 0-based data column
            index = int(d.get("joint", 0))
        else:
            raise DataError("not a drake_est friction model (missing format 'drake_est.friction/2')")
        m = cls([term_from_dict(t) for t in d["terms"]], index=index, lam=d.get("lam", 0.0),
                energy=None if d.get("energy") is None else EnergyDynamics.from_dict(d["energy"]),
                joint_number=d.get("joint_number"), name=d.get("name", ""),
                energy_additive=d.get("energy_additive", True), torque_limit=d.get("torque_limit"))
        m.coef = np.asarray(d["coef"], dtype=float)
        if m.coef.size != m.n_params:
            raise DataError(f"friction model has {m.coef.size} coefficients for {m.n_params} regressors")
        return m

    @property
    def joint(self) -> int:
        """Deprecated read alias of :attr:`index` (the 0-based data column)."""
        return self.index

    @joint.setter
    def joint(self, value):
        self.index = int(value)

    def joint_number_or_index(self) -> int:
        """The 1-based joint number: ``joint_number`` when known, else the data column + 1."""
        return int(self.joint_number) if self.joint_number is not None else index_to_joint(self.index)

    def copy(self) -> "JointFriction":
        return copy.deepcopy(self)

    @classmethod
    def coulomb_viscous(cls, kc, kv, joint: int | None = None, kc_minus=None, joint_number=None,
                        index: int | None = None) -> "JointFriction":
        """A fixed (not fitted) Coulomb + viscous model (9.2), or direction-dependent
        (9.3) when ``kc_minus`` is given (then ``kc`` is kc+). ``index``: 0-based data column."""
        index = resolve_index(index, joint, "JointFriction.coulomb_viscous")
        if kc_minus is None:
            m = cls([Viscous(), Coulomb()], index=index, lam=0.0, joint_number=joint_number, name="nominal")
            m.coef = np.array([kv, kc], dtype=float)
        else:
            m = cls([Viscous(), AsymmetricCoulomb()], index=index, lam=0.0, joint_number=joint_number,
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
