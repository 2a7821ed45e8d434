"""Simulation helpers for the LTV examples of thesis Secs. 7.6-7.7 (jump and drift systems).

Split out of :mod:`drake_est.identification.ltv`, which re-exports every name."""
from __future__ import annotations

import numpy as np



# =============================================================================================
# simulation helpers for examples (Secs. 7.6-7.7)
# =============================================================================================
def simulate_ltv(A, B, u, x0=None, sigma_v=0.0, seed=0):
    """x_{t+1} = A_t x_t + B_t u_t + v_t; A (T, n, n) or (n, n); returns x (T+1, n)."""
    rng = np.random.default_rng(seed)
    u = np.asarray(u, float)
    if u.ndim == 1:
        u = u[:, None]
    T = u.shape[0]
    A = np.broadcast_to(np.asarray(A, float), (T,) + np.shape(A)[-2:])
    B = np.broadcast_to(np.asarray(B, float), (T,) + np.shape(B)[-2:])
    n = A.shape[1]
    x = np.zeros((T + 1, n))
    if x0 is not None:
        x[0] = x0
    for t in range(T):
        x[t + 1] = A[t] @ x[t] + B[t] @ u[t] + sigma_v * rng.standard_normal(n)
    return x


def jump_system(T=400, t_switch=200, sigma=0.2, seed=0):
    """The jump-linear system of Sec. 7.6 (Fig. 7.1): A changes at t = t_switch.

    Returns (x (T+1, 2), u (T, 1), y (T, 2) = x_{t+1} + e_t, A_true (T, 2, 2), B_true (T, 2, 1)).
    State-transition and measurement noise both have standard deviation ``sigma``."""
    rng = np.random.default_rng(seed)
    A1 = np.array([[0.95, 0.1], [0.0, 0.95]])
    A2 = np.array([[0.5, 0.05], [0.0, 0.5]])
    Bm = np.array([[0.2], [1.0]])
    A = np.array([A1 if t < t_switch else A2 for t in range(T)])
    B = np.broadcast_to(Bm, (T, 2, 1)).copy()
    u = rng.standard_normal((T, 1))
    x = np.zeros((T + 1, 2))
    for t in range(T):
        x[t + 1] = A[t] @ x[t] + B[t] @ u[t] + sigma * rng.standard_normal(2)
    y = x[1:] + sigma * rng.standard_normal((T, 2))
    return x, u, y, A, B


def drift_system(T=2000, n=3, m=2, sigma_v=0.01, sigma_w=0.001, seed=0):
    """The slowly drifting system of Sec. 7.7: k follows a random walk with std ``sigma_w``,
    the state noise has std ``sigma_v``, inputs are N(0, I).  Returns (x, u, A_true, B_true)."""
    rng = np.random.default_rng(seed)
    A0 = np.diag(rng.uniform(0.8, 0.95, n)) + 0.05 * rng.standard_normal((n, n))
    rad = np.max(np.abs(np.linalg.eigvals(A0)))
    if rad > 0.95:
        A0 *= 0.95 / rad
    B0 = rng.standard_normal((n, m)) * 0.5
    k = np.hstack([A0, B0]).reshape(-1)
    K = k.size
    ks = k + np.cumsum(sigma_w * rng.standard_normal((T, K)), axis=0)
    AB = ks.reshape(T, n, n + m)
    A, B = AB[:, :, :n], AB[:, :, n:]
    u = rng.standard_normal((T, m))
    x = np.zeros((T + 1, n))
    for t in range(T):
        x[t + 1] = A[t] @ x[t] + B[t] @ u[t] + sigma_v * rng.standard_normal(n)
    return x, u, A, B
