"""Simulation error (thesis Sec. 3.1): run the plant forward with the *measured* torque through
the nominal and the extended model and compare the simulated and measured joint velocities.

An open-loop simulation of a robot driven by recorded torques drifts away (integrated torque
errors, unstable gravity), so the comparison uses short windows (default 2 s) that start from the
measured state, as multiple-shooting does; the simulation error is the RMS of the velocity error
over windows spread evenly over the log.

* robot (IRB 140 / URDF): a Drake ``Diagram`` with the continuous ``MultibodyPlant`` (the extended
  one carries the identified payload), a :class:`DiagnosedFriction` ``LeafSystem`` and the measured
  torque as a first-order-hold ``TrajectorySource``; Drake's ``Simulator`` integrates it;
* generic: each axis J qdd = tau - F(q, qd) integrated by classical Runge-Kutta (RK4).

The energy state of the energy-dependent friction model is taken from the measured history (it
is a slow, minutes-long state), i.e. E(t) is an input of the friction system, as is time for the
abrupt-change model.

Several logs of one machine (:mod:`drake_est.diagnose.multilog`): every window lies inside one log, the
friction in it carries that log's own Coulomb/viscous offsets [dkv_k, dkc_k] (the same numbers the held-out
comparison used), and the energy state restarts at each log's first sample.
"""
from __future__ import annotations

import numpy as np

from drake_est.diagnose.multilog import log_starts, unit_energy_per_log
from drake_est.diagnose.nominal import nominal_names
from drake_est.errors import DrakeEstError
from drake_est.systems.friction import DiagnosedFriction  # noqa: F401  (the system lives in systems/)
from drake_est.identification.friction import Coulomb, EnergyDynamics, ExtensionTerm, JointFriction, Viscous
from drake_est.identification.friction.terms import _sign


SIM_STEP_S = 0.002


def diagnosed_friction_models(result, model, fit, cols: dict, sign_eps: float = 0.0) -> dict:
    """The diagnosed friction of every excited joint as a :class:`JointFriction` (one friction model):
    nominal :class:`Viscous` + :class:`Coulomb` (9.2) plus one :class:`ExtensionTerm` per accepted
    per-joint extension, with the fitted coefficients.  ``cols``: {1-based log joint: 0-based index
    of that joint in the coordinates the models will read}.  Returns {index: JointFriction}.

    Each model fades its extensions by |tanh(qd / v_min)| towards standstill (they were identified on
    moving samples, (9.9)), evaluates the ripple amplitude at speeds clipped to the identified range
    and clips |F| at 1.5 x the largest friction torque seen.  A diagnosed energy effect reads the
    unit-gain energy E = 1/(tau_e s + 1) |F qd| (9.23) from a unit-gain :class:`EnergyDynamics`
    (``energy_additive=False``: the fitted coefficient multiplies sign(qd) E)."""
    prep = result.prep
    names = nominal_names(prep.robot_kind)
    if names != ["kv", "kc"]:
        raise DrakeEstError(f"unexpected nominal columns {names}")
    h = float(np.median(np.diff(prep.log.t))) if prep.log.t.size > 1 else 0.01
    out = {}
    for j, jd in prep.joints.items():
        v_used = jd.v[jd.rows]
        v_min = float(jd.counts["thresholds"]["v_min"])
        v_range = (float(v_used.min()), float(v_used.max()))
        terms, energy = [Viscous(), Coulomb()], None
        for e in model.own(j):
            coupled = [cols[i] for i in e.spec.get("coupled_joints", [])] or None
            terms.append(ExtensionTerm(e.spec, v_min=v_min, v_range=v_range, coupled_indices=coupled))
            if e.effect == "energy_dependent_friction":
                energy = EnergyDynamics(gain=1.0, time_constant=float(e.spec["tau_e"]), h=h)
        m = JointFriction(terms, index=cols[j], lam=0.0, energy=energy, joint_number=int(j),
                          name="diagnosed", energy_additive=False,
                          torque_limit=1.5 * float(np.max(np.abs(jd.y))))
        m.coef = np.asarray(fit.coef[j], float).copy()
        if m.coef.size != m.n_params:
            raise DrakeEstError(f"joint {j}: {m.coef.size} coefficients for {m.n_params} columns")
        out[cols[j]] = m
    return out


class FrictionLaw:
    """Friction torques of the excited joints for a (subset of the) diagnosed model, in log coordinates.

    The numbers come from the diagnosed :class:`JointFriction` models
    (:func:`diagnosed_friction_models`); the energy of an energy-dependent effect is taken from the
    measured history (the unit-gain state the regression used, Algorithm 6).
    ``friction(t, q, v)`` takes the log-joint vectors (len = number of log joints) and returns the
    friction torque of every log joint (zero for joints that were not diagnosed).  Several logs: the
    per-log offsets of ``fit`` (``fit.per_log``) of the log that time ``t`` lies in are added,
    dkv_k qd + dkc_k sign(qd) (:func:`~drake_est.diagnose.multilog.per_log_offsets`)."""

    def __init__(self, result, model, fit, sign_eps: float = 0.0):
        prep = result.prep
        self.prep = prep
        self.kind = prep.robot_kind
        self.log_joints = list(prep.log.joints)
        self.sign_eps = float(sign_eps)
        cols = {j: c for c, j in enumerate(self.log_joints)}
        self.models = diagnosed_friction_models(result, model, fit, cols, sign_eps)
        self.parts = {}
        for j, jd in prep.joints.items():
            self.parts[j] = {"J": jd.counts.get("inertia"), "model": self.models[cols[j]]}
            e = next((e for e in model.own(j) if e.effect == "energy_dependent_friction"), None)
            if e is not None:
                if e.obj is not None:      # the unit-gain energy state the regression used (Algorithm 6)
                    self.parts[j]["E_t"] = (jd.t, np.asarray(e.obj, float))
                else:
                    c = fit.coef[j]
                    F = c[0] * jd.v + c[1] * np.sign(jd.v)
                    self.parts[j]["E_t"] = (jd.t, unit_energy_per_log(jd.t, np.abs(F * jd.v), e.spec["tau_e"],
                                                                      log_starts(prep)))
        #: {log joint: {0-based log: [dkv, dkc]}}: per-log offsets (several logs; empty for one log)
        self.offsets = {j: dict(o) for j, o in (getattr(fit, "per_log", None) or {}).items()}
        st = log_starts(prep)
        self._log_start_t = None if st is None else prep.log.t[st]
        self._log_start_k = None if st is None else np.asarray(prep.log.channels["log_index"]).astype(int)[st]

    def offsets_at(self, t, v) -> np.ndarray:
        """Per-log offset torques dkv_k qd + dkc_k sign(qd) of every log joint at time ``t`` (0 for one log)."""
        F = np.zeros(len(self.log_joints))
        if not self.offsets:
            return F
        i = int(np.searchsorted(self._log_start_t, t, side="right")) - 1
        k = int(self._log_start_k[max(i, 0)])      # the log that time t lies in (multilog.log_at_time)
        for j, offs in self.offsets.items():
            if k in offs:
                c = self.log_joints.index(j)
                dkv, dkc = offs[k]
                F[c] = dkv * v[c] + dkc * float(_sign(np.array([v[c]]), self.sign_eps)[0])
        return F

    def energy_at(self, t) -> np.ndarray:
        """The measured-history unit-gain energy of every log joint at time ``t`` (0 where none)."""
        E = np.zeros(len(self.log_joints))
        for j, p in self.parts.items():
            if "E_t" in p:
                tt, EE = p["E_t"]
                E[self.log_joints.index(j)] = np.interp(t, tt, EE)
        return E

    def friction(self, t, q, v) -> np.ndarray:
        q = np.asarray(q, float).reshape(1, -1)
        v = np.asarray(v, float).reshape(1, -1)
        E = self.energy_at(t)
        F = np.zeros(len(self.log_joints))
        for c, m in self.models.items():
            F[c] = float(m.predict(q, v, E[c:c + 1] if m.needs_energy else None, sign_eps=self.sign_eps,
                                   t=np.array([t]))[0])
        return F + self.offsets_at(t, v.ravel())


def _windows_in(t, window_s, n_windows):
    T = float(t[-1] - t[0])
    if T < 3 * window_s:
        return [float(t[0])] if T > window_s else []
    return list(t[0] + window_s + (T - 3 * window_s) * (np.arange(n_windows) + 0.5) / n_windows)


def _windows(result, window_s, n_windows):
    """Start times of ``n_windows`` windows spread evenly over the log (away from its ends).  Several logs:
    at least one window per log (``max(n_windows, number of logs)`` in all, shared out evenly), each inside
    its log, so that no simulation runs across the boundary between two logs."""
    prep = result.prep
    t = prep.log.t
    starts = log_starts(prep)
    if starts is None:
        return _windows_in(t, window_s, n_windows)
    bounds = list(starts) + [t.size]
    n_logs = len(starts)
    per = [max(n_windows, n_logs) // n_logs + (1 if k < max(n_windows, n_logs) % n_logs else 0) for k in range(n_logs)]
    out = []
    for k in range(n_logs):
        out += _windows_in(t[bounds[k]:bounds[k + 1]], window_s, per[k])
    return out


def _simulate_robot(result, law, payload, t0, t1):
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import TrajectorySource
    from pydrake.trajectories import PiecewisePolynomial

    from drake_est.systems.builders import (AddIrb140Plant, AddJointFriction, AddRobotPlant, AddStateLogger,
                                            PlantConfig)

    prep = result.prep
    log = prep.log
    builder = DiagramBuilder()
    config = PlantConfig(time_step=0.0, payload=payload)   # continuous plant, extended model's payload
    if prep.robot_kind == "irb140":
        plant = AddIrb140Plant(builder, config)
    else:
        plant = AddRobotPlant(builder, prep.robot.urdf, config, flange_frame=prep.robot.flange.name())
    n = plant.num_positions()
    sel = (log.t >= t0 - 0.05) & (log.t <= t1 + 0.05)
    ts = log.t[sel]
    U = np.zeros((ts.size, n))
    for c, j in enumerate(log.joints):
        U[:, j - 1] = log.tau[sel, c]
    src = builder.AddSystem(TrajectorySource(PiecewisePolynomial.FirstOrderHold(ts, U.T)))
    AddJointFriction(builder, plant, DiagnosedFriction(law, n, prep.robot_cols),
                     actuation_source=src.get_output_port())
    h = float(np.median(np.diff(log.t)))
    sink = AddStateLogger(builder, plant, h)
    diagram = builder.Build()
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    ctx.SetTime(t0)
    k0 = int(np.searchsorted(log.t, t0))
    x0 = np.concatenate([prep.q_full[k0], prep.v_full[k0]])
    plant.SetPositionsAndVelocities(plant.GetMyMutableContextFromRoot(ctx), x0)
    integ = sim.get_mutable_integrator()
    # fixed steps of at most 2 ms (RK3): error control would chase the ripple and the smoothed sign
    integ.set_fixed_step_mode(True)
    integ.set_maximum_step_size(min(h, SIM_STEP_S))
    sim.AdvanceTo(t1)
    lg = sink.FindLog(ctx)
    return lg.sample_times(), lg.data()[n:].T


def _simulate_generic(result, law, t0, t1):
    prep = result.prep
    log = prep.log
    sel = (log.t >= t0) & (log.t <= t1)
    ts = log.t[sel]
    m = len(log.joints)
    k0 = int(np.flatnonzero(sel)[0])
    q = log.q[k0].copy()
    v = log.dq[k0].copy()
    Jinv = np.zeros(m)
    for j, p in law.parts.items():
        if p["J"] and p["J"] > 0:
            Jinv[log.joints.index(j)] = 1.0 / p["J"]
    tau_at = lambda tt: np.array([np.interp(tt, log.t, log.tau[:, c]) for c in range(m)])  # noqa: E731

    def f(tt, q, v):
        return v, Jinv * (tau_at(tt) - law.friction(tt, q, v))

    V = [v.copy()]
    for k in range(ts.size - 1):
        h = ts[k + 1] - ts[k]
        nsub = max(1, int(np.ceil(h / 0.002)))
        dt = h / nsub
        tt = ts[k]
        for _ in range(nsub):
            k1q, k1v = f(tt, q, v)
            k2q, k2v = f(tt + dt / 2, q + dt / 2 * k1q, v + dt / 2 * k1v)
            k3q, k3v = f(tt + dt / 2, q + dt / 2 * k2q, v + dt / 2 * k2v)
            k4q, k4v = f(tt + dt, q + dt * k3q, v + dt * k3v)
            q = q + dt / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
            v = v + dt / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
            tt += dt
        V.append(v.copy())
    return ts, np.array(V)


def _payload_of(result, fit):
    coef = fit.shared.get("payload")
    if coef is None:
        return None
    from drake_est.diagnose.detectors import PAYLOAD_COMS
    m = float(np.sum(coef))
    if m <= 0:
        return None
    com = np.sum(np.asarray(PAYLOAD_COMS) * coef[:, None], axis=0) / m
    return (m, com)


def simulation_error(result, window_s: float = 2.0, n_windows: int = 4) -> dict:
    """Windowed forward simulations with the measured torque through the nominal and the final
    model; returns the velocity RMS errors and the traces (for plotting)."""
    from drake_est.diagnose.core import Model
    prep = result.prep
    eps = {j: 0.02 * float(np.quantile(np.abs(jd.v), 0.95)) for j, jd in prep.joints.items()}
    sign_eps = min(eps.values())
    laws = {"nominal": (FrictionLaw(result, Model(prep), result.nominal_fit, sign_eps), None),
            "extended": (FrictionLaw(result, result.final_model, result.final_fit, sign_eps),
                         _payload_of(result, result.final_fit))}
    starts = _windows(result, window_s, n_windows)
    log = prep.log
    cols = [log.joints.index(j) for j in prep.joints]
    traces = []
    err = {k: [] for k in laws}
    for s in starts:
        tr = {"t0": s}
        for name, (law, payload) in laws.items():
            if prep.robot is not None:
                ts, V = _simulate_robot(result, law, payload, s, s + window_s)
                Vj = np.column_stack([V[:, prep.robot_cols[j]] for j in prep.joints])
            else:
                ts, V = _simulate_generic(result, law, s, s + window_s)
                Vj = V[:, cols]
            Vm = np.column_stack([np.interp(ts, log.t, log.dq[:, c]) for c in cols])
            err[name].append(Vj - Vm)
            tr[name] = (ts, Vj)
            tr["measured"] = (ts, Vm)
        traces.append(tr)
    out = {"window_s": window_s, "n_windows": len(starts), "joints": list(prep.joints),
           "method": "Drake Simulator, continuous MultibodyPlant + DiagnosedFriction" if prep.robot is not None
           else "per-axis RK4 integration of J qdd = tau - F"}
    for name in laws:
        if err[name]:
            E = np.vstack(err[name])
            out[f"velocity_rmse_{name}"] = {int(j): float(np.sqrt(np.mean(E[:, k] ** 2)))
                                            for k, j in enumerate(prep.joints)}
    out["_traces"] = traces
    return out
