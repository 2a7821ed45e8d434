"""Extended Kalman filter and linearized RTS smoother (thesis Sec. 4.3, the EKF of Eqs. (4.16)-(4.25) with
the model linearized about the current estimate).

Model::

    x[t+1] = f(x[t], u[t], t) + v[t],  v ~ N(0, R1);   y[t] = h(x[t], u[t], t) + e[t],  e ~ N(0, R2)

``f`` and ``h`` broadcast over leading dimensions of x (shape (..., nx)).  Jacobians F = df/dx, H = dh/dx
come from the user (``F=``/``H=`` callables of (x, u, t)), else from Drake's AutoDiffXd when the filter is
built from a Drake system (:meth:`ExtendedKalmanFilter.from_system`), else from central finite differences
(one vectorized call of f or h per Jacobian).  The correction is the project's Joseph-form step
(:func:`drake_est.estimation.gaussian.joseph_correct`) with H in place of C; on a linear model the EKF equals
:class:`~drake_est.estimation.kalman.KalmanFilter` to rounding (tested to 1e-10).
"""
from __future__ import annotations

import numpy as np

from drake_est.errors import DataError
from drake_est.estimation.gaussian import GaussianFilter, check_cov, finite, joseph_correct


def _shape_checked(v, shape, what):
    v = np.asarray(v, dtype=float)
    if v.shape != shape:
        raise DataError(f"{what} returned shape {v.shape}, expected {shape}")
    return v


def fd_jacobian(fun, x, u, t, m, rel_step=1e-6):
    """Central-difference Jacobian d fun(x, u, t) / dx (m, nx), one vectorized call over 2 nx points."""
    nx = x.shape[0]
    h = rel_step * np.maximum(1.0, np.abs(x))
    X = np.concatenate([x + np.diag(h), x - np.diag(h)])
    F = np.asarray(fun(X, u, t), float).reshape(2 * nx, m)
    return ((F[:nx] - F[nx:]) / (2.0 * h[:, None])).T


class ExtendedKalmanFilter(GaussianFilter):
    """EKF implementing :class:`drake_est.estimation.protocol.Filter` (belief (x, P)).

    Arguments: ``f``, ``h`` model functions (see module docstring); ``R1`` (nx, nx) process and ``R2``
    (ny, ny) measurement noise covariances; prior ``x0`` (nx,), ``P0`` (nx, nx); optional Jacobians ``F``,
    ``H``; ``nu`` (input dimension, for checking logs); ``ny`` (inferred from h(x0) if omitted);
    ``fd_step`` relative finite-difference step."""

    def __init__(self, f, h, R1, R2, x0, P0, F=None, H=None, nu: int | None = None, ny: int | None = None,
                 fd_step: float = 1e-6):
        if not callable(f) or not callable(h):
            raise DataError("f and h must be callables f(x, u, t), h(x, u, t)")
        self.f, self.h, self.F, self.H = f, h, F, H
        self.x0 = finite(x0, "x0").reshape(-1)
        nx = self.nx = self.x0.shape[0]
        self.nu = nu
        if ny is None:
            ny = np.atleast_1d(np.asarray(h(self.x0, None if not nu else np.zeros(nu), 0), float)).shape[-1]
        self.ny = int(ny)
        self.R1 = check_cov(R1, "R1", nx, definite=False)
        self.R2 = check_cov(R2, "R2", self.ny, definite=True)
        self.P0 = check_cov(P0, "P0", nx, definite=False)
        if self.R1.ndim != 2 or self.R2.ndim != 2:
            raise DataError("R1 and R2 must be constant (n, n) matrices for the EKF")
        self.fd_step = float(fd_step)

    # -- Jacobians --------------------------------------------------------------------------------
    def jacobian_f(self, x, u, t):
        """F_t = df/dx at (x, u, t): user callable, else central differences."""
        if self.F is not None:
            return _shape_checked(self.F(x, u, t), (self.nx, self.nx), "F")
        return fd_jacobian(self.f, x, u, t, self.nx, self.fd_step)

    def jacobian_h(self, x, u, t):
        """H_t = dh/dx at (x, u, t): user callable, else central differences."""
        if self.H is not None:
            return _shape_checked(self.H(x, u, t), (self.ny, self.nx), "H")
        return fd_jacobian(self.h, x, u, t, self.ny, self.fd_step)

    # -- protocol ---------------------------------------------------------------------------------
    def predict(self, x, P, u=None, t: int = 0):
        """x+ = f(x, u, t), P+ = F P F^T + R1 with F linearized at x_{t|t}."""
        xn = _shape_checked(self.f(x, u, t), (self.nx,), "f")
        Fj = self.jacobian_f(x, u, t)
        Pn = Fj @ P @ Fj.T + self.R1
        return xn, 0.5 * (Pn + Pn.T)

    def correct(self, x, P, y, u=None, t: int = 0):
        """Joseph-form update with innovation y - h(x) and H linearized at x_{t|t-1}."""
        yhat = _shape_checked(self.h(x, u, t), (self.ny,), "h")
        return joseph_correct(x, P, np.asarray(y, float) - yhat, self.jacobian_h(x, u, t), self.R2)

    def smoother_cross(self, t, x_filt, P_filt, u):
        """Linearized RTS: Cov(x_t, x_{t+1} | y_0..y_t) ~ P_{t|t} F_t^T."""
        return P_filt @ self.jacobian_f(x_filt, u, t).T

    # -- from a Drake model -----------------------------------------------------------------------
    @classmethod
    def from_system(cls, system, R1, R2, x0, P0, measurement, **kw):
        """EKF of a discrete-time Drake ``LeafSystem`` or a discrete ``MultibodyPlant`` (x = [q; v]).

        f is the system's discrete update; F from AutoDiffXd scalar conversion when the system supports it
        (a discrete MultibodyPlant does, stepped by ``Simulator_[AutoDiffXd]``), otherwise central differences; ``measurement`` is a callable
        h(x, u, t) or a matrix C (y = C x, H = C).  The model's period is stored as ``self.period``."""
        from drake_est.estimation.drake_model import discrete_model, measurement_function

        f, jac, nx, nu, period = discrete_model(system)
        h, Hj = measurement_function(measurement, nx)
        kw.setdefault("F", jac)
        kw.setdefault("H", Hj)
        ekf = cls(f, h, R1, R2, x0, P0, nu=nu or None, **kw)
        ekf.period = period
        return ekf
