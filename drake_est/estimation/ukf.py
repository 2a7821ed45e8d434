"""Unscented Kalman filter and unscented RTS smoother (thesis Sec. 4.3; the unscented transform replaces the
linearization of the EKF).

Sigma points (the standard scaled set of Julier and Uhlmann / Wan and van der Merwe): with n = nx,
lambda = alpha^2 (n + kappa) - n, c = sqrt(n + lambda) and L the lower Cholesky factor of P,

    X_0 = x,   X_i = x + c L[:, i],   X_{n+i} = x - c L[:, i]       (i = 1..n)

with mean weights Wm_0 = lambda / (n + lambda), Wm_i = 1 / (2 (n + lambda)) and covariance weights
Wc_0 = Wm_0 + (1 - alpha^2 + beta), Wc_i = Wm_i.  Defaults alpha = 1, beta = 2, kappa = 0 (lambda = 0:
points at +-sqrt(n) standard deviations, no negative weight; beta = 2 is optimal for Gaussian priors and
only matters with alpha != 1).  Small alpha (e.g. 1e-3) gives a negative Wc_0 and may make predicted
covariances indefinite.  P must be positive definite (Cholesky); otherwise a one-line DataError names the
covariance and step.  ``f`` and ``h`` are called once per step on all 2n+1 points (shape (2n+1, nx)).

The unscented RTS smoother uses the sigma-point cross covariance
D_t = sum_i Wc_i (X_i - x_{t|t})(f(X_i) - x_{t+1|t})^T in the shared backward pass
(:func:`drake_est.estimation.gaussian.rts_backward`).  On a linear model the UKF equals the Kalman filter to
rounding (tested to 1e-10).
"""
from __future__ import annotations

import numpy as np
from drake_est.errors import DataError
from drake_est.estimation.ekf import _shape_checked
from drake_est.estimation.gaussian import GaussianFilter, check_cov, finite, innovation_solve


class UnscentedKalmanFilter(GaussianFilter):
    """UKF implementing :class:`drake_est.estimation.protocol.Filter` (belief (x, P)).

    Arguments as :class:`~drake_est.estimation.ekf.ExtendedKalmanFilter` (``f``, ``h``, ``R1``, ``R2``,
    ``x0``, ``P0``, ``nu``, ``ny``) plus the sigma-point parameters ``alpha``, ``beta``, ``kappa``."""

    def __init__(self, f, h, R1, R2, x0, P0, alpha: float = 1.0, beta: float = 2.0, kappa: float = 0.0,
                 nu: int | None = None, ny: int | None = None):
        if not callable(f) or not callable(h):
            raise DataError("f and h must be callables f(x, u, t), h(x, u, t)")
        self.f, self.h = f, h
        self.x0 = finite(x0, "x0").reshape(-1)
        n = self.nx = self.x0.shape[0]
        self.nu = nu
        if ny is None:
            ny = np.atleast_1d(np.asarray(h(self.x0, None if not nu else np.zeros(nu), 0), float)).shape[-1]
        self.ny = int(ny)
        self.R1 = check_cov(R1, "R1", n, definite=False)
        self.R2 = check_cov(R2, "R2", self.ny, definite=True)
        self.P0 = check_cov(P0, "P0", n, definite=True)
        if self.R1.ndim != 2 or self.R2.ndim != 2:
            raise DataError("R1 and R2 must be constant (n, n) matrices for the UKF")
        if not alpha > 0 or not n + kappa > 0:
            raise DataError(f"alpha must be > 0 and nx + kappa > 0 (got alpha={alpha}, kappa={kappa})")
        lam = alpha ** 2 * (n + kappa) - n
        self.alpha, self.beta, self.kappa = float(alpha), float(beta), float(kappa)
        self.c = float(np.sqrt(n + lam))
        self.Wm = np.full(2 * n + 1, 0.5 / (n + lam))
        self.Wm[0] = lam / (n + lam)
        self.Wc = self.Wm.copy()
        self.Wc[0] += 1.0 - alpha ** 2 + beta

    def sigma_points(self, x, P, what: str = "P", t: int = 0):
        """The 2n+1 sigma points (rows) of N(x, P)."""
        try:
            L = np.linalg.cholesky(0.5 * (P + P.T))
        except np.linalg.LinAlgError:
            raise DataError(f"{what} is not positive definite at step {t} (UKF sigma points need its Cholesky "
                            f"factor)") from None
        cL = self.c * L.T
        return np.concatenate([x[None, :], x + cL, x - cL])

    def _f(self, X, u, t):
        return _shape_checked(self.f(X, u, t), X.shape, "f")

    def predict(self, x, P, u=None, t: int = 0):
        """Unscented time update: x+ = sum Wm f(X_i), P+ = sum Wc (f(X_i) - x+)(.)^T + R1."""
        Fx = self._f(self.sigma_points(x, P, "P_filt", t), u, t)
        m = self.Wm @ Fx
        d = Fx - m
        Pn = d.T @ (self.Wc[:, None] * d) + self.R1
        return m, 0.5 * (Pn + Pn.T)

    def correct(self, x, P, y, u=None, t: int = 0):
        """Unscented measurement update: K = Pxy S^{-1} (a solve, S checked by Cholesky), P+ = P - K S K^T."""
        X = self.sigma_points(x, P, "P_pred", t)
        Y = _shape_checked(self.h(X, u, t), (X.shape[0], self.ny), "h")
        yhat = self.Wm @ Y
        dy = Y - yhat
        dx = X - x
        S = dy.T @ (self.Wc[:, None] * dy) + self.R2
        Pxy = dx.T @ (self.Wc[:, None] * dy)
        e = np.asarray(y, float) - yhat
        Kt, ll = innovation_solve(S, Pxy.T, e, what=f"innovation covariance S at step {t}")
        K = Kt.T
        xn = x + K @ e
        Pn = P - K @ S @ K.T
        return xn, 0.5 * (Pn + Pn.T), ll

    def smoother_cross(self, t, x_filt, P_filt, u):
        """Unscented RTS: D_t = sum Wc (X_i - x_{t|t})(f(X_i) - x_{t+1|t})^T."""
        X = self.sigma_points(x_filt, P_filt, "P_filt", t)
        Fx = self._f(X, u, t)
        m = self.Wm @ Fx
        return (X - x_filt).T @ (self.Wc[:, None] * (Fx - m))

    @classmethod
    def from_system(cls, system, R1, R2, x0, P0, measurement, **kw):
        """UKF of a discrete-time Drake ``LeafSystem`` or a discrete ``MultibodyPlant`` (x = [q; v]); f is the
        system's discrete update (evaluated at each sigma point), ``measurement`` a callable h or a matrix C."""
        from drake_est.estimation.drake_model import discrete_model, measurement_function

        f, _, nx, nu, period = discrete_model(system)
        h, _ = measurement_function(measurement, nx)
        ukf = cls(f, h, R1, R2, x0, P0, nu=nu or None, **kw)
        ukf.period = period
        return ukf
