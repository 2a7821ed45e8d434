"""An independent log generator for checking the diagnosis (not :mod:`drake_est.synth`).

A single generic axis (``robot="generic"``), written from scratch with its own trajectory family,
friction law and noise models, so that the diagnosis is not tuned to one generator:

* trajectory: back-and-forth sweeps at several constant speed levels (cosine-smoothed ramps), or at one
  speed only (``speeds=1``), optionally with a slow sinusoidal part;
* nominal axis: tau = J qdd + kv qd + kc sign(qd);
* planted effects (``effects={name: size}``, size 1 = typical, 1/3 = small), vocabulary names of
  :mod:`drake_est.effects` plus out-of-vocabulary ones that must end as "unexplained":
  ``backlash`` (a dead band at each reversal during which the arm-side load is not felt) and
  ``delay`` (torque samples delayed against position samples);
* noise: ``"gaussian"``, ``"student_t"`` (3 degrees of freedom) or ``"quantized"`` (a coarse torque ADC).

:func:`generate` returns ``(Log, truth)``; ``truth["effects"]`` names what was planted.
"""
from __future__ import annotations

import numpy as np

#: out-of-vocabulary effects this generator can plant
OUT_OF_VOCABULARY = ("backlash", "delay")


def _velocity_profile(rng, t, levels, q_lo, q_hi, ramp):
    """Square-wave velocity (forward then back, one period per speed level, cycling through the levels),
    each half lasting at most 4 s or one crossing of [q_lo, q_hi]; rate-limited ramps; q integrated."""
    N = t.size
    h = t[1] - t[0]
    target = np.zeros(N)
    i, k = 0, 0
    while i < N:
        lv = levels[k % len(levels)]
        P = min(4.0, 0.9 * (q_hi - q_lo) / lv)
        n = max(2, int(P / h))
        target[i:i + n] = lv
        target[i + n:i + 2 * n] = -lv
        i += 2 * n
        k += 1
    acc = 4.0 * max(levels) / max(ramp, 1e-3)
    v = np.zeros(N)
    for i in range(1, N):
        v[i] = v[i - 1] + np.clip(target[i] - v[i - 1], -acc * h, acc * h)
    # jerk-limited: a moving average over 0.25 s (smooth corners, as a real trajectory generator gives)
    m = max(1, int(round(0.25 / h)))
    v = np.convolve(np.concatenate([np.zeros(m), v, np.full(m, v[-1])]), np.ones(m) / m, "same")[m:-m]
    # trapezoidal integration: a plain cumulative sum would put q half a sample ahead of v (and of the
    # torque), a built-in delay of h/2 between torque and position samples
    q = q_lo + 0.05 * (q_hi - q_lo) + np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]))]) * h
    return q, v


def generate(effects=None, seed: int = 0, duration: float = 120.0, sample_rate: float = 100.0, speeds: int = 6,
             noise: str = "gaussian", noise_std: float = 0.05, prismatic: bool = False):
    """A generic-axis log with planted ``effects`` ({name: relative size}); returns ``(Log, truth)``."""
    from drake_est.data import from_arrays

    effects = dict(effects or {})
    rng = np.random.default_rng(seed)
    h = 1.0 / sample_rate
    t = np.arange(int(round(duration * sample_rate))) * h
    J = rng.uniform(0.05, 0.5)
    kv = rng.uniform(0.5, 3.0)
    kc = rng.uniform(0.5, 3.0)
    q_lo, q_hi = -rng.uniform(1.0, 2.0), rng.uniform(1.0, 2.0)
    vmax = rng.uniform(0.8, 2.0)
    if speeds <= 1:
        levels = [vmax * rng.uniform(0.4, 0.8)]
    else:
        levels = list(rng.permutation(np.geomspace(0.04 * vmax, vmax, speeds)))
    q, v = _velocity_profile(rng, t, levels, q_lo, q_hi, ramp=0.3)
    a = np.gradient(v, h)
    s = np.sign(v)
    truth = {"effects": sorted(effects), "J": J, "kv": kv, "kc": kc, "levels": [float(x) for x in levels],
             "noise": noise, "noise_std": noise_std}
    kc_t = np.full_like(t, kc)
    kv_t = np.full_like(t, kv)
    extra = np.zeros_like(t)
    for name, size in effects.items():
        if name == "stribeck":
            vs = effects.get("_vs", rng.uniform(0.05, 0.2) * vmax)
            ks = size * rng.uniform(0.6, 1.2) * kc
            delta = float(rng.choice([1.0, 2.0]))
            extra += ks * s * np.exp(-np.abs(v / vs) ** delta)
            truth["stribeck"] = {"ks": ks, "vs": float(vs), "delta": delta}
        elif name == "time_periodic_disturbance":
            f = float(effects.get("_f_hz", rng.uniform(0.5, 0.2 * sample_rate)))
            A = size * rng.uniform(0.3, 0.6) * kc
            extra += A * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
            truth["time_periodic_disturbance"] = {"frequency_hz": f, "amplitude": A}
        elif name == "motor_position_ripple":
            f = float(effects.get("_f_per_rad", rng.uniform(3.0, 12.0)))
            A = size * rng.uniform(0.2, 0.4) * kc
            extra += A * (np.sin(2 * np.pi * f * q + 0.3) + 0.4 * np.sin(4 * np.pi * f * q + 1.1))
            truth["motor_position_ripple"] = {"frequency_per_arm_rad": f, "amplitude": A}
        elif name == "position_dependent_friction":
            A = size * rng.uniform(0.3, 0.5) * kc
            extra += A * s * np.sin(1.7 * q + rng.uniform(0, 6))
        elif name == "position_dependent_load":
            A = size * rng.uniform(0.5, 1.0) * kc
            extra += A * np.sin(q + rng.uniform(0, 6))
        elif name == "asymmetric_coulomb":
            extra += size * rng.uniform(0.25, 0.4) * kc * (v < 0)
        elif name == "abrupt_change":
            tc = rng.uniform(0.3, 0.7) * duration
            H = t >= tc
            kc_t = kc_t + size * 0.35 * kc * H
            kv_t = kv_t + size * 0.25 * kv * H
            truth["abrupt_change"] = {"t_change": tc}
        elif name == "energy_dependent_friction":
            tau_e = rng.uniform(0.15, 0.4) * duration
            W = np.abs((kv * v + kc * s) * v)
            E = np.zeros_like(t)
            alpha = h / tau_e
            for i in range(1, t.size):
                E[i] = E[i - 1] + alpha * (W[i - 1] - E[i - 1])
            E /= max(E.max(), 1e-12)
            kc_t = kc_t * (1.0 - size * 0.3 * E)
            kv_t = kv_t * (1.0 - size * 0.2 * E)
            truth["energy_dependent_friction"] = {"tau_e": tau_e}
        elif name in ("backlash", "delay") or name.startswith("_"):
            pass
        else:
            raise ValueError(f"testbench: unknown effect {name}")
    tau = J * a + kv_t * v + kc_t * s + extra
    q_meas = q.copy()
    if "backlash" in effects:
        # the arm-side load (inertia, viscous part) is not felt while the motor crosses the dead band
        b = effects["backlash"] * rng.uniform(0.03, 0.06)
        qa = np.empty_like(q)
        qa[0] = q[0]
        for i in range(1, t.size):
            qa[i] = min(max(qa[i - 1], q[i] - b / 2), q[i] + b / 2)
        engaged = np.abs(np.diff(qa, prepend=qa[0])) > 0
        tau = np.where(engaged, tau, 0.25 * kc * s + 0.2 * J * a)
        truth["backlash"] = {"band_rad": b}
    if "delay" in effects:
        d = max(1, int(round(effects["delay"] * rng.uniform(0.03, 0.06) * sample_rate)))
        tau = np.concatenate([np.full(d, tau[0]), tau[:-d]])
        truth["delay"] = {"samples": d, "seconds": d * h}
    if noise == "gaussian":
        e = rng.normal(0, noise_std, t.size)
    elif noise == "student_t":
        e = noise_std / np.sqrt(3.0) * rng.standard_t(3, t.size)
    elif noise == "quantized":
        e = rng.normal(0, 0.3 * noise_std, t.size)
    else:
        raise ValueError(f"testbench: unknown noise {noise}")
    tau = tau + e
    if noise == "quantized":
        step = 2.0 * noise_std
        tau = step * np.round(tau / step)
    q_meas = np.round(q_meas / 1e-5) * 1e-5
    meta = {"file": f"testbench_{'+'.join(sorted(effects)) or 'none'}_{seed}"}
    if prismatic:
        meta["axis_type"] = "prismatic"
    log = from_arrays(t, q_meas[:, None], tau[:, None], joints=[1], meta=meta, derivatives=True)
    return log, truth
