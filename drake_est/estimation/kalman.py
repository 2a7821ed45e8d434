"""Kalman filter and Rauch-Tung-Striebel smoother (thesis Sec. 4.3).

Model (Eqs. (4.14)-(4.15)), possibly time varying::

    x[t+1] = A_t x[t] + B_t u[t] + v[t],   v ~ N(0, R1_t)
    y[t]   = C_t x[t] + D_t u[t] + e[t],   e ~ N(0, R2_t)

Conventions (as in LowLevelParticleFilters.jl): the filter starts from the prior
``x[0] ~ N(x0, P0)``, i.e. ``x_pred[0] = x0``; at every step it first corrects with
``y[t]`` and then predicts with ``u[t]``.  The measurement update uses the Joseph
form ``P = (I-KC) P (I-KC)^T + K R2 K^T``, which stays symmetric positive
semi-definite in floating point; all gains come from Cholesky solves, never from
explicit inverses.  The state may carry several columns (``x0`` of shape (nx, r)):
the columns share the covariance, which is how the LTV identification of Ch. 7
runs the n rows of ``[A B]`` through one filter.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from drake_est.errors import DataError

_LOG2PI = np.log(2.0 * np.pi)


def _tv(M, T, name, shape=None):
    """Return a callable t -> matrix for a constant (2-D) or time-varying (3-D) array."""
    if M is None:
        return None
    M = np.asarray(M, dtype=float)
    if M.ndim == 2:
        if shape is not None and M.shape != shape:
            raise DataError(f"{name} has shape {M.shape}, expected {shape}")
        return lambda t: M
    if M.ndim == 3:
        if T is not None and M.shape[0] < T:
            raise DataError(f"time-varying {name} has {M.shape[0]} steps, the data have {T}")
        return lambda t: M[t]
    raise DataError(f"{name} must be a matrix or a (T, rows, cols) array, got ndim={M.ndim}")


def _finite(a, name):
    a = np.asarray(a, dtype=float)
    if not np.all(np.isfinite(a)):
        bad = np.argwhere(~np.isfinite(a))[0]
        raise DataError(f"{name} contains NaN/Inf (first at index {tuple(int(i) for i in bad)})")
    return a


@dataclass
class FilterResult:
    """Output of :meth:`KalmanFilter.forward_trajectory`.

    ``x_filt[t]``/``P_filt[t]`` = x_{t|t}, ``x_pred[t]``/``P_pred[t]`` = x_{t|t-1}
    (``x_pred[T]`` is the one-step prediction past the data), ``loglik`` the data
    log-likelihood sum_t log N(y_t; C x_{t|t-1}, S_t)."""
    x_filt: np.ndarray
    P_filt: np.ndarray
    x_pred: np.ndarray
    P_pred: np.ndarray
    loglik: float


@dataclass
class SmoothResult:
    """Output of :meth:`KalmanFilter.smooth`: x_{t|T}, P_{t|T} and the filter pass."""
    x_smooth: np.ndarray
    P_smooth: np.ndarray
    loglik: float
    filtered: FilterResult


class KalmanFilter:
    """Linear Gaussian filter/smoother, Eqs. (4.16)-(4.25), Joseph-form update.

    Parameters are matrices or (T, ., .) arrays for time-varying models.
    ``B``/``D`` may be None (no input).  ``x0`` may be (nx,) or (nx, r)."""

    def __init__(self, A, C, R1, R2, x0, P0, B=None, D=None):
        self.A, self.B, self.C, self.D = A, B, C, D
        self.R1, self.R2 = R1, R2
        self.x0 = _finite(x0, "x0")
        self.P0 = _finite(P0, "P0")
        nx = self.x0.shape[0]
        if self.P0.shape != (nx, nx):
            raise DataError(f"P0 has shape {self.P0.shape}, expected ({nx}, {nx})")
        self.nx = nx

    # -- single steps ------------------------------------------------------------------------
    def predict(self, x, P, u=None, t: int = 0, A=None, B=None, R1=None):
        """Time update (4.16)-(4.17): returns x_{t+1|t}, P_{t+1|t}."""
        A = _tv(self.A, None, "A")(t) if A is None else A
        R1 = _tv(self.R1, None, "R1")(t) if R1 is None else R1
        x = A @ x
        if u is not None and (B is not None or self.B is not None):
            B = _tv(self.B, None, "B")(t) if B is None else B
            x = x + B @ u
        P = A @ P @ A.T + R1
        return x, 0.5 * (P + P.T)

    def correct(self, x, P, y, u=None, t: int = 0, C=None, R2=None, D=None):
        """Measurement update (4.23)-(4.25) in Joseph form.

        Returns (x_{t|t}, P_{t|t}, loglik contribution).  ``C``/``R2`` override the
        model's, which is how extra pseudo-measurements (priors, Eqs. (7.16)-(7.18))
        are incorporated."""
        C = _tv(self.C, None, "C")(t) if C is None else C
        R2 = _tv(self.R2, None, "R2")(t) if R2 is None else R2
        yhat = C @ x
        if u is not None and (D is not None or self.D is not None):
            D = _tv(self.D, None, "D")(t) if D is None else D
            yhat = yhat + D @ u
        e = y - yhat
        PCt = P @ C.T
        S = C @ PCt + R2
        cf = cho_factor(0.5 * (S + S.T), lower=True)
        K = cho_solve(cf, PCt.T).T                      # K = P C^T S^{-1}
        x = x + K @ e
        IKC = np.eye(P.shape[0]) - K @ C
        P = IKC @ P @ IKC.T + K @ R2 @ K.T
        ny = S.shape[0]
        r = 1 if e.ndim == 1 else e.shape[1]
        quad = float(np.sum(e * cho_solve(cf, e)))
        logdet = 2.0 * float(np.sum(np.log(np.diag(cf[0]))))
        ll = -0.5 * (quad + r * (logdet + ny * _LOG2PI))
        return x, 0.5 * (P + P.T), ll

    # -- whole trajectories ------------------------------------------------------------------
    def _check(self, u, y):
        y = _finite(y, "y")
        T = y.shape[0]
        if u is not None:
            u = _finite(u, "u")
            if u.shape[0] != T:
                raise DataError(f"u has {u.shape[0]} samples but y has {T}")
        return u, y, T

    def forward_trajectory(self, u, y) -> FilterResult:
        """Run the filter over y (T, ny[, r]) with inputs u (T, nu[, r]) or None."""
        u, y, T = self._check(u, y)
        x, P = self.x0.copy(), self.P0.copy()
        xf = np.empty((T,) + x.shape)
        Pf = np.empty((T, self.nx, self.nx))
        xp = np.empty((T + 1,) + x.shape)
        Pp = np.empty((T + 1, self.nx, self.nx))
        ll = 0.0
        for t in range(T):
            xp[t], Pp[t] = x, P
            ut = None if u is None else u[t]
            x, P, l = self.correct(x, P, y[t], ut, t)
            ll += l
            xf[t], Pf[t] = x, P
            x, P = self.predict(x, P, ut, t)
        xp[T], Pp[T] = x, P
        return FilterResult(xf, Pf, xp, Pp, ll)

    def smooth(self, u, y) -> SmoothResult:
        """Rauch-Tung-Striebel smoother: x_{t|T}, P_{t|T} for all t."""
        fr = self.forward_trajectory(u, y)
        return SmoothResult(*rts_smooth(fr, self.A), fr.loglik, fr)

    def loglik(self, u, y) -> float:
        """Data log-likelihood log p(y_{0:T-1} | u), computed in the forward pass."""
        return self.forward_trajectory(u, y).loglik


def rts_smooth(fr: FilterResult, A):
    """Backward RTS pass on a :class:`FilterResult`; ``A`` constant or (T, nx, nx).

    G_t = P_{t|t} A_t^T P_{t+1|t}^{-1} (by a Cholesky solve),
    x_{t|T} = x_{t|t} + G_t (x_{t+1|T} - x_{t+1|t}),
    P_{t|T} = P_{t|t} + G_t (P_{t+1|T} - P_{t+1|t}) G_t^T."""
    T = fr.x_filt.shape[0]
    At = _tv(A, None, "A")
    xs = fr.x_filt.copy()
    Ps = fr.P_filt.copy()
    for t in range(T - 2, -1, -1):
        Pf = fr.P_filt[t]
        cf = cho_factor(fr.P_pred[t + 1], lower=True)
        G = cho_solve(cf, At(t) @ Pf).T
        xs[t] = fr.x_filt[t] + G @ (xs[t + 1] - fr.x_pred[t + 1])
        P = Pf + G @ (Ps[t + 1] - fr.P_pred[t + 1]) @ G.T
        Ps[t] = 0.5 * (P + P.T)
    return xs, Ps
