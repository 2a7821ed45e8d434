"""Benchmark systems of thesis Sec. 8.6 for the neural dynamics models: random stable linear systems
(Algorithm 5) and the pendulum on a cart (8.11)-(8.12), with their true Jacobians, plus the
eigenvalue-distance Jacobian error of Sec. 8.6."""
from __future__ import annotations

import numpy as np
from scipy.linalg import expm
from scipy.signal import butter, lfilter

from drake_est.errors import DataError


# ---------------------------------------------------------------------------- linear task
def random_stable_system(rng, n=10, m=10, dt=0.02):
    """Random stable discrete-time (A, B) by thesis Algorithm 5: A0 random, A = A0 - A0^T (pure imaginary
    eigenvalues), A - dt I ('slightly' stable), A = exp(dt A); B random."""
    A0 = rng.standard_normal((n, n))
    A = A0 - A0.T
    A = A - dt * np.eye(n)
    return expm(dt * A), rng.standard_normal((n, m))


def lowpass_noise(rng, T, m, cutoff=0.2, order=2):
    """Gaussian noise low-pass filtered by a Butterworth filter with normalized cutoff ``cutoff``
    (fraction of the Nyquist frequency), scaled to unit standard deviation per channel."""
    b, a = butter(order, cutoff)
    w = lfilter(b, a, rng.standard_normal((T + 50, m)), axis=0)[50:]
    return w / w.std(axis=0, keepdims=True)


def simulate_linear(A, B, u, x0=None, noise=0.0, rng=None):
    """x_{t+1} = A x_t + B u_t (+ noise * N(0, I) on the recorded states); returns (T, n) for u (T, m)."""
    T, n = u.shape[0], A.shape[0]
    x = np.zeros((T, n))
    if x0 is not None:
        x[0] = x0
    for t in range(T - 1):
        x[t + 1] = A @ x[t] + B @ u[t]
    if noise > 0:
        x = x + noise * rng.standard_normal(x.shape)
    return x


# ---------------------------------------------------------------------------- pendulum on a cart
CARTPOLE = {"g": 9.81, "l": 1.0, "d": 0.5}


def cartpole_rhs(x, u, g=9.81, l=1.0, d=0.5):
    """Continuous-time dynamics (8.11)-(8.12), state (theta, theta_dot, p, v), input u = cart acceleration.
    Works on (n,) or (B, n) arrays."""
    th, w = x[..., 0], x[..., 1]
    uu = u[..., 0]
    return np.stack([w, -g / l * np.sin(th) + uu / l * np.cos(th) - d * w, x[..., 3], uu], axis=-1)


def _cartpole_rhs_jac(x, u, g, l, d):
    th = x[..., 0]
    uu = u[..., 0]
    shape = x.shape[:-1]
    Jx = np.zeros(shape + (4, 4))
    Ju = np.zeros(shape + (4, 1))
    Jx[..., 0, 1] = 1.0
    Jx[..., 1, 0] = -g / l * np.cos(th) - uu / l * np.sin(th)
    Jx[..., 1, 1] = -d
    Jx[..., 2, 3] = 1.0
    Ju[..., 1, 0] = np.cos(th) / l
    Ju[..., 3, 0] = 1.0
    return Jx, Ju


def cartpole_step(x, u, dt=0.02, g=9.81, l=1.0, d=0.5, jacobian=False):
    """One RK4 step of (8.11)-(8.12) with zero-order-hold input; with ``jacobian=True`` also the exact
    Jacobian [A B] of that discrete map (chain rule through the four stages)."""
    x = np.asarray(x, float)
    u = np.asarray(u, float).reshape(x.shape[:-1] + (1,))
    k1 = cartpole_rhs(x, u, g, l, d)
    k2 = cartpole_rhs(x + 0.5 * dt * k1, u, g, l, d)
    k3 = cartpole_rhs(x + 0.5 * dt * k2, u, g, l, d)
    k4 = cartpole_rhs(x + dt * k3, u, g, l, d)
    xn = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    if not jacobian:
        return xn
    eye = np.broadcast_to(np.eye(4), x.shape[:-1] + (4, 4))
    zer = np.zeros(x.shape[:-1] + (4, 1))
    # d stage / d [x u]: K_i' = Jx(s_i) (ds_i/d[x u]) + [0 Ju(s_i)]
    S = np.concatenate([eye, zer], axis=-1)
    Ks = []
    for c, prev in ((0.0, None), (0.5, 0), (0.5, 1), (1.0, 2)):
        xs = x if prev is None else x + c * dt * (k1, k2, k3)[prev]
        dS = S if prev is None else S + c * dt * Ks[prev]
        Jx, Ju = _cartpole_rhs_jac(xs, u, g, l, d)
        K = Jx @ dS
        K[..., 4:] += Ju
        Ks.append(K)
    J = S + dt / 6 * (Ks[0] + 2 * Ks[1] + 2 * Ks[2] + Ks[3])
    return xn, J


def cartpole_input(rng, T, dt=0.02, n_sines=4, amp=2.0, noise=0.5):
    """Superposition of sine waves of random frequencies and phases plus random noise (Sec. 8.6)."""
    t = np.arange(T) * dt
    freqs = rng.uniform(0.1, 1.5, n_sines)
    phases = rng.uniform(0, 2 * np.pi, n_sines)
    u = amp / np.sqrt(n_sines) * np.sin(2 * np.pi * freqs[None] * t[:, None] + phases[None]).sum(1)
    return (u + noise * rng.standard_normal(T))[:, None]


def simulate_cartpole(rng, T=200, dt=0.02, noise=0.0, **kw):
    """One trajectory (x (T, 4), u (T, 1)) from a random initial state near the bottom."""
    u = cartpole_input(rng, T, dt)
    x = np.zeros((T, 4))
    x[0] = rng.normal(0, [0.5, 0.5, 0.2, 0.2])
    for t in range(T - 1):
        x[t + 1] = cartpole_step(x[t], u[t], dt, **kw)
    if noise > 0:
        x = x + noise * rng.standard_normal(x.shape)
    return x, u


# ---------------------------------------------------------------------------- error measures
def eigenvalue_distance(A_true, A_est):
    """Jacobian error of Sec. 8.6: for each true eigenvalue the distance to the nearest estimated one, and
    vice versa, summed; averaged over points.  A_true (n, n) or (T, n, n), A_est (T, n, n) or (n, n)."""
    At = np.asarray(A_true, float)
    Ae = np.asarray(A_est, float)
    if At.ndim == 2:
        At = At[None]
    if Ae.ndim == 2:
        Ae = Ae[None]
    T = max(At.shape[0], Ae.shape[0])
    if At.shape[0] not in (1, T) or Ae.shape[0] not in (1, T):
        raise DataError(f"A_true has {At.shape[0]} matrices and A_est {Ae.shape[0]}")
    lt = np.linalg.eigvals(At)
    le = np.linalg.eigvals(Ae)
    lt = np.broadcast_to(lt, (T, lt.shape[-1]))
    le = np.broadcast_to(le, (T, le.shape[-1]))
    D = np.abs(lt[:, :, None] - le[:, None, :])
    return float(np.mean(D.min(axis=2).sum(axis=1) + D.min(axis=1).sum(axis=1)))


def jacobian_error(J_true, J_est):
    """Mean over points of the Frobenius norm ||J_est - J_true||_F (pendulum task, Sec. 8.6)."""
    D = np.asarray(J_est, float) - np.asarray(J_true, float)
    return float(np.mean(np.sqrt(np.sum(D.reshape(D.shape[0], -1) ** 2, axis=1))))
