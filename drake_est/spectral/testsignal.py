"""The simulated test signal of thesis Sec. 10.3, Eq. (10.21).

``y = sum_w A(w, v) cos(w x - phi(w, v)) + e``, ``e ~ N(0, 0.1^2)``, ``v = linspace(0, 1, N)``,
``x = sort(U(0, 10))``, ``Omega = {4 pi, 20 pi, 100 pi}`` rad per unit, i.e. 2, 10 and 50 cycles
per unit of x, with ``A(4pi, v) = 2 v^2``, ``A(20pi, v) = 2 / (5 v + 1)``,
``A(100pi, v) = 3 exp(-10 (v - 0.5)^2)`` and ``phi = 0.5 A``.
"""
from __future__ import annotations

import numpy as np

#: the frequencies of (10.21) in cycles per unit of x (omega / 2 pi)
TRUE_FREQS = np.array([2.0, 10.0, 50.0])


def true_amplitude(v) -> np.ndarray:
    """(3, M) true amplitude functions of (10.21) at schedule values ``v``."""
    v = np.atleast_1d(np.asarray(v, dtype=float))
    return np.array([2 * v**2, 2 / (5 * v + 1), 3 * np.exp(-10 * (v - 0.5) ** 2)])


def true_phase(v) -> np.ndarray:
    """(3, M) true phase functions ``phi = 0.5 A`` (rad)."""
    return 0.5 * true_amplitude(v)


def thesis_signal(N: int = 500, noise: float = 0.1, seed: int = 0):
    """Returns ``(x, y, v)`` of Eq. (10.21) with ``N`` samples."""
    rng = np.random.default_rng(seed)
    x = np.sort(rng.uniform(0.0, 10.0, N))
    v = np.linspace(0.0, 1.0, N)
    A = true_amplitude(v)
    ph = true_phase(v)
    y = np.sum(A * np.cos(2 * np.pi * TRUE_FREQS[:, None] * x[None, :] - ph), axis=0)
    y = y + noise * rng.standard_normal(N)
    return x, y, v


def ripple_signal(n: int = 45000, gear_ratio: float = 117.0, harmonic: int = 2, a0: float = 0.5,
                  v_half: float = 0.5, coulomb: float = 1.5, viscous: float = 2.0, noise: float = 0.1,
                  sample_rate: float = 100.0, counts_per_motor_rev: int = 4096, seed: int = 0):
    """A quick numpy stand-in for a joint sweep with motor-position torque ripple (no dynamics):
    piecewise-constant velocity levels between +-1 rad, torque
    ``coulomb sign(v) + viscous v + a0 / (1 + |v| / v_half) sin(h * g * q + phase) + noise``,
    position quantized at the motor encoder.  Returns ``(q, v, tau, truth)``; the ripple's
    frequency is ``h g / (2 pi)`` cycles per arm radian and its amplitude falls with speed."""
    rng = np.random.default_rng(seed)
    dt = 1.0 / sample_rate
    levels = rng.uniform(0.05, 1.5, 64) * rng.choice([-1.0, 1.0], 64)
    q = np.empty(n)
    v = np.empty(n)
    qc, li, lo, hi = 0.0, 0, -1.0, 1.0
    seg_len = max(1, n // 64)
    for i in range(n):
        if i and i % seg_len == 0:
            li = (li + 1) % levels.size
        vi = levels[li]
        if (qc >= hi and vi > 0) or (qc <= lo and vi < 0):
            levels[li] = -vi
            vi = -vi
        qc = qc + vi * dt
        q[i], v[i] = qc, vi
    phase = rng.uniform(0, 2 * np.pi)
    ripple = a0 / (1 + np.abs(v) / v_half) * np.sin(harmonic * gear_ratio * q + phase)
    tau = coulomb * np.sign(v) + viscous * v + ripple + noise * rng.standard_normal(n)
    step = 2 * np.pi / (counts_per_motor_rev * gear_ratio)
    qm = np.round(q / step) * step
    truth = {"frequency_per_arm_rad": harmonic * gear_ratio / (2 * np.pi), "gear_ratio": gear_ratio,
             "harmonic": harmonic, "a0": a0, "v_half": v_half, "phase": phase, "ripple": ripple}
    return qm, v, tau, truth
