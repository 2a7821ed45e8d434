"""Synthetic "measured" IRB 140 logs with known hidden effects.

:func:`synthesize` simulates the IRB 140 ``MultibodyPlant`` (continuous time) under a
tracking controller (Drake's ``InverseDynamicsController`` on the nominal model, with
integral action) while a :class:`TrueJointFriction` system applies the *true* joint
friction, which may contain hidden effects the nominal model lacks.  The logged torque
is the controller's motor torque (arm side) plus noise; logged positions are quantized.
Ground truth is returned separately from the data.

Experiments (``experiment=``):

* ``"sweep"`` -- thesis Sec. 9.6: the selected joint(s) move at piecewise-constant
  velocities between (a margin inside) the joint limits, the others hold still;
* ``"excitation"`` -- multi-joint excitation: sums of sinusoids on all selected joints.

Hidden effects (``effect=`` one name or a list; the diagnosis vocabulary):

``position_dependent_friction``  Gaussian bumps in arm position added to the Coulomb level (9.16)
``motor_position_ripple``        A(|qd|) sin(h * p_motor + phi), p_motor = mod(g q, 2 pi), A falling with speed
``energy_dependent_friction``    F = F_n + sign(v) E, dE/dt = (k_e W - E)/tau_e, W = |F v|  (9.22)-(9.23)
``asymmetric_coulomb``           different Coulomb levels for positive and negative velocity (9.3)
``gear_coupling``                wrist joints 5/6 feel Coulomb + viscous friction of the coupled joints' motion (9.12)
``payload``                      an unmodeled mass at the flange (present in the simulated plant only)
``abrupt_change``                the Coulomb and viscous levels of a joint jump at an instant

plus torque noise and encoder quantization (always).
"""
from __future__ import annotations

import copy

import numpy as np
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import Simulator
from pydrake.trajectories import PiecewisePolynomial

from drake_est.data import Log
from drake_est.effects import EFFECTS  # the one effect list (re-exported here)
from drake_est.errors import DrakeEstError
from drake_est.identification.friction.truth import FrictionTruth  # noqa: F401  (re-exported)
from drake_est.robots import irb140_metadata, models_dir
from drake_est.systems.friction import TrueJointFriction  # noqa: F401  (re-exported)
from drake_est.systems.builders import (Irb140SimulationConfig, MakeIrb140Simulation, PlantConfig,
                                       TrackingControllerConfig)


# ----------------------------------------------------------------------------- truth model


# FrictionTruth (numpy) lives in drake_est.identification.friction.truth and its LeafSystem
# TrueJointFriction in drake_est.systems.friction (one place for friction); re-exported here.


# ----------------------------------------------------------------------------- trajectories


def sweep_trajectory(rng, joints, q0, limits, vmax, duration, margin=0.15, n_levels=8, ramp=0.5):
    """Piecewise-constant-velocity sweeps between the limits (Sec. 9.6) for each 0-based joint in
    ``joints``; returns knot times, positions (K, n), velocities (K, n)."""
    n = len(q0)
    dt = 0.02
    ts = np.arange(0.0, duration + dt, dt)
    Q = np.tile(q0, (len(ts), 1))
    V = np.zeros_like(Q)
    for j in joints:
        lo, hi = limits[j]
        span = hi - lo
        lo, hi = lo + margin * span, hi - margin * span
        levels = vmax[j] * np.linspace(0.1, 0.6, n_levels)
        q, v_cmd, direction = q0[j], rng.choice(levels), 1.0 if rng.random() < 0.5 else -1.0
        v = 0.0
        for k in range(len(ts)):
            # accelerate toward the commanded velocity with a limited acceleration (smooth ramps)
            target = direction * v_cmd
            acc = vmax[j] / ramp
            v_new = v + np.clip(target - v, -acc * dt, acc * dt)
            q += 0.5 * (v + v_new) * dt  # trapezoidal: consistent with the cubic Hermite interpolation
            v = v_new
            if (direction > 0 and q >= hi) or (direction < 0 and q <= lo):
                direction = -direction
                v_cmd = rng.choice(levels)
            Q[k, j], V[k, j] = q, v
        # jerk-limited ramps: smooth the velocity profile with a moving average, re-integrate positions
        w = max(3, int(round(0.3 * ramp / dt)) | 1)
        kernel = np.ones(w) / w
        V[:, j] = np.convolve(np.pad(V[:, j], (w // 2, w // 2), mode="edge"), kernel, mode="valid")
        Q[:, j] = q0[j] + np.concatenate([[0.0], np.cumsum(0.5 * (V[1:, j] + V[:-1, j]) * dt)])
    return ts, Q, V


def excitation_trajectory(rng, joints, q0, limits, vmax, duration, n_harm=4, f0=None):
    """Sums of sinusoids (periodic excitation) on the selected 0-based joints."""
    n = len(q0)
    dt = 0.02
    ts = np.arange(0.0, duration + dt, dt)
    Q = np.tile(q0, (len(ts), 1))
    V = np.zeros_like(Q)
    for j in joints:
        lo, hi = limits[j]
        amp_budget = 0.35 * min(q0[j] - lo, hi - q0[j])
        base = f0 if f0 is not None else rng.uniform(0.05, 0.12)
        qj = np.zeros_like(ts)
        vj = np.zeros_like(ts)
        for k in range(1, n_harm + 1):
            w = 2 * np.pi * base * k * rng.uniform(0.9, 1.1)
            a = amp_budget / n_harm * rng.uniform(0.6, 1.0)
            a = min(a, 0.5 * vmax[j] / n_harm / w)
            ph = rng.uniform(0, 2 * np.pi)
            qj += a * np.sin(w * ts + ph)
            vj += a * w * np.cos(w * ts + ph)
        Q[:, j] = q0[j] + qj - qj[0]
        V[:, j] = vj
    # fade in over 1 s so that the start is at rest
    fade = np.clip(ts / 1.0, 0, 1)[:, None]
    Q = q0 + (Q - q0) * fade
    V = V * fade
    return ts, Q, V


# ----------------------------------------------------------------------------- main entry


def _sample_truth(rng, meta, effects, moving, duration, ctrl_joints):
    n = len(meta.gear_ratios)
    scale = rng.uniform(0.7, 1.3, n)
    kc = meta.coulomb * scale
    kv = meta.viscous * rng.uniform(0.7, 1.3, n)
    truth = FrictionTruth(kc=kc, kv=kv)
    eff = {}
    for e in effects:
        if e == "position_dependent_friction":
            truth.bumps = {}
            for j in moving:
                lo, hi = meta.position_limits[j]
                span = hi - lo
                k = int(rng.integers(2, 5))
                c = rng.uniform(lo + 0.25 * span, hi - 0.25 * span, k)
                w = rng.uniform(0.04, 0.1, k) * span
                a = rng.choice([-1, 1], k) * rng.uniform(0.25, 0.5, k) * kc[j]
                truth.bumps[j] = (c, w, a)
                eff.setdefault(e, {})[j + 1] = {"centers": c, "widths": w, "amplitudes": a}
        elif e == "motor_position_ripple":
            truth.ripple = {}
            for j in moving:
                g = meta.gear_ratios[j]
                h = int(rng.integers(1, 4))
                a0 = rng.uniform(0.3, 0.6) * kc[j]
                vh = rng.uniform(0.15, 0.4) * meta.velocity_limits[j]
                ph = rng.uniform(0, 2 * np.pi)
                truth.ripple[j] = (g, h, a0, vh, ph)
                eff.setdefault(e, {})[j + 1] = {"gear_ratio": g, "harmonic_per_motor_rev": h, "amplitude_at_rest": a0,
                                                "v_half": vh, "phase": ph,
                                                "frequency_per_arm_rad": h * g / (2 * np.pi),
                                                "amplitude_trend_with_speed": "decreasing"}
        elif e == "energy_dependent_friction":
            truth.energy = {}
            for j in moving:
                te = rng.uniform(0.12, 0.25) * duration
                # choose k_e so that the stationary drift is 20-40 % of the Coulomb level (friction falls when warm)
                ke = -rng.uniform(0.2, 0.4) * kc[j] / max(kc[j] * 0.35 * meta.velocity_limits[j], 1e-9)
                truth.energy[j] = (ke, te)
                eff.setdefault(e, {})[j + 1] = {"k_e": ke, "tau_e": te}
        elif e == "asymmetric_coulomb":
            truth.kc_neg = kc.copy()
            for j in moving:
                r = rng.uniform(1.3, 1.7)
                truth.kc_neg[j] = kc[j] * (r if rng.random() < 0.5 else 1.0 / r)
                eff.setdefault(e, {})[j + 1] = {"kc_pos": kc[j], "kc_neg": truth.kc_neg[j]}
        elif e == "gear_coupling":
            truth.coupling = {}
            N = meta.motor_from_arm
            for j in (4, 5):
                terms = []
                for i in range(3, j):
                    if N[j, i] == 0:
                        continue
                    # motor-side friction of the coupled motor reflected to joint j (Eq. (9.12)); sized
                    # like half the joint's own friction, as the thesis reports for an IRB 2400
                    kci = rng.uniform(0.3, 0.6) * kc[j]
                    kvi = rng.uniform(0.3, 0.6) * kv[j]
                    terms.append((i, kci, kvi))
                truth.coupling[j] = terms
                eff.setdefault(e, {})[j + 1] = {f"joint{i + 1}": {"kc": kci, "kv": kvi} for i, kci, kvi in terms}
        elif e == "payload":
            mass = rng.uniform(1.5, 5.0)
            com = np.array([0.0, 0.0, rng.uniform(0.03, 0.12)])
            eff[e] = {"mass": mass, "com_in_flange": com}
        elif e == "abrupt_change":
            truth.change = {}
            for j in moving:
                tc = rng.uniform(0.35, 0.65) * duration
                f = rng.uniform(1.35, 1.7) if rng.random() < 0.5 else 1 / rng.uniform(1.35, 1.7)
                truth.change[j] = (tc, kc[j] * f, kv[j] * f)
                eff.setdefault(e, {})[j + 1] = {"t_change": tc, "kc_before": kc[j], "kc_after": kc[j] * f,
                                                "kv_before": kv[j], "kv_after": kv[j] * f}
        else:
            raise DrakeEstError(f"unknown effect '{e}'; choose from: none, {', '.join(EFFECTS)}")
    return truth, eff


def synthesize(effect="none", seed: int = 0, joints=None, duration: float | None = None,
               sample_rate: float = 100.0, experiment: str | None = None, noise_std: float | None = None,
               encoder_counts_per_motor_rev: int = 4096, progress: bool = False, knot_offset: float = 0.0):
    """Simulate a "measured" IRB 140 log with hidden effects.

    Parameters
    ----------
    effect : "none", one name of :data:`EFFECTS`, or a list of names.
    seed : seeds every random choice (friction levels, effect parameters, trajectory, noise).
    joints : 1-based joints that move (default: [1] for a sweep; [4, 5, 6] for gear_coupling;
        [1, 2, 3] for payload).
    duration : seconds (default 300 s, 900 s with the energy effect).
    sample_rate : logged samples per second [Hz].
    experiment : "sweep" (Sec. 9.6) or "excitation" (default: sweep, excitation for payload/gear_coupling).
    noise_std : torque noise [N m] (default: random in 0.2-0.6 N m; the thesis' simulation uses 0.5).
    encoder_counts_per_motor_rev : position quantization at the motor (arm step 2 pi / (counts g)).
    knot_offset : seconds, in [0, 0.02), by which the reference's knots (every 20 ms) are moved later.  The desired
        acceleration of the cubic Hermite reference jumps at each knot and so does the computed-torque controller's
        torque; with the default 0 every knot falls on a sample at rates that divide 50 Hz, where the logged
        torque is the value after the jump while a smoothed acceleration sees both sides (a torque that leads the
        positions by about half a sample; ``benchmarks/bench_synth_knots.py``).  Half a sample period moves the knots
        between the samples.

    The first second (controller start-up transient) is not logged, so a log of ``duration`` seconds
    holds ``duration - 1`` seconds of data, with time starting at 0.

    Returns ``(log, truth)``: the :class:`~drake_est.data.Log` (t, q, tau, quantized q, no derivatives)
    and a dict with the true friction parameters, the effect parameters, the noise level and the
    noise-free friction torque."""
    effects = [] if effect in (None, "none") else ([effect] if isinstance(effect, str) else list(effect))
    effects = [e for e in effects if e != "none"]
    for e in effects:
        if e not in EFFECTS:
            raise DrakeEstError(f"unknown effect '{e}'; choose from: none, {', '.join(EFFECTS)}")
    rng = np.random.default_rng(seed)
    meta = irb140_metadata()
    n = len(meta.gear_ratios)
    if joints is None:
        joints = [4, 5, 6] if "gear_coupling" in effects else ([2, 3] if "payload" in effects else [1])
    joints = [int(j) for j in joints]
    for j in joints:
        if not 1 <= j <= n:
            raise DrakeEstError(f"joint {j} does not exist (the IRB 140 has joints 1-{n})")
    moving = [j - 1 for j in joints]
    if experiment is None:
        experiment = "excitation" if ("payload" in effects or "gear_coupling" in effects) else "sweep"
    if duration is None:
        duration = 900.0 if "energy_dependent_friction" in effects else 300.0
    if noise_std is None:
        noise_std = float(rng.uniform(0.2, 0.6))
    truth, eff = _sample_truth(rng, meta, effects, moving, duration, moving)
    # friction acts on the moving joints only: the held joints' friction is irrelevant to the
    # experiment and a stiff friction law at rest would only slow the integrator down
    truth.active = np.isin(np.arange(n), moving)

    # ---- reference trajectory
    q0 = np.array([0.0, 0.0, 0.0, 0.0, 0.6, 0.0])  # forearm horizontal, wrist bent: low inertia about J1
    limits = meta.position_limits
    vmax = meta.velocity_limits
    if experiment == "sweep":
        ts, Qr, Vr = sweep_trajectory(rng, moving, q0, limits, vmax, duration)
    elif experiment == "excitation":
        ts, Qr, Vr = excitation_trajectory(rng, moving, q0, limits, vmax, duration)
    else:
        raise DrakeEstError(f"unknown experiment '{experiment}' (use 'sweep' or 'excitation')")
    if not 0.0 <= knot_offset < 0.02:
        raise DrakeEstError(f"knot_offset must be in [0, 0.02) s (the knots are 20 ms apart), got {knot_offset}")
    if knot_offset > 0:
        # the knots moved later, the reference held at its first knot (at rest) before them
        ts = np.concatenate([[0.0], ts + knot_offset])
        Qr, Vr = np.vstack([Qr[:1], Qr]), np.vstack([np.zeros_like(Vr[:1]), Vr])
    traj = PiecewisePolynomial.CubicHermite(ts, Qr.T, Vr.T)

    # ---- diagram: plant (+ payload) <- controller (nominal model) - true friction
    payload = (eff["payload"]["mass"], eff["payload"]["com_in_flange"]) if "payload" in eff else None
    period = 1.0 / sample_rate
    config = Irb140SimulationConfig(plant=PlantConfig(time_step=0.0, payload=payload),
                                    controller=TrackingControllerConfig.from_bandwidth(25.0, ki_ratio=0.5),
                                    log_period=period)
    diagram, h = MakeIrb140Simulation(config, traj, friction=TrueJointFriction(truth))
    plant, log_x, log_u, log_f = h.plant, h.state_log, h.torque_log, h.friction_log
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    plant.SetPositions(plant.GetMyMutableContextFromRoot(ctx), Qr[0])
    integ = sim.get_mutable_integrator()
    integ.set_target_accuracy(1e-3)
    integ.set_maximum_step_size(min(period, 0.01))
    if progress:
        from drake_est.progress import progress as bar
        pb = bar(total=int(duration), desc="simulating IRB140")
        last = [0]

        def monitor(c):
            t = int(c.get_time())
            if t > last[0]:
                pb.update(t - last[0])
                last[0] = t
        from pydrake.systems.framework import EventStatus
        sim.set_monitor(lambda c: (monitor(c), EventStatus.Succeeded())[1])
    sim.AdvanceTo(duration)
    if progress:
        pb.close()
    lx = log_x.FindLog(ctx)
    lu = log_u.FindLog(ctx)
    lf = log_f.FindLog(ctx)
    t = lx.sample_times()
    X = lx.data().T
    U = lu.data().T
    Ffr = lf.data().T
    m = min(len(t), len(U), len(Ffr))
    t, X, U, Ffr = t[:m], X[:m], U[:m], Ffr[:m]
    # drop the initial transient (first second) and duplicated publish times
    keep = np.r_[True, np.diff(t) > 0] & (t >= 1.0)
    t, X, U, Ffr = t[keep] - t[keep][0], X[keep], U[keep], Ffr[keep]

    # ---- measurement: quantized encoders, torque noise
    step = 2 * np.pi / (encoder_counts_per_motor_rev * meta.gear_ratios)
    q_meas = np.round(X[:, :n] / step) * step
    tau_meas = U + noise_std * rng.standard_normal(U.shape)
    cols = list(range(n))  # all joints are logged; the ones not in `joints` hold still
    log = Log(t=t, q=q_meas, tau=tau_meas, joints=list(range(1, n + 1)),
              meta={"source": "drake_est.synth", "seed": seed, "effects": effects, "experiment": experiment,
                    "sample_rate": sample_rate, "robot": "irb140"})
    truth_out = {
        "effects": effects,
        "effect_parameters": eff,
        "joints": joints,
        "noise_std": noise_std,
        "friction": {j + 1: {"kc": float(truth.kc[j]), "kv": float(truth.kv[j])} for j in range(n)},
        "friction_torque": Ffr,
        "q_true": X[:, :n],
        "dq_true": X[:, n:],
        "seed": seed,
        "truth_model": copy.deepcopy(truth),
    }
    return log, truth_out
