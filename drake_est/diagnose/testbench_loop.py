"""A second independent log generator for checking the diagnosis: a *simulated* axis in a closed loop.

Built differently from :mod:`drake_est.diagnose.testbench` (which writes the torque as model + noise along
square-wave speed levels) and from :mod:`drake_est.synth` (Drake IRB 140):

* the axis is simulated (linearly-implicit Euler at <= 0.5 ms; friction is a force on the motor and on the
  load, smoothed through zero by ``tanh(v / v_eps)``); the logged torque is the **command of a PID position
  controller** (gains from a 3-8 Hz bandwidth, inertia and viscous feedforward) that reads a quantized motor
  encoder (``counts`` per motor revolution, gear ratio ``g``) through a filtered difference;
* reference trajectories of another family: point-to-point moves with minimum-jerk (quintic) profiles whose
  peak speeds are drawn log-uniformly over 1.7 decades (``"p2p"``), or a random multisine (``"multisine"``);
* the vocabulary effects have shapes of their own: Stribeck with a Gaussian *or* a Lorentzian law
  ``ks / (1 + (v/vs)^2)``, a time-periodic force (fundamental + second harmonic) on the load, a cogging ripple
  periodic in the *motor* angle ``g q`` (1-3 periods per motor revolution, second harmonic), position friction
  as two localized bumps, a position load that is a spring plus a gravity-like cosine, an asymmetric Coulomb
  level smoothed through zero, an abrupt change of Coulomb and viscous friction by factors, and friction that
  falls as a lubricant temperature state driven by the dissipated power rises (Coulomb linearly, viscous
  exponentially);
* out-of-vocabulary effects (:data:`OUT_OF_VOCABULARY`) that must end as "unexplained": ``backlash`` (motor
  and load joined through a dead band), ``compliance`` (an elastic gear: a lightly damped two-mass resonance
  at 4-12 Hz, motor-side encoder) and ``sensor_delay`` (the logged encoder channel lags the logged torque
  channel by 10-40 ms, as when the two reach the logger over different bus paths; the controller itself reads the
  encoder without delay);
* noise: encoder quantization of the position, and torque noise ``"gaussian"``, ``"student_t"`` (3 degrees
  of freedom) or ``"quantized"`` (a coarse ADC).

**Visibility rule.**  A planted effect counts as planted (``truth["effects"]``) only if a log can show it:
the axis is simulated a second time with that effect left out (same seed, no torque noise) and the
difference of the two nominal residuals ``r = tau - LS fit of [qdd, qd, sign(qd)]`` on the samples kept by the
data selection (9.9) (on every moving sample for an out-of-vocabulary effect; derivatives by
:func:`drake_est.data.smooth_derivatives` over 0.1 s) must hold at least :data:`VISIBLE_SHARE` of the log's
noise variance (a perfect model would lower the RMSE by about 5 %); Stribeck also needs at least 5 % of the
moving samples below 2 vs.  A torque ripple or disturbance above the servo bandwidth moves the axis instead of
the command and can fail this rule; so can a tiny third-size effect.  Effects that fail are listed in
``truth["not_visible"]`` with their numbers, and a checker must neither require them nor count them wrong.

:func:`generate` has the signature of :func:`drake_est.diagnose.testbench.generate` and returns
``(Log, truth)``.  The simulation loop is compiled with numba when available (``cache=True``);
``DRAKE_EST_NO_NUMBA=1`` runs the same Python function (same numbers, tested to 1e-10).
"""
from __future__ import annotations

import math
import os

import numpy as np

#: out-of-vocabulary effects this generator can plant
OUT_OF_VOCABULARY = ("backlash", "compliance", "sensor_delay")
#: vocabulary effects it can plant
VOCABULARY_EFFECTS = ("stribeck", "time_periodic_disturbance", "motor_position_ripple", "position_dependent_friction",
                      "position_dependent_load", "asymmetric_coulomb", "abrupt_change", "energy_dependent_friction")
#: an effect is visible when its part of the nominal residual holds at least this share of the noise variance
VISIBLE_SHARE = 0.1
#: Stribeck is excited when at least this share of the moving samples lies below 2 vs
STRIBECK_LOW_SHARE = 0.05

# indices of the parameter vector of the simulation kernel
(P_J, P_JM, P_RHO, P_KC, P_KV, P_VEPS, P_KP, P_KD, P_KI, P_ALPHA, P_QSTEP, P_DT,
 P_KS, P_VS, P_SLAW, P_TPA, P_TPF, P_TPP1, P_TPP2, P_RA, P_RW, P_RP1, P_RP2,
 P_PFA, P_PFC1, P_PFS1, P_PFW1, P_PFC2, P_PFS2, P_PFW2, P_PLA, P_PLQC, P_PLH, P_PLP,
 P_ASY, P_TC, P_FCJ, P_FVJ, P_CE, P_VE, P_TAUE, P_PREF,
 P_TWO, P_KCPL, P_CCPL, P_GAP, P_NDELAY, P_NSUB, P_Q0) = range(49)
N_PARAMS = 49


def _simulate_py(p, qr, vr, ar, n_log):
    """The closed-loop axis (see the module docstring), one step per reference sample; returns the logged
    (encoder position, possibly delayed; torque command; true motor position; true motor velocity; thermal state) every
    ``p[P_NSUB]`` steps.  Plain Python scalar code: the numba kernel is this same function compiled."""
    J, Jm = p[P_J], p[P_JM]
    Jl = J - Jm
    rho, kc, kv, veps = p[P_RHO], p[P_KC], p[P_KV], p[P_VEPS]
    Kp, Kd, Ki, alpha, qstep, dt = p[P_KP], p[P_KD], p[P_KI], p[P_ALPHA], p[P_QSTEP], p[P_DT]
    two = p[P_TWO] > 0.5
    nd = int(p[P_NDELAY])
    nsub = int(p[P_NSUB])
    n = qr.shape[0]
    out_y = np.zeros(n_log)
    out_u = np.zeros(n_log)
    out_q = np.zeros(n_log)
    out_v = np.zeros(n_log)
    out_th = np.zeros(n_log)
    hist = np.zeros(nd + 1)
    qm = p[P_Q0]
    vm = 0.0
    ql = qm
    vl = 0.0
    for i in range(nd + 1):
        hist[i] = qm
    y_prev = math.floor(qm / qstep + 0.5) * qstep
    vf = 0.0
    integ = 0.0
    th = 0.0
    k_log = 0
    for k in range(n):
        t = k * dt
        # ---- sensor: encoder reading, filtered difference velocity; the logged encoder channel lags by nd steps
        hist[k % (nd + 1)] = qm
        q_logged = hist[(k + 1) % (nd + 1)] if nd > 0 else qm
        y = math.floor(qm / qstep + 0.5) * qstep
        if k > 0:
            vf += alpha * ((y - y_prev) / dt - vf)
        y_prev = y
        # ---- controller: PID on the position with inertia and viscous feedforward
        err = qr[k] - y
        integ += err * dt
        u = J * ar[k] + kv * vr[k] + Kp * err + Kd * (vr[k] - vf) + Ki * integ
        # ---- friction parameters now (abrupt change, temperature)
        kc_e = kc
        kv_e = kv
        if t >= p[P_TC]:
            kc_e *= p[P_FCJ]
            kv_e *= p[P_FVJ]
        kc_e *= 1.0 - p[P_CE] * th
        kv_e *= math.exp(-p[P_VE] * th)
        # ---- motor-side forces
        sg = math.tanh(vm / veps)
        x = vm / p[P_VS]
        if p[P_SLAW] < 0.5:
            strib = p[P_KS] * math.exp(-x * x)
        else:
            strib = p[P_KS] / (1.0 + x * x)
        d1 = (qm - p[P_PFC1]) / p[P_PFS1]
        d2 = (qm - p[P_PFC2]) / p[P_PFS2]
        posf = p[P_PFA] * (p[P_PFW1] * math.exp(-0.5 * d1 * d1) + p[P_PFW2] * math.exp(-0.5 * d2 * d2))
        asy = p[P_ASY] * 0.5 * (1.0 - sg)
        level_m = (1.0 - rho) * kc_e + strib + posf + asy
        ripple = p[P_RA] * (math.sin(p[P_RW] * qm + p[P_RP1]) + 0.5 * math.sin(2.0 * p[P_RW] * qm + p[P_RP2]))
        Fm = level_m * sg + (1.0 - rho) * kv_e * vm + ripple
        Km = abs(level_m) / veps * (1.0 - sg * sg) + (1.0 - rho) * kv_e
        # ---- load-side forces
        qx, vx = (ql, vl) if two else (qm, vm)
        sgl = math.tanh(vx / veps)
        wt = 2.0 * math.pi * p[P_TPF] * t
        dist = p[P_TPA] * (math.sin(wt + p[P_TPP1]) + 0.25 * math.sin(2.0 * wt + p[P_TPP2]))
        load = p[P_PLA] * (0.6 * (qx - p[P_PLQC]) / p[P_PLH] + 0.5 * math.cos(qx + p[P_PLP]))
        Fl = rho * kc_e * sgl + rho * kv_e * vx + load + dist
        Kl = rho * kc_e / veps * (1.0 - sgl * sgl) + rho * kv_e
        # ---- thermal state of the lubricant: driven by the friction power
        pw = abs(((1.0 - rho) * kc_e + strib + posf + asy) * sg * vm + (1.0 - rho) * kv_e * vm * vm
                 + rho * kc_e * sgl * vx + rho * kv_e * vx * vx)
        th += dt * (pw / p[P_PREF] - th) / p[P_TAUE]
        if k % nsub == 0 and k_log < n_log:
            out_y[k_log] = math.floor(q_logged / qstep + 0.5) * qstep
            out_u[k_log] = u
            out_q[k_log] = qm
            out_v[k_log] = vm
            out_th[k_log] = th
            k_log += 1
        # ---- dynamics: linearly-implicit Euler (friction's stiff slope through zero taken implicitly)
        if two:
            dz = qm - ql
            g2 = 0.5 * p[P_GAP]
            if dz > g2:
                fc = p[P_KCPL] * (dz - g2) + p[P_CCPL] * (vm - vl)
            elif dz < -g2:
                fc = p[P_KCPL] * (dz + g2) + p[P_CCPL] * (vm - vl)
            else:
                fc = 0.0
            vm += dt * (u - Fm - fc) / (Jm + dt * Km)
            vl += dt * (fc - Fl) / (Jl + dt * Kl)
            qm += dt * vm
            ql += dt * vl
        else:
            vm += dt * (u - Fm - Fl) / (J + dt * (Km + Kl))
            qm += dt * vm
    return out_y, out_u, out_q, out_v, out_th


_KERNEL = None


def _use_numba() -> bool:
    if os.environ.get("DRAKE_EST_NO_NUMBA", "") not in ("", "0"):
        return False
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def simulate(p, qr, vr, ar, n_log, use_numba: bool | None = None):
    """Run the closed-loop kernel (:func:`_simulate_py`), compiled unless ``use_numba=False`` or
    ``DRAKE_EST_NO_NUMBA=1``."""
    global _KERNEL
    if use_numba is None:
        use_numba = _use_numba()
    if use_numba:
        if _KERNEL is None:
            import numba
            _KERNEL = numba.njit(cache=True)(_simulate_py)
        return _KERNEL(p, qr, vr, ar, int(n_log))
    return _simulate_py(p, qr, vr, ar, int(n_log))


# ----------------------------------------------------------------------------- reference trajectories


def _quintic_moves(rng, T_total, dt, lo, hi, vmax):
    """Point-to-point moves with minimum-jerk profiles, peak speeds log-uniform in [0.02, 1] vmax, a move
    lasting at most 20 s, dwells of 0-0.4 s; sampled at dt (q, v, a)."""
    n = int(round(T_total / dt)) + 1
    q = np.empty(n)
    v = np.zeros(n)
    a = np.zeros(n)
    pos = lo + 0.5 * (hi - lo)
    i = 0
    span = hi - lo
    while i < n:
        target = rng.uniform(lo + 0.05 * span, hi - 0.05 * span)
        vpk = vmax * 10 ** rng.uniform(np.log10(0.02), 0.0)
        D = target - pos
        if abs(D) < 0.1 * span:
            D = np.sign(D or 1.0) * 0.1 * span
            if not lo <= pos + D <= hi:
                D = -D
        T = 1.875 * abs(D) / vpk
        if T > 20.0:
            D *= 20.0 / T
            T = 20.0
        T = max(T, 0.2)
        m = max(2, int(round(T / dt)))
        s = np.arange(m) / m
        q[i:i + m] = (pos + D * (10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5))[:n - i]
        v[i:i + m] = (D / T * (30 * s ** 2 - 60 * s ** 3 + 30 * s ** 4))[:n - i]
        a[i:i + m] = (D / T ** 2 * (60 * s - 180 * s ** 2 + 120 * s ** 3))[:n - i]
        i += m
        pos = pos + D
        w = int(round(rng.uniform(0.0, 0.4) / dt))
        q[i:i + w] = pos
        i += w
    return q, v, a


def _multisine(rng, T_total, dt, lo, hi, vmax):
    """A random multisine (5 components, 0.01-0.25 Hz, random phases) scaled into [lo, hi] and under vmax,
    with a 2 s cosine fade-in from rest."""
    t = np.arange(int(round(T_total / dt)) + 1) * dt
    f = np.exp(rng.uniform(np.log(0.01), np.log(0.25), 5))
    A = rng.uniform(0.3, 1.0, 5) / f ** 0.5
    ph = rng.uniform(0, 2 * np.pi, 5)
    w = 2 * np.pi * f
    z = (A * np.sin(np.outer(t, w) + ph)).sum(1)
    zd = (A * w * np.cos(np.outer(t, w) + ph)).sum(1)
    zdd = (-A * w ** 2 * np.sin(np.outer(t, w) + ph)).sum(1)
    c = 0.5 * (lo + hi)
    scale = min(0.45 * (hi - lo) / max(np.abs(z - z.mean()).max(), 1e-9), vmax / max(np.abs(zd).max(), 1e-9))
    z0 = z.mean()
    # fade in: e(t) rises from 0 to 1 over 2 s
    Tf = 2.0
    e = np.where(t < Tf, 0.5 - 0.5 * np.cos(np.pi * t / Tf), 1.0)
    ed = np.where(t < Tf, 0.5 * np.pi / Tf * np.sin(np.pi * t / Tf), 0.0)
    edd = np.where(t < Tf, 0.5 * (np.pi / Tf) ** 2 * np.cos(np.pi * t / Tf), 0.0)
    x, xd, xdd = scale * (z - z0), scale * zd, scale * zdd
    q = c + e * x
    v = ed * x + e * xd
    a = edd * x + 2 * ed * xd + e * xdd
    return q, v, a


# ----------------------------------------------------------------------------- the generator


def _draw(rng, effects, duration, sample_rate):
    """Draw the axis, controller and effect parameters; returns (p, info, trajectory arguments)."""
    p = np.zeros(N_PARAMS)
    J = rng.uniform(0.2, 2.0)
    p[P_J] = J
    p[P_JM] = J * rng.uniform(0.3, 0.6)
    p[P_RHO] = 0.0
    kc, kv = rng.uniform(1.0, 5.0), rng.uniform(0.3, 3.0)
    p[P_KC], p[P_KV] = kc, kv
    p[P_VEPS] = rng.uniform(2e-4, 1e-3)
    gear = int(rng.integers(30, 121))
    counts = int(rng.choice([16384, 65536, 262144]))
    p[P_QSTEP] = 2 * np.pi / (counts * gear)
    wc = 2 * np.pi * rng.uniform(3.0, 8.0)
    p[P_KP], p[P_KD], p[P_KI] = J * wc ** 2, 2 * 0.8 * J * wc, J * wc ** 3 / 10.0
    h = 1.0 / sample_rate
    nsub = max(1, int(math.ceil(h / 5e-4 - 1e-9)))
    dt = h / nsub
    p[P_DT], p[P_NSUB] = dt, nsub
    p[P_ALPHA] = 1.0 - math.exp(-2 * np.pi * 80.0 * dt)
    lo, hi = -rng.uniform(0.8, 2.5), rng.uniform(0.8, 2.5)
    vmax = rng.uniform(0.6, 2.5)
    traj = "p2p" if rng.uniform() < 0.6 else "multisine"
    # neutral effect parameters
    p[P_VS], p[P_PFS1], p[P_PFS2], p[P_PLH] = 1.0, 1.0, 1.0, 1.0
    p[P_TC], p[P_FCJ], p[P_FVJ] = 2 * duration + 1.0, 1.0, 1.0
    p[P_TAUE], p[P_PREF] = 1.0, 1.0
    p[P_KCPL], p[P_CCPL] = 0.0, 0.0
    info = {"J": J, "kc": kc, "kv": kv, "gear_ratio": gear, "encoder_counts_per_motor_rev": counts,
            "encoder_step_rad": float(p[P_QSTEP]), "control_bandwidth_hz": wc / (2 * np.pi), "trajectory": traj,
            "range": [lo, hi], "vmax": vmax, "sim_dt": dt, "v_eps": float(p[P_VEPS])}
    draws = {}
    # every effect draws its parameters in a fixed order whether planted or not, so that leaving one out
    # (the visibility check) changes nothing else
    for name in VOCABULARY_EFFECTS + OUT_OF_VOCABULARY:
        draws[name] = rng.uniform(size=8)
    return p, info, (traj, lo, hi, vmax), draws


def _plant(p, info, name, size, u, effects, duration, sample_rate):
    """Set the parameters of one effect (``u``: its 8 uniform draws); returns its truth entry."""
    kc, kv, J, vmax = info["kc"], info["kv"], info["J"], info["vmax"]
    lo, hi = info["range"]
    if name == "stribeck":
        vs = float(effects.get("_vs", vmax * 10 ** (np.log10(0.02) + u[0] * (np.log10(0.15) - np.log10(0.02)))))
        p[P_KS] = size * (0.5 + 0.5 * u[1]) * kc
        p[P_VS] = vs
        p[P_SLAW] = 0.0 if u[2] < 0.5 else 1.0
        return {"ks": float(p[P_KS]), "vs": vs, "law": "gauss" if p[P_SLAW] < 0.5 else "lorentz"}
    if name == "time_periodic_disturbance":
        f = effects.get("_f_hz")
        if f is None:
            f = math.exp(math.log(0.3) + u[0] * (math.log(0.3 * sample_rate) - math.log(0.3)))
        p[P_TPF] = float(f)
        p[P_TPA] = size * (0.3 + 0.3 * u[1]) * kc
        p[P_TPP1], p[P_TPP2] = 2 * np.pi * u[2], 2 * np.pi * u[3]
        return {"frequency_hz": float(f), "amplitude": float(p[P_TPA]), "second_harmonic": 0.25}
    if name == "motor_position_ripple":
        if "_f_per_rad" in effects:
            w = 2 * np.pi * float(effects["_f_per_rad"])
            per_rev = w / info["gear_ratio"]
        else:
            per_rev = float(1 + int(u[0] * 3))
            w = per_rev * info["gear_ratio"]
        p[P_RW] = w
        p[P_RA] = size * (0.15 + 0.15 * u[1]) * kc
        p[P_RP1], p[P_RP2] = 2 * np.pi * u[2], 2 * np.pi * u[3]
        return {"frequency_per_arm_rad": w / (2 * np.pi), "periods_per_motor_rev": per_rev,
                "amplitude": float(p[P_RA])}
    if name == "position_dependent_friction":
        span = hi - lo
        p[P_PFA] = size * (0.3 + 0.2 * u[0]) * kc
        p[P_PFC1], p[P_PFC2] = lo + span * (0.15 + 0.3 * u[1]), lo + span * (0.55 + 0.3 * u[2])
        p[P_PFS1], p[P_PFS2] = span * (0.06 + 0.08 * u[3]), span * (0.06 + 0.08 * u[4])
        p[P_PFW1], p[P_PFW2] = 1.0, -0.5 + 1.5 * u[5]
        return {"amplitude": float(p[P_PFA]), "centers": [float(p[P_PFC1]), float(p[P_PFC2])],
                "widths": [float(p[P_PFS1]), float(p[P_PFS2])]}
    if name == "position_dependent_load":
        p[P_PLA] = size * (0.5 + 0.5 * u[0]) * kc
        p[P_PLQC], p[P_PLH], p[P_PLP] = 0.5 * (lo + hi), 0.5 * (hi - lo), 2 * np.pi * u[1]
        return {"amplitude": float(p[P_PLA]), "spring_center": float(p[P_PLQC])}
    if name == "asymmetric_coulomb":
        p[P_ASY] = size * (0.25 + 0.2 * u[0]) * kc * (1.0 if u[1] < 0.5 else -1.0)
        return {"extra_coulomb_negative_direction": float(p[P_ASY])}
    if name == "abrupt_change":
        p[P_TC] = (0.3 + 0.4 * u[0]) * duration
        f = 1.3 + 0.2 * u[1] if u[2] < 0.5 else 0.6 + 0.15 * u[1]
        p[P_FCJ] = 1.0 + size * (f - 1.0)
        p[P_FVJ] = 1.0 + size * (math.sqrt(f) - 1.0)
        return {"t_change": float(p[P_TC]), "coulomb_factor": float(p[P_FCJ]), "viscous_factor": float(p[P_FVJ])}
    if name == "energy_dependent_friction":
        p[P_TAUE] = (0.15 + 0.2 * u[0]) * duration
        p[P_CE], p[P_VE] = size * 0.3, size * 0.35
        return {"tau_e": float(p[P_TAUE]), "coulomb_drop_per_unit_state": float(p[P_CE]),
                "viscous_exponent": float(p[P_VE])}
    if name in ("backlash", "compliance"):
        p[P_TWO] = 1.0
        p[P_RHO] = 0.3 + 0.2 * u[0]
        Jm, Jl = p[P_JM], p[P_J] - p[P_JM]
        mu = Jm * Jl / J
        if name == "backlash" and p[P_KCPL] == 0.0:
            wn = 2 * np.pi * 40.0
            p[P_KCPL], p[P_CCPL] = mu * wn ** 2, 2 * 0.3 * mu * wn
        if name == "compliance":
            fres = 4.0 + 8.0 * u[1]
            wn = 2 * np.pi * fres
            p[P_KCPL], p[P_CCPL] = mu * wn ** 2, 2 * (0.03 + 0.05 * u[2]) * mu * wn
            out = {"resonance_hz": fres, "damping_ratio": 0.03 + 0.05 * u[2]}
        if name == "backlash":
            p[P_GAP] = size * (0.005 + 0.015 * u[3])
            out = {"band_rad": float(p[P_GAP])}
        return out
    if name == "sensor_delay":
        d = size * (0.01 + 0.03 * u[0])
        p[P_NDELAY] = max(1, int(round(d / p[P_DT])))
        return {"seconds": float(p[P_NDELAY] * p[P_DT])}
    raise ValueError(f"testbench_loop: unknown effect {name}")  # unreachable: generate() checks the names


def _run(p, ref, n_log):
    qr, vr, ar = ref
    y, u, q, v, th = simulate(p, qr, vr, ar, n_log)
    return y, u, q, v, th


def _nominal_residual(t, y, u):
    """Residual of the torque ``u`` after a least-squares fit of the nominal axis [qdd, qd, sign(qd)] (9.2) on
    the samples that the data selection (9.9) keeps (|qd| > 2 % of its 95 % quantile, |qdd| <= 3 x its median
    over the moving samples), derivatives of the logged positions ``y`` over 0.1 s; returns (residual at every
    sample, qd, the selection mask, the moving mask).
    """
    from drake_est.data import smooth_derivatives
    dq, ddq, _ = smooth_derivatives(t, y[:, None], window_s=0.1)
    v, a = dq[:, 0], ddq[:, 0]
    av, aa = np.abs(v), np.abs(a)
    moving = av > 0.02 * np.quantile(av, 0.95)
    sel = moving & (aa <= 3.0 * np.median(aa[moving])) if moving.any() else moving
    A = np.column_stack([a, v, np.sign(v)])
    c = np.linalg.lstsq(A[sel], u[sel], rcond=None)[0]
    return u - A @ c, v, sel, moving


def generate(effects=None, seed: int = 0, duration: float = 120.0, sample_rate: float = 100.0,
             noise: str = "gaussian", noise_std: float = 0.1, prismatic: bool = False, check_visible: bool = True,
             speeds=None, reference_ulps: int = 0):
    """A closed-loop axis log with planted ``effects`` ({name: relative size}, 1 = typical, 1/3 = small;
    optional keys ``_vs`` [rad/s], ``_f_hz`` [Hz], ``_f_per_rad`` [cycles/rad]); returns ``(Log, truth)``.

    ``truth["effects"]``: the planted effects that are visible (module docstring); ``truth["not_visible"]``:
    {name: reason} for those that are not; ``truth["signals"]``: noise-free arrays (true position, velocity,
    thermal state, torque command before the torque noise) at the logged samples.  ``speeds`` (of
    :func:`drake_est.diagnose.testbench.generate`) is accepted for the same call and has no meaning here: the
    speeds come from the reference family.  ``reference_ulps`` = k scales the position reference by
    (1 + k 2^-52): the log then differs from k = 0 in the last digits, as on a CPU whose math library rounds
    differently (the closed loop and the quantized encoder carry such digits into every sample); a test that
    follows one log near a threshold runs over several k so that its claim is not one CPU's last digit.  Unknown
    effects, noise kinds or sizes raise a one-line DataError."""
    from drake_est.data import from_arrays
    from drake_est.errors import DataError

    effects = dict(effects or {})
    planted = {k: float(v) for k, v in effects.items() if not k.startswith("_")}
    for k, size in planted.items():
        if k not in VOCABULARY_EFFECTS + OUT_OF_VOCABULARY:
            known = ", ".join(VOCABULARY_EFFECTS + OUT_OF_VOCABULARY)
            raise DataError(f"effects: unknown effect '{k}' (choose from {known})")
        if not (np.isfinite(size) and size > 0):
            raise DataError(f"effects: the size of '{k}' must be a finite number > 0, got {size}")
    if noise not in ("gaussian", "student_t", "quantized"):
        raise DataError(f"noise: unknown kind '{noise}' (choose from gaussian, student_t, quantized)")
    if not (np.isfinite(duration) and duration > 0 and np.isfinite(sample_rate) and sample_rate > 0):
        raise DataError(f"duration and sample_rate must be finite and > 0, got {duration}, {sample_rate}")
    if isinstance(reference_ulps, bool) or not isinstance(reference_ulps, (int, np.integer)) \
            or not 0 <= reference_ulps <= 1024:
        raise DataError(f"reference_ulps must be an integer in 0..1024, got {reference_ulps!r}")
    rng = np.random.default_rng(seed)
    p0, info, (traj, lo, hi, vmax), draws = _draw(rng, effects, duration, sample_rate)
    n_log = int(round(duration * sample_rate))
    h = 1.0 / sample_rate
    t = np.arange(n_log) * h
    dt = p0[P_DT]
    fam = _quintic_moves if traj == "p2p" else _multisine
    ref = fam(rng, duration + 2 * h, dt, lo, hi, vmax)
    n_sim = n_log * int(p0[P_NSUB])
    ref = tuple(np.ascontiguousarray(r[:n_sim]) for r in ref)
    if reference_ulps:
        ref = (ref[0] * (1.0 + int(reference_ulps) * 2.0 ** -52),) + ref[1:]
    p0[P_Q0] = ref[0][0]
    truth = {"noise": noise, "noise_std": noise_std, **info}

    def params(names):
        p = p0.copy()
        for name in names:
            entry = _plant(p, info, name, planted[name], draws[name], effects, duration, sample_rate)
            truth.setdefault(name, entry)
        # the thermal state's power scale: the mean friction power of the nominal axis along the reference
        v = ref[1]
        p[P_PREF] = max(float(np.mean(info["kc"] * np.abs(v) + info["kv"] * v * v)), 1e-6)
        return p

    names = list(planted)
    y, u, q, v, th = _run(params(names), ref, n_log)
    # torque noise of the log
    if noise == "gaussian":
        e = rng.normal(0, noise_std, n_log)
    elif noise == "student_t":
        e = noise_std / np.sqrt(3.0) * rng.standard_t(3, n_log)
    else:
        e = rng.normal(0, 0.3 * noise_std, n_log)
    tau = u + e
    if noise == "quantized":
        step = 2.0 * noise_std
        tau = step * np.round(tau / step)
    visible, not_visible, shares = [], {}, {}
    if check_visible and names:
        r_all, vhat, sel, mov = _nominal_residual(t, y, u)
        r_null, _, sel0, _ = _nominal_residual(t, *_run(params([]), ref, n_log)[:2])
        noise_var = float(np.var(tau - u)) + float(np.mean(r_null[sel0] ** 2))
        truth["nominal_residual_rms_noise_free"] = float(np.sqrt(np.mean(r_null[sel0] ** 2)))
        moving = sel
        for name in names:
            y2, u2 = _run(params([x for x in names if x != name]), ref, n_log)[:2]
            r_wo, _, sel2, mov2 = _nominal_residual(t, y2, u2)
            # compared on the samples both logs' selections (9.9) keep; an out-of-vocabulary effect, which no
            # vocabulary model is fitted to, on every moving sample (accelerating ones too)
            both = (mov & mov2) if name in OUT_OF_VOCABULARY else (sel & sel2)
            share = float(np.mean((r_all[both] - r_wo[both]) ** 2) / max(noise_var, 1e-300)) if both.any() else 0.0
            shares[name] = share
            why = None
            if share < VISIBLE_SHARE:
                why = f"its part of the nominal residual holds {share:.3f} of the noise variance (< {VISIBLE_SHARE})"
            elif name == "stribeck":
                low = float(np.mean(np.abs(vhat[moving]) < 2 * truth["stribeck"]["vs"])) if moving.any() else 0.0
                truth["stribeck"]["share_moving_below_2vs"] = low
                if low < STRIBECK_LOW_SHARE:
                    why = f"only {low:.3f} of the moving samples are below 2 vs (< {STRIBECK_LOW_SHARE})"
            if why:
                not_visible[name] = why
            else:
                visible.append(name)
    else:
        visible = names
    truth["effects"] = sorted(visible)
    truth["planted"] = sorted(names)
    truth["not_visible"] = not_visible
    truth["visible_share"] = shares
    truth["signals"] = {"q": q, "v": v, "thermal_state": th, "torque_command": u}
    meta = {"file": f"testbench_loop_{'+'.join(sorted(names)) or 'none'}_{seed}"}
    if prismatic:
        meta["axis_type"] = "prismatic"
    log = from_arrays(t, y[:, None], tau[:, None], joints=[1], meta=meta)
    return log, truth


# ----------------------------------------------------------------------------- the first round's axis generator


def axis_log(effect: str, seed: int, duration: float = 180.0, sample_rate: float = 100.0, noise_std: float = 0.3,
             dt: float | None = None):
    """The first round's independent generator (used by ``benchmarks/bench_diagnose.py --other-generator``):
    one rotary axis (inertia J) under a PI velocity controller tracking trapezoidal sweeps, semi-implicit
    Euler at ``dt``, encoder quantization, torque noise; position dependence a sum of sines in q, the ripple
    with gear 83 and a constant amplitude, the energy state driven by |F v|.  Returns ``(Log with t, q1, tau1
    only, truth dict)``."""
    from drake_est.data import Log
    rng = np.random.default_rng(seed)
    J = rng.uniform(0.5, 4.0)
    kc, kv = rng.uniform(2.0, 10.0), rng.uniform(0.5, 5.0)
    dt = dt or min(1.0 / sample_rate, 0.002)
    n = int(round(duration / dt))
    lo, hi = -rng.uniform(1.0, 2.5), rng.uniform(1.0, 2.5)
    levels = rng.uniform(0.1, 1.0, 6)
    t_change = rng.uniform(0.35, 0.65) * duration
    jump = rng.choice([0.6, 1.5])
    tau_e, k_e = rng.uniform(0.1, 0.25) * duration, -rng.uniform(0.3, 0.6) * kc / (0.5 * kc)
    ph = rng.uniform(0, 2 * np.pi, 3)
    q, v, E, integ = 0.0, 0.0, 0.0, 0.0
    direction, vcmd, vref = 1.0, levels[0], 0.0
    every = max(1, int(round(1.0 / (sample_rate * dt))))
    T, Qs, Us = [], [], []
    for k in range(n):
        tk = k * dt
        if (direction > 0 and q >= hi) or (direction < 0 and q <= lo):
            direction = -direction
            vcmd = levels[rng.integers(len(levels))]
        vref += np.clip(direction * vcmd - vref, -2.0 * dt, 2.0 * dt)
        level = kc
        if effect == "position_dependent_friction":
            level += 0.3 * kc * np.sin(2.3 * q + ph[0]) + 0.15 * kc * np.sin(5.1 * q + ph[1])
        if effect == "asymmetric_coulomb" and v < 0:
            level *= 1.5
        kv_k = kv
        if effect == "abrupt_change" and tk >= t_change:
            level *= jump
            kv_k *= jump
        s = np.tanh(v / 1e-3)
        F = kv_k * v + s * (level + E)
        if effect == "motor_position_ripple":
            F += 0.4 * kc * np.sin(83.0 * q + ph[2])
        if effect == "energy_dependent_friction":
            E += dt * (k_e * abs(F * v) - E) / tau_e
        err = vref - v
        integ += err * dt
        u = 40.0 * J * err + 400.0 * J * integ
        if k % every == 0:
            T.append(tk)
            Qs.append(q)
            Us.append(u)
        a = (u - F) / J
        v += a * dt
        q += v * dt
    step = 2 * np.pi / (4096 * 83)
    Qm = np.round(np.array(Qs) / step) * step
    tau = np.array(Us) + noise_std * rng.standard_normal(len(Us))
    truth = {"effects": [] if effect == "none" else [effect], "joints": [1], "noise_std": noise_std,
             "J": J, "kc": kc, "kv": kv}
    return Log(t=np.array(T), q=Qm, tau=tau, joints=[1]), truth
