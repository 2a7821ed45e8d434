"""``FrictionModel``: identified joint friction as a Drake ``LeafSystem``.

Ports
-----
* input ``joint_positions`` (n,) [rad]
* input ``joint_velocities`` (n,) [rad/s]
* output ``friction_torques`` (n,) [N m]

Sign convention: the output is the friction torque F of the identification
(thesis Eq. (9.8)): the torque the motor must supply to overcome friction, so that
the measured motor torque is ``tau = ID(q, dq, ddq) + F``; F has the sign of the
velocity. The torque friction exerts on the joint is ``-F``: to simulate a plant
with this friction, feed ``u - F`` into its actuation input (e.g. through
``Gain(-1)`` and an ``Adder``), see :func:`add_friction`.

Each joint's friction is any :class:`drake_est.identification.friction.JointFriction`
(Coulomb + viscous (9.2), direction-dependent Coulomb (9.3), position / motor-position
expansions, gear-coupled wrist terms, energy models). Energy models (9.22)-(9.24) keep
their signal E in a discrete state (one entry per joint), updated periodically with the
ZOH recursion E <- a E + k_e (1 - a) |F v| driven by the friction power.

The Coulomb term sign(v) is discontinuous; for continuous-time integration pass
``sign_eps > 0`` [rad/s] to use tanh(v / sign_eps) instead (identification always
uses the exact sign).
"""
from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
from pydrake.autodiffutils import AutoDiffXd
from pydrake.systems.framework import LeafSystem, LeafSystem_
from pydrake.systems.scalar_conversion import TemplateSystem

from drake_est.errors import DataError, DrakeEstError
from drake_est.identification.friction import JointFriction
from drake_est.joints import index_to_joint, joint_to_index


PARAMS_FORMAT = "drake_est.friction_model/2"


def _value(x) -> float:
    """A float from a float or AutoDiffXd scalar (e.g. the Context's time)."""
    return float(x.value()) if hasattr(x, "value") else float(x)


def _as_models(models, n_joints):
    if isinstance(models, JointFriction):
        models = [models]
    if isinstance(models, dict):
        # keys are 1-based joint numbers (issue #18); converted to 0-based indices here
        keys = list(models)
        if n_joints is None:
            n_joints = max(joint_to_index(k, None, "friction model key") for k in keys) + 1 if keys else 0
        out = [None] * n_joints
        for k, m in models.items():
            out[joint_to_index(k, n_joints, "friction model key (a 1-based joint number)")] = m
        models = out
    models = list(models)
    if n_joints is None:
        n_joints = len(models)
    if len(models) != n_joints:
        raise DrakeEstError(f"{len(models)} friction models for {n_joints} joints")
    fixed = []
    for index, m in enumerate(models):
        if m is None:
            fixed.append(None)
            continue
        if isinstance(m, dict):
            m = JointFriction.from_dict(m)
        if not isinstance(m, JointFriction):
            raise DrakeEstError(f"joint {index_to_joint(index)}: expected a JointFriction or its dict, "
                                f"got {type(m).__name__}")
        if m.coef is None:
            raise DrakeEstError(f"joint {index_to_joint(index)}: friction model is not fitted")
        m = m.copy()
        m.index = index  # the model reads its own joint from column `index` of the plant's q, dq
        fixed.append(m)
    return fixed, n_joints


def _fd_columns(term, Q, DQ, j, E, sign_eps, t):
    """Columns of ``term`` at AutoDiffXd inputs for terms without an object-array path (e.g. the
    basis-function expansions of Sec. 6.3): values from the float columns, derivatives by the chain rule
    with d(columns)/d(inputs) from central differences of the float columns (relative step 1e-6)."""
    ins = [Q[0], DQ[0]] + ([np.asarray(E).ravel()] if E is not None else [])
    vals = [np.array([_value(x) for x in a]) for a in ins]
    grads = [[np.asarray(x.derivatives(), float) if hasattr(x, "derivatives") else np.zeros(0) for x in a]
             for a in ins]
    nd = max((g.size for gs in grads for g in gs), default=0)

    def cols(vs):
        Ef = vs[2] if E is not None else None
        if term.needs_time:
            return term.columns(vs[0][None], vs[1][None], j, Ef, sign_eps, t=t)[0]
        return term.columns(vs[0][None], vs[1][None], j, Ef, sign_eps)[0]

    c0 = np.asarray(cols(vals), float)
    D = np.zeros((c0.size, nd))
    for a, (va, ga) in enumerate(zip(vals, grads)):
        for i, g in enumerate(ga):
            if g.size == 0 or not np.any(g):
                continue
            h = 1e-6 * (1.0 + abs(va[i]))
            up = [x.copy() for x in vals]
            dn = [x.copy() for x in vals]
            up[a][i] += h
            dn[a][i] -= h
            D += np.outer((np.asarray(cols(up), float) - np.asarray(cols(dn), float)) / (2 * h), g)
    return np.array([[AutoDiffXd(c0[k], D[k]) for k in range(c0.size)]], dtype=object)


def _object_friction(model, q, v, E, t: float, sign_eps: float):
    """F of one joint for AutoDiffXd (n,) object arrays ``q``, ``v``, ``E``: the same regressor columns as
    :meth:`JointFriction.predict` times the fitted coefficients.  Each term's ``columns`` runs on the object
    arrays (exact derivatives through Coulomb (9.1), viscous (9.2), direction-dependent (9.3), gravity,
    gear-coupled (9.12) terms); terms without an object-array path (basis-function expansions) get
    derivatives from central differences (:func:`_fd_columns`). Use ``sign_eps > 0``: sign(v) has no
    useful derivative."""
    Q, DQ = q.reshape(1, -1), v.reshape(1, -1)
    Ej = None if E is None else E[model.index:model.index + 1]
    tj = np.array([t])
    blocks = []
    for tm in model.terms:
        try:
            c = (tm.columns(Q, DQ, model.index, Ej, sign_eps, t=tj) if tm.needs_time
                 else tm.columns(Q, DQ, model.index, Ej, sign_eps))
        except (TypeError, ValueError, AttributeError):
            c = _fd_columns(tm, Q, DQ, model.index, Ej, sign_eps, tj)
        blocks.append(np.asarray(c, dtype=object).reshape(1, -1))
    F = (np.hstack(blocks) @ np.asarray(model.coef, float))[0]
    if model.energy is not None and model.energy_additive:
        vj = v[model.index]
        F = F + (np.tanh(vj / sign_eps) if sign_eps > 0 else np.sign(vj)) * E[model.index]
    if model.torque_limit is not None:
        lim = float(model.torque_limit)
        F = min(max(F, -lim), lim)
    return F


@TemplateSystem.define("FrictionModel_", T_list=(float, AutoDiffXd))
def FrictionModel_(T):

    class Impl(LeafSystem_[T]):
        """Joint friction torques F(q, dq[, E, t]) [N m] of ``n_joints`` joints (thesis Ch. 9).

        Ports: inputs ``joint_positions`` (n,) [rad] and ``joint_velocities`` (n,) [rad/s]; output
        ``friction_torques`` (n,) [N m].  Energy models keep E [N m] as discrete state in the Context.
        Scalar types float and AutoDiffXd (``ToAutoDiffXd()``), so a plant with friction can be
        differentiated (iLQR); use ``sign_eps > 0`` there.

        Parameters
        ----------
        models : list (length n_joints, in joint order) of JointFriction / its dict / None (no friction),
            or a dict {1-based joint number: model}, or a single model for a 1-joint system.
        n_joints : number of joints (default: from ``models``).
        sign_eps : smoothing velocity for sign(v) [rad/s]; 0 = exact sign.
        energy_period : update period of the energy state [s] (default: the energy model's h).
        """

        def _construct(self, models, n_joints: int | None = None, sign_eps: float = 0.0,
                       energy_period: float | None = None, converter=None):
            LeafSystem_[T].__init__(self, converter)
            self._models, n = _as_models(models, n_joints)
            self._n = n
            self._sign_eps = float(sign_eps)
            self._energy_period = energy_period
            self._positions = self.DeclareVectorInputPort("joint_positions", n)
            self._velocities = self.DeclareVectorInputPort("joint_velocities", n)
            self._torques = self.DeclareVectorOutputPort("friction_torques", n, self._calc_torques)
            self._energy_joints = [j for j, m in enumerate(self._models) if m is not None and m.energy is not None]
            self._E_index = None
            if self._energy_joints:
                hs = [self._models[j].energy.h for j in self._energy_joints]
                period = float(energy_period) if energy_period is not None else float(min(hs))
                if period <= 0:
                    raise DrakeEstError(f"energy update period must be positive, got {period}")
                self._period = period
                E0 = np.zeros(n)
                for j in self._energy_joints:
                    E0[j] = self._models[j].energy.E0
                self._E_index = self.DeclareDiscreteState(E0)
                self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update_energy)
                # ZOH coefficients at the update period (which may differ from the identification h)
                self._ab = {}
                for j in self._energy_joints:
                    e = self._models[j].energy
                    a = float(np.exp(-period / e.time_constant))
                    self._ab[j] = (a, e.gain * (1.0 - a))

        def _construct_copy(self, other, converter=None):
            Impl._construct(self, other._models, other._n, other._sign_eps, other._energy_period,
                            converter=converter)

        # ------------------------------------------------------------------ helpers
        @property
        def n_joints(self) -> int:
            return self._n

        @property
        def models(self) -> list:
            return list(self._models)

        def get_joint_positions_input_port(self):
            return self._positions

        def get_joint_velocities_input_port(self):
            return self._velocities

        def get_friction_torques_output_port(self):
            return self._torques

        def _E(self, context):
            if self._E_index is None:
                return np.zeros(self._n)
            return context.get_discrete_state(self._E_index).CopyToVector()

        def _friction_T(self, q, v, E, t):
            """:meth:`friction` for the system's scalar type (float: exactly :meth:`friction`)."""
            if T is float:
                return self.friction(q, v, E, t)
            F = np.array([T(0.0)] * self._n, dtype=object)
            for j, m in enumerate(self._models):
                if m is not None:
                    F[j] = _object_friction(m, q, v, E if m.needs_energy else None, float(t), self._sign_eps)
            return F

        def friction(self, q, v, E=None, t: float = 0.0) -> np.ndarray:
            """F(q, v, E, t) for one configuration (n,) -- the same numbers as the output port
            (``t`` [s]: time, read by time-dependent terms such as a diagnosed abrupt change)."""
            q = np.asarray(q, float).reshape(1, -1)
            v = np.asarray(v, float).reshape(1, -1)
            if q.shape[1] != self._n or v.shape[1] != self._n:
                raise DataError(f"expected {self._n} joint positions/velocities, got {q.shape[1]}/{v.shape[1]}")
            E = np.zeros(self._n) if E is None else np.asarray(E, float)
            F = np.zeros(self._n)
            for j, m in enumerate(self._models):
                if m is None:
                    continue
                Ej = np.array([E[j]]) if m.needs_energy else None
                tj = np.array([t]) if m.needs_time else None
                F[j] = float(m.predict(q, v, Ej, sign_eps=self._sign_eps, t=tj)[0])
            return F

        # ------------------------------------------------------------------ callbacks
        def _qv(self, context):
            return self._positions.Eval(context), self._velocities.Eval(context)

        def _calc_torques(self, context, output):
            q, v = self._qv(context)
            output.SetFromVector(self._friction_T(q, v, self._E(context), _value(context.get_time())))

        def _update_energy(self, context, discrete_state):
            q, v = self._qv(context)
            E = self._E(context)
            F = self._friction_T(q, v, E, _value(context.get_time()))
            Enew = E.copy()
            for j in self._energy_joints:
                a, b = self._ab[j]
                Enew[j] = a * E[j] + b * abs(F[j] * v[j])   # E <- a E + k_e (1 - a) W,  W = |F v|  (9.21), (9.24)
            discrete_state.get_mutable_vector(self._E_index).SetFromVector(Enew)

        # ------------------------------------------------------------------ constructors
        @classmethod
        def coulomb_viscous(cls, kc, kv, kc_minus=None, sign_eps: float = 0.0) -> "FrictionModel":
            """Plain Coulomb + viscous friction (9.2) per joint, or direction-dependent
            Coulomb (9.3) when ``kc_minus`` is given (``kc`` is then kc+). Arrays of length n [N m], [N m s/rad]."""
            kc = np.atleast_1d(np.asarray(kc, float))
            kv = np.atleast_1d(np.asarray(kv, float))
            if kc.shape != kv.shape:
                raise DrakeEstError(f"kc has {kc.size} entries, kv has {kv.size}")
            km = None if kc_minus is None else np.atleast_1d(np.asarray(kc_minus, float))
            if km is not None and km.shape != kc.shape:
                raise DrakeEstError(f"kc_minus has {km.size} entries, kc has {kc.size}")
            models = [JointFriction.coulomb_viscous(kc[j], kv[j], index=j, kc_minus=None if km is None else km[j])
                      for j in range(kc.size)]
            return cls(models, sign_eps=sign_eps)

        def to_params(self) -> dict:
            """The models as a JSON-able ``params.json`` dict: ``{"format": "drake_est.friction_model/2",
            "n_joints": n, "models": {"<1-based joint number>": model dict}}`` (:meth:`from_json` reads it)."""
            return {"format": PARAMS_FORMAT, "n_joints": self._n,
                    "models": {str(index_to_joint(i)): m.to_dict() for i, m in enumerate(self._models) if m is not None}}

        @classmethod
        def from_params(cls, d: dict, n_joints: int | None = None, sign_eps: float = 0.0, source: str = "params") -> "FrictionModel":
            """Build from a params dict: :meth:`to_params`'s format, ``drake-est fit-friction``'s ``params.json``
            (``{"model": ...}``, placed at its 1-based joint number), or a single model dict.

            Files written before issue #18 keyed ``models`` by 0-based index (no ``format``): they are
            still read, as 0-based indices, with a ``DeprecationWarning`` (re-save with :meth:`to_params`)."""
            if "models" in d:
                if d.get("format") == PARAMS_FORMAT:
                    models = {int(k): v for k, v in d["models"].items()}
                    n_joints = n_joints if n_joints is not None else d.get("n_joints")
                else:
                    warnings.warn(f"{source}: friction models keyed by 0-based index (written before drake_est "
                                  f"issue #18); read as indices 0.. -- re-save with FrictionModel.to_params() to get "
                                  f"1-based joint keys", DeprecationWarning, stacklevel=3)
                    models = {int(k) + 1: v for k, v in d["models"].items()}
            else:
                m = d["model"] if "model" in d else d
                models = {JointFriction.from_dict(m).joint_number_or_index(): m}
            return cls(models, n_joints=n_joints, sign_eps=sign_eps)

        @classmethod
        def from_json(cls, path, n_joints: int | None = None, sign_eps: float = 0.0) -> "FrictionModel":
            """Load models written by ``drake-est fit-friction`` or :meth:`to_params` (see :meth:`from_params`)."""
            try:
                d = json.loads(Path(path).read_text())
            except (OSError, ValueError) as e:
                raise DataError(f"cannot read friction params {path}: {e}") from None
            return cls.from_params(d, n_joints=n_joints, sign_eps=sign_eps, source=str(path))

        def write_json(self, path) -> Path:
            """Write :meth:`to_params` as ``params.json`` (no NaN/Inf)."""
            from drake_est.jsonutil import dump_json
            return dump_json(self.to_params(), path)


    return Impl


FrictionModel = FrictionModel_[None]


class TrueJointFriction(LeafSystem):
    """Applies the synthetic logs' :class:`~drake_est.identification.friction.truth.FrictionTruth` to a
    plant, with the ports of :class:`FrictionModel`: inputs ``joint_positions`` (n,) [rad] and
    ``joint_velocities`` (n,) [rad/s], output ``friction_torques`` (n,) [N m]; continuous state E
    [N m] (energy effect, (9.23)), so the whole truth lives in the Context."""

    def __init__(self, truth):
        super().__init__()
        self._truth = truth
        n = len(truth.kc)
        self._n = n
        self._positions = self.DeclareVectorInputPort("joint_positions", n)
        self._velocities = self.DeclareVectorInputPort("joint_velocities", n)
        self._has_energy = bool(truth.energy)
        if self._has_energy:
            self.DeclareContinuousState(n)
        self._torques = self.DeclareVectorOutputPort("friction_torques", n, self._calc_torque)

    def get_joint_positions_input_port(self):
        return self._positions

    def get_joint_velocities_input_port(self):
        return self._velocities

    def get_friction_torques_output_port(self):
        return self._torques

    def _qv(self, context):
        return self._positions.Eval(context), self._velocities.Eval(context)

    def _calc_torque(self, context, output):
        q, v = self._qv(context)
        E = context.get_continuous_state_vector().CopyToVector() if self._has_energy else None
        output.SetFromVector(self._truth.torque(q, v, context.get_time(), E))

    def DoCalcTimeDerivatives(self, context, derivatives):
        if not self._has_energy:
            return
        q, v = self._qv(context)
        E = context.get_continuous_state_vector().CopyToVector()
        F = self._truth.torque(q, v, context.get_time(), E)
        derivatives.get_mutable_vector().SetFromVector(self._truth.energy_rate(F, v, E))


def add_friction(builder, plant, friction: FrictionModel, actuation_source=None):
    """Wire ``friction`` into ``plant``: its positions/velocities feed the friction
    model and ``-F`` (plus ``actuation_source``'s output port, if given) drives the
    plant's actuation. Returns the Adder (or Gain) that feeds the actuation.

    A thin wrapper over :func:`drake_est.systems.builders.AddJointFriction` (the one builder set)
    that first checks the plant and the friction model have the same number of joints."""
    from drake_est.systems.builders import AddJointFriction

    n = friction.n_joints
    if plant.num_positions() != n or plant.num_velocities() != n:
        raise DrakeEstError(f"plant has {plant.num_positions()} positions, friction model has {n} joints")
    return AddJointFriction(builder, plant, friction, actuation_source=actuation_source).actuation


class DiagnosedFriction(LeafSystem):
    """Drake system of a diagnosed friction model with the *measured* energy history (used by the
    windowed simulation error; :func:`drake_est.diagnose.friction_system` gives the
    :class:`~drake_est.systems.friction.FrictionModel` of the same models, with the energy as state).

    Input ports ``joint_positions`` [rad] and ``joint_velocities`` [rad/s] (robot coordinates);
    output ``friction_torques`` [N m] (the torque the actuators spend on friction; feed its
    negative to the plant). Time enters through the Context (abrupt change, energy history).

    ``law`` is any object with ``log_joints`` (the log's 1-based joint numbers) and
    ``friction(t, q, v)`` on log-joint vectors (:class:`drake_est.diagnose.simulate.FrictionLaw`);
    ``robot_cols`` maps a log joint to its index in the robot's joint vector."""

    def __init__(self, law, n_robot: int, robot_cols: dict):
        super().__init__()
        self._law = law
        self._n = n_robot
        self._map = [(law.log_joints.index(j), robot_cols[j]) for j in law.log_joints if j in robot_cols]
        self._positions = self.DeclareVectorInputPort("joint_positions", n_robot)
        self._velocities = self.DeclareVectorInputPort("joint_velocities", n_robot)
        self._torques = self.DeclareVectorOutputPort("friction_torques", n_robot, self._calc)

    def get_joint_positions_input_port(self):
        return self._positions

    def get_joint_velocities_input_port(self):
        return self._velocities

    def get_friction_torques_output_port(self):
        return self._torques

    def _calc(self, context, output):
        qr = self._positions.Eval(context)
        vr = self._velocities.Eval(context)
        m = len(self._law.log_joints)
        q, v = np.zeros(m), np.zeros(m)
        for c, rc in self._map:
            q[c], v[c] = qr[rc], vr[rc]
        F = self._law.friction(context.get_time(), q, v)
        out = np.zeros(self._n)
        for c, rc in self._map:
            out[rc] = F[c]
        output.SetFromVector(out)


def contract_cases():
    """FrictionModel (Coulomb + viscous, direction-dependent, and an energy model with discrete state)
    and TrueJointFriction; expected outputs from the plain models (JointFriction.predict, FrictionTruth.torque)."""
    from drake_est.identification.friction import EnergyDynamics, JointFriction
    from drake_est.identification.friction.truth import FrictionTruth
    from drake_est.systems.contract import ContractCase

    q = np.array([0.3, -0.4])
    v = np.array([0.5, -0.2])
    inputs = {"joint_positions": q, "joint_velocities": v}

    def make_cv():
        return FrictionModel.coulomb_viscous([2.0, 1.5], [0.8, 0.4], kc_minus=[1.8, 1.2])

    def cv_expected(s):
        return {"friction_torques": [float(m.predict(q[None], v[None])[0]) for m in s.models]}

    def make_energy():
        m = JointFriction.coulomb_viscous(2.0, 0.8, index=0)
        m.energy = EnergyDynamics(gain=0.05, time_constant=0.5, h=0.01)
        return FrictionModel([m, None], sign_eps=0.01)

    truth = FrictionTruth(kc=np.array([2.0, 1.0]), kv=np.array([0.8, 0.3]), kc_neg=np.array([1.7, 0.9]),
                          bumps={0: (np.array([0.2]), np.array([0.3]), np.array([0.5]))})

    def truth_expected(s):
        return {"friction_torques": truth.torque(q, v, 0.05)}

    class _Law:                                   # a stand-in for diagnose.simulate.FrictionLaw
        log_joints = [2, 1]

        def __init__(self):
            self.m = [JointFriction.coulomb_viscous(1.0, 0.5, index=0), JointFriction.coulomb_viscous(2.0, 0.2, index=0)]

        def friction(self, t, q, v):
            return np.array([float(m.predict(q[None, c:c + 1], v[None, c:c + 1])[0]) * (1.0 + t)
                             for c, m in enumerate(self.m)])

    def make_diag():
        return DiagnosedFriction(_Law(), 2, {1: 0, 2: 1})

    def diag_expected(s):
        F = _Law().friction(0.05, np.array([q[1], q[0]]), np.array([v[1], v[0]]))
        return {"friction_torques": [F[1], F[0]]}

    return [ContractCase(make_cv, inputs, expected=cv_expected, label="coulomb_viscous"),
            ContractCase(make_diag, inputs, expected=diag_expected, label="diagnosed (time-varying law)"),
            ContractCase(make_energy, inputs, t_final=0.05, label="energy state"),
            ContractCase(lambda: TrueJointFriction(truth), inputs, expected=truth_expected, label="truth")]
