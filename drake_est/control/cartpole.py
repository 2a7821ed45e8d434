"""The pendulum on a cart of Eqs. (8.11)-(8.12) as an iLQR model (explicit Euler, compiled rollout).

State x = (theta, theta', p, v) with theta = 0 hanging down, input u = cart acceleration:
theta'' = -(g/l) sin theta + (u/l) cos theta - d theta',  p'' = u;  x_{t+1} = x_t + h f(x_t, u_t).
:func:`benchmark_problem` is the fixed problem of ``benchmarks/bench_ilqr.py`` (J* = 786.1796).
"""
from __future__ import annotations

import numpy as np

from drake_est.control import kernels
from drake_est.control.ilqr import Model, QuadraticCost

J_STAR = 786.1796


def cartpole_rhs(x, u, g=9.81, l=1.0, d=0.1):
    """Continuous-time right-hand side of (8.11)-(8.12) for one state x (4,) and input u (scalar or (1,))."""
    u = float(np.asarray(u).ravel()[0])
    th, w, _, v = x
    return np.array([w, -(g / l) * np.sin(th) + (u / l) * np.cos(th) - d * w, v, u])


class CartPoleModel(Model):
    """Explicit-Euler cart-pole (8.11)-(8.12) with analytic first and second derivatives; rollout and
    derivatives are numba kernels (numpy twins used when ``numba=False`` or DRAKE_EST_NO_NUMBA=1)."""
    n = 4
    m = 1
    has_second_order = True

    def __init__(self, h=0.01, g=9.81, l=1.0, d=0.1, numba=None):
        self.h, self.g, self.l, self.d = float(h), float(g), float(l), float(d)
        self.numba = numba
        self._buf = None

    def step(self, t, x, u):
        return np.asarray(x, float) + self.h * cartpole_rhs(x, u, self.g, self.l, self.d)

    def forward(self, x0, Xn, Un, K, k, alpha, lb, ub):
        if not kernels.use_numba(self.numba):
            return super().forward(x0, Xn, Un, K, k, alpha, lb, ub)
        T = Un.shape[0]
        X = np.empty((T + 1, 4))
        U = np.empty((T, 1))
        ok = kernels.cartpole_forward_nb(np.asarray(x0, float), Xn, Un, K, k, float(alpha), lb, ub,
                                         self.h, self.g, self.l, self.d, X, U)
        if not ok:
            X[~np.isfinite(X)] = np.nan
        return X, U, bool(ok)

    def _buffers(self, T):
        if self._buf is None or self._buf[0].shape[0] != T:
            self._buf = (np.zeros((T, 4, 4)), np.zeros((T, 4, 1)), np.zeros((T, 4, 4, 4)),
                         np.zeros((T, 4, 1, 4)), np.zeros((T, 4, 1, 1)))
        return self._buf

    def linearize(self, X, U, second_order=False):
        T = U.shape[0]
        h, g, l, d = self.h, self.g, self.l, self.d
        if kernels.use_numba(self.numba):
            fx, fu, fxx, fux, fuu = (b.copy() for b in self._buffers(T))
            kernels.cartpole_derivs_nb(X, U, h, g, l, d, fx, fu, fxx, fux, bool(second_order))
        else:
            th, u = X[:T, 0], U[:, 0]
            s, c = np.sin(th), np.cos(th)
            fx = np.broadcast_to(np.eye(4), (T, 4, 4)).copy()
            fx[:, 0, 1] = h
            fx[:, 1, 0] = h * (-(g / l) * c - (u / l) * s)
            fx[:, 1, 1] = 1.0 - h * d
            fx[:, 2, 3] = h
            fu = np.zeros((T, 4, 1))
            fu[:, 1, 0] = h * c / l
            fu[:, 3, 0] = h
            fxx = np.zeros((T, 4, 4, 4))
            fux = np.zeros((T, 4, 1, 4))
            fuu = np.zeros((T, 4, 1, 1))
            if second_order:
                fxx[:, 1, 0, 0] = h * ((g / l) * s - (u / l) * c)
                fux[:, 1, 0, 0] = -h * s / l
        if not second_order:
            return fx, fu, None, None, None
        return fx, fu, fxx, fux, fuu


def benchmark_problem(T=400, numba=None):
    """(model, cost, x0, U0, lower, upper) of the issue's fixed cart-pole problem: Q = diag(1, .1, .1, .1),
    R = 0.01, h = 0.01, |u| <= 10, x0 = (pi - 0.1, 0, 0, 0), u = 0 initially (J* = 786.1796 for T = 400)."""
    model = CartPoleModel(h=0.01, numba=numba)
    cost = QuadraticCost(np.diag([1.0, 0.1, 0.1, 0.1]), np.array([[0.01]]))
    x0 = np.array([np.pi - 0.1, 0.0, 0.0, 0.0])
    return model, cost, x0, np.zeros((T, 1)), -10.0, 10.0
