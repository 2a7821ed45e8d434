"""Kalman filter and Rauch-Tung-Striebel smoother (thesis Sec. 4.3).

Model (Eqs. (4.14)-(4.15)), possibly time varying::

    x[t+1] = A_t x[t] + B_t u[t] + v[t],   v ~ N(0, R1_t)
    y[t]   = C_t x[t] + D_t u[t] + e[t],   e ~ N(0, R2_t)

Conventions (as in LowLevelParticleFilters.jl, :mod:`drake_est.estimation.protocol`): the filter starts
from the prior ``x[0] ~ N(x0, P0)``, i.e. ``x_pred[0] = x0``; at every step it first corrects with ``y[t]``
and then predicts with ``u[t]``; a NaN in a measurement row means "no measurement" (predict only, counted
in ``FilterResult.n_missing``).  The measurement update is the project's single Joseph-form step
(:func:`drake_est.estimation.gaussian.joseph_correct`, Cholesky solves, never an inverse).  The state may
carry several columns (``x0`` of shape (nx, r)): the columns share the covariance, which is how the LTV
identification of Ch. 7 runs the n rows of ``[A B]`` through one filter.

For a constant model with a single state column, :meth:`KalmanFilter.forward_trajectory` and
:meth:`KalmanFilter.smooth` run fused numba loops (:mod:`drake_est.estimation.kalman_kernels`) giving the
generic numpy loop's numbers to 1e-10; ``DRAKE_EST_NO_NUMBA=1`` forces the numpy loop.
"""
from __future__ import annotations

import numpy as np

from drake_est.errors import DataError
from drake_est.estimation import kalman_kernels as _kk
from drake_est.estimation.gaussian import (GaussianFilter, SmoothResult, check_cov, finite, joseph_correct,
                                           rts_backward)
from drake_est.estimation.protocol import FilterResult, check_inputs

__all__ = ["KalmanFilter", "FilterResult", "SmoothResult", "rts_smooth", "kalman_predict", "kalman_correct"]

_finite = finite   # backwards-compatible private name


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


def kalman_predict(x, P, A, R1, B=None, u=None):
    """Time update, Eqs. (4.16)-(4.17): x+ = A x + B u, P+ = A P A^T + R1."""
    x = A @ x
    if B is not None and u is not None:
        x = x + B @ u
    P = A @ P @ A.T + R1
    return x, 0.5 * (P + P.T)


def kalman_correct(x, P, y, C, R2, D=None, u=None):
    """Measurement update, Eqs. (4.23)-(4.25) (Joseph form): returns (x_{t|t}, P_{t|t}, log-likelihood)."""
    yhat = C @ x
    if D is not None and u is not None:
        yhat = yhat + D @ u
    return joseph_correct(x, P, y - yhat, C, R2)


class KalmanFilter(GaussianFilter):
    """Linear Gaussian filter/smoother, Eqs. (4.16)-(4.25), Joseph-form update; implements ``Filter``.

    Parameters are matrices or (T, ., .) arrays for time-varying models.  ``B``/``D`` may be None (no
    input).  ``x0`` may be (nx,) or (nx, r).  R1 and P0 must be positive semidefinite, R2 positive
    definite; A, B, C, D finite (each checked, named in the error)."""

    def __init__(self, A, C, R1, R2, x0, P0, B=None, D=None):
        self.x0 = finite(x0, "x0")
        if self.x0.ndim not in (1, 2):
            raise DataError(f"x0 must be (nx,) or (nx, r), got shape {self.x0.shape}")
        nx = self.x0.shape[0]
        self.nx = nx
        self.A = self._mat(A, "A", (nx, nx))
        self.C = self._mat(C, "C", (None, nx))
        ny = self.C.shape[-2]
        self.ny = ny
        self.B = None if B is None else self._mat(B, "B", (nx, None))
        self.nu = None if self.B is None else self.B.shape[-1]
        self.D = None if D is None else self._mat(D, "D", (ny, self.nu))
        self.R1 = check_cov(R1, "R1", nx, definite=False)
        self.R2 = check_cov(R2, "R2", ny, definite=True)
        self.P0 = check_cov(P0, "P0", nx, definite=False)

    @staticmethod
    def _mat(M, name, shape):
        M = finite(np.atleast_2d(np.asarray(M, dtype=float)), name)
        if M.ndim not in (2, 3):
            raise DataError(f"{name} must be a matrix or a (T, rows, cols) array, got ndim={M.ndim}")
        for got, want, what in zip(M.shape[-2:], shape, ("rows", "columns")):
            if want is not None and got != want:
                raise DataError(f"{name} has {got} {what}, expected {want} (shape {M.shape[-2:]})")
        return M

    @property
    def constant(self) -> bool:
        """True when no model matrix is time varying."""
        return all(M is None or M.ndim == 2 for M in (self.A, self.B, self.C, self.D, self.R1, self.R2))

    # -- single steps (protocol) -----------------------------------------------------------------
    def predict(self, x, P, u=None, t: int = 0, A=None, B=None, R1=None):
        """Time update (4.16)-(4.17): returns x_{t+1|t}, P_{t+1|t}."""
        A = _tv(self.A, None, "A")(t) if A is None else A
        R1 = _tv(self.R1, None, "R1")(t) if R1 is None else R1
        if u is not None and (B is not None or self.B is not None):
            B = _tv(self.B, None, "B")(t) if B is None else B
        else:
            B = None
        return kalman_predict(x, P, A, R1, B, u)

    def correct(self, x, P, y, u=None, t: int = 0, C=None, R2=None, D=None):
        """Measurement update (4.23)-(4.25) in Joseph form.

        Returns (x_{t|t}, P_{t|t}, loglik contribution).  ``C``/``R2`` override the model's, which is how
        extra pseudo-measurements (priors, Eqs. (7.16)-(7.18)) are incorporated."""
        C = _tv(self.C, None, "C")(t) if C is None else C
        R2 = _tv(self.R2, None, "R2")(t) if R2 is None else R2
        if u is not None and (D is not None or self.D is not None):
            D = _tv(self.D, None, "D")(t) if D is None else D
        else:
            D = None
        return kalman_correct(x, P, y, C, R2, D, u)

    def smoother_cross(self, t, x_filt, P_filt, u):
        return P_filt @ _tv(self.A, None, "A")(t).T

    # -- whole trajectories ----------------------------------------------------------------------
    def _check_lengths(self, T):
        for M, name in ((self.A, "A"), (self.B, "B"), (self.C, "C"), (self.D, "D"), (self.R1, "R1"),
                        (self.R2, "R2")):
            if M is not None and M.ndim == 3 and M.shape[0] < T:
                raise DataError(f"time-varying {name} has {M.shape[0]} steps, the data have {T}")

    def _prepare(self, u, y):
        if self.x0.ndim == 2:                           # several state columns: y (T, ny, r)
            y = np.asarray(y, dtype=float)
            if y.ndim != 3 or y.shape[1:] != (self.ny, self.x0.shape[1]):
                raise DataError(f"y must be (T, {self.ny}, {self.x0.shape[1]}) for a (nx, r) state, "
                                f"got shape {y.shape}")
        u, y, T, missing = check_inputs(u, y, self.nu, self.ny)
        self._check_lengths(T)
        return u, y, T, missing

    def _fused_ok(self):
        return _kk.use_numba() and self.constant and self.x0.ndim == 1

    def forward_trajectory(self, u, y, fused: bool | None = None) -> FilterResult:
        """Run the filter over y (T, ny[, r]) with inputs u (T, nu[, r]) or None (NaN rows of y: predict
        only).  ``fused=None`` picks the compiled loop when possible; False forces the numpy loop."""
        u, y, T, missing = self._prepare(u, y)
        if fused is None:
            fused = self._fused_ok()
        if not fused:
            return super().forward_trajectory(u, y)
        nx, ny = self.nx, self.ny
        B = np.zeros((nx, 0)) if self.B is None or u is None else self.B
        uu = np.zeros((T, 0)) if self.B is None or u is None else np.ascontiguousarray(u)
        D = np.zeros((ny, B.shape[1])) if self.D is None or u is None else self.D
        xf = np.empty((T, nx)); Pf = np.empty((T, nx, nx))
        xp = np.empty((T + 1, nx)); Pp = np.empty((T + 1, nx, nx))
        c = np.ascontiguousarray
        ll, bad = _kk.kf_forward(c(self.A), c(B), c(self.C), c(D), c(self.R1), c(self.R2), self.x0.copy(),
                                 c(self.P0), uu, c(np.nan_to_num(y)), missing, xf, Pf, xp, Pp)
        if bad:
            raise DataError(f"innovation covariance S = C P C^T + R2 is not positive definite at step "
                            f"{bad - 1} (check R2)")
        return FilterResult(xf, Pf, xp, Pp, float(ll), int(missing.sum()))

    def smooth(self, u, y, fused: bool | None = None) -> SmoothResult:
        """Rauch-Tung-Striebel smoother: x_{t|T}, P_{t|T} for all t."""
        if fused is None:
            fused = self._fused_ok()
        fr = self.forward_trajectory(u, y, fused=fused)
        if fused:
            xs = np.empty_like(fr.x_filt); Ps = np.empty_like(fr.P_filt)
            bad = _kk.rts_smooth_fused(np.ascontiguousarray(self.A), fr.x_filt, fr.P_filt, fr.x_pred,
                                       fr.P_pred, xs, Ps)
            if bad:
                raise DataError(f"P_pred is not positive definite at step {bad - 1} (RTS smoother; R1 "
                                f"singular?)")
        else:
            xs, Ps = rts_smooth(fr, self.A)
        return SmoothResult(xs, Ps, fr.loglik, fr)


def rts_smooth(fr: FilterResult, A):
    """Backward RTS pass on a :class:`FilterResult`; ``A`` constant or (T, nx, nx).

    G_t = P_{t|t} A_t^T P_{t+1|t}^{-1} (by a Cholesky solve),
    x_{t|T} = x_{t|t} + G_t (x_{t+1|T} - x_{t+1|t}),
    P_{t|T} = P_{t|t} + G_t (P_{t+1|T} - P_{t+1|t}) G_t^T."""
    At = _tv(A, None, "A")
    return rts_backward(fr.x_filt, fr.P_filt, fr.x_pred, fr.P_pred, lambda t: fr.P_filt[t] @ At(t).T)
