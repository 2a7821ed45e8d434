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
"""
from __future__ import annotations

import numpy as np
from pydrake.systems.framework import LeafSystem

from drake_est.diagnose.detectors import columns_at, unit_energy
from drake_est.diagnose.nominal import nominal_names


SIM_STEP_S = 0.002


class FrictionLaw:
    """Friction torques of the excited joints for a (subset of the) diagnosed model.

    ``friction(t, q, v)`` takes the log-joint vectors (len = number of log joints) and returns the
    friction torque of every log joint (zero for joints that were not diagnosed)."""

    def __init__(self, result, model, fit, sign_eps: float = 0.0):
        prep = result.prep
        self.prep = prep
        self.kind = prep.robot_kind
        self.log_joints = list(prep.log.joints)
        self.sign_eps = float(sign_eps)
        names = nominal_names(self.kind)
        self.parts = {}
        for j, jd in prep.joints.items():
            c = fit.coef[j]
            k = len(names)
            own = []
            for e in model.own(j):
                own.append((e, c[k:k + e.n_params]))
                k += e.n_params
            v_used = jd.v[jd.rows]
            self.parts[j] = {"kv": float(c[names.index("kv")]), "kc": float(c[names.index("kc")]),
                             "J": jd.counts.get("inertia"), "own": own,
                             "v_range": (float(v_used.min()), float(v_used.max())),
                             "F_max": 1.5 * float(np.max(np.abs(jd.y))),
                             "v_min": float(jd.counts["thresholds"]["v_min"])}
            if any(e.effect == "energy_dependent_friction" for e, _ in own):
                e = next(e for e, _ in own if e.effect == "energy_dependent_friction")
                if e.obj is not None:      # the unit-gain energy state the regression used (Algorithm 6)
                    self.parts[j]["E_t"] = (jd.t, np.asarray(e.obj, float))
                else:
                    F = self.parts[j]["kv"] * jd.v + self.parts[j]["kc"] * np.sign(jd.v)
                    self.parts[j]["E_t"] = (jd.t, unit_energy(jd.t, np.abs(F * jd.v), e.spec["tau_e"]))

    def sgn(self, v):
        return np.tanh(v / self.sign_eps) if self.sign_eps > 0 else np.sign(v)

    def friction(self, t, q, v) -> np.ndarray:
        F = np.zeros(len(self.log_joints))
        for j, p in self.parts.items():
            c = self.log_joints.index(j)
            f = p["kv"] * v[c] + p["kc"] * self.sgn(v[c])
            vr = float(np.clip(v[c], *p["v_range"]))   # basis expansions are not extrapolated in speed
            for e, coef in p["own"]:
                E = None
                if e.effect == "energy_dependent_friction":
                    tt, EE = p["E_t"]
                    E = np.array([np.interp(t, tt, EE)])
                others = {i: np.array([v[self.log_joints.index(i)]]) for i in e.spec.get("coupled_joints", [])}
                vv = vr if e.effect == "motor_position_ripple" else v[c]
                cols = columns_at(e.spec, np.array([q[c]]), np.array([vv]), np.array([t]), others, E,
                                  sign=self.sgn)
                # the extensions were identified on moving samples only (|v| > v_min, (9.9)):
                # faded out towards standstill instead of extrapolated there
                f += float(cols[0] @ coef) * abs(np.tanh(v[c] / p["v_min"]))
            F[c] = float(np.clip(f, -p["F_max"], p["F_max"]))
        return F


class DiagnosedFriction(LeafSystem):
    """Drake system of a diagnosed friction model.

    Input ports ``joint_positions`` [rad] and ``joint_velocities`` [rad/s] (robot coordinates);
    output ``friction_torques`` [N m] (the torque the actuators spend on friction; feed its
    negative to the plant). Time enters through the Context (abrupt change, energy history)."""

    def __init__(self, law: FrictionLaw, n_robot: int, robot_cols: dict):
        super().__init__()
        self._law = law
        self._n = n_robot
        self._map = [(law.log_joints.index(j), robot_cols[j]) for j in law.log_joints if j in robot_cols]
        self.DeclareVectorInputPort("joint_positions", n_robot)
        self.DeclareVectorInputPort("joint_velocities", n_robot)
        self.DeclareVectorOutputPort("friction_torques", n_robot, self._calc)

    def _calc(self, context, output):
        qr = self.get_input_port(0).Eval(context)
        vr = self.get_input_port(1).Eval(context)
        m = len(self._law.log_joints)
        q, v = np.zeros(m), np.zeros(m)
        for c, rc in self._map:
            q[c], v[c] = qr[rc], vr[rc]
        F = self._law.friction(context.get_time(), q, v)
        out = np.zeros(self._n)
        for c, rc in self._map:
            out[rc] = F[c]
        output.SetFromVector(out)


def _windows(result, window_s, n_windows):
    """Start times of ``n_windows`` windows spread evenly over the log (away from its ends)."""
    t = result.prep.log.t
    T = float(t[-1] - t[0])
    if T < 3 * window_s:
        return [float(t[0])] if T > window_s else []
    return list(t[0] + window_s + (T - 3 * window_s) * (np.arange(n_windows) + 0.5) / n_windows)


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
