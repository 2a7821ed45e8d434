"""Shared pieces of the Gaussian filters (Kalman, EKF, UKF; thesis Sec. 4.3).

* :func:`check_cov` validates a covariance argument (shape, finite, symmetric, positive (semi)definite) and
  names it in the one-line :class:`~drake_est.errors.DataError`;
* :func:`joseph_correct` is the one measurement update of the project (Eqs. (4.23)-(4.25), Joseph form,
  Cholesky solves only), used by the Kalman filter, the EKF and the LTV parameter filter of Ch. 7;
* :func:`rts_backward` is the one Rauch-Tung-Striebel backward pass, written in terms of the cross
  covariance ``Cov(x_t, x_{t+1} | y_0..y_t)`` so that the Kalman (``P_t|t A^T``), linearized (EKF) and
  unscented (UKF) smoothers share it;
* :class:`GaussianFilter` is the common base: belief ``(x, P)``, ``mean``/``cov``, ``smooth``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_est.errors import DataError
from drake_est.estimation.protocol import Filter, FilterResult, check_inputs

_LOG2PI = np.log(2.0 * np.pi)


def finite(a, name):
    """``a`` as a float array; one-line DataError naming ``name`` at the first NaN/Inf."""
    a = np.asarray(a, dtype=float)
    if not np.all(np.isfinite(a)):
        bad = np.argwhere(~np.isfinite(a))[0]
        raise DataError(f"{name} contains NaN/Inf (first at index {tuple(int(i) for i in bad)})")
    return a


def check_cov(M, name: str, n: int | None = None, definite: bool = True, rtol: float = 1e-9):
    """Validate a covariance (n, n) or a time-varying stack (T, n, n).

    ``definite=True`` requires positive definiteness (a Cholesky factor exists), else positive
    semidefiniteness (smallest eigenvalue >= -rtol * largest).  Raises a one-line DataError naming ``name``."""
    M = finite(np.atleast_2d(np.asarray(M, dtype=float)), name)
    if M.ndim not in (2, 3) or M.shape[-1] != M.shape[-2]:
        raise DataError(f"{name} must be a square matrix or a (T, n, n) stack, got shape {M.shape}")
    if n is not None and M.shape[-1] != n:
        raise DataError(f"{name} has shape {M.shape}, expected ({n}, {n})")
    Ms = M.reshape(-1, M.shape[-1], M.shape[-1])
    scale = np.maximum(np.abs(Ms).max(axis=(1, 2)), 1e-300)
    asym = np.abs(Ms - np.swapaxes(Ms, 1, 2)).max(axis=(1, 2))
    if np.any(asym > 1e-8 * scale):
        raise DataError(f"{name} is not symmetric (max |{name} - {name}^T| = {asym.max():.3g})")
    ev = np.linalg.eigvalsh(0.5 * (Ms + np.swapaxes(Ms, 1, 2)))
    if definite:
        bad = ev[:, 0] <= 0
        if np.any(bad):
            k = int(np.argmax(bad))
            where = f" at step {k}" if M.ndim == 3 else ""
            raise DataError(f"{name} is not positive definite{where} (smallest eigenvalue {ev[k, 0]:.3g})")
    else:
        bad = ev[:, 0] < -rtol * np.maximum(ev[:, -1], 1e-300)
        if np.any(bad):
            k = int(np.argmax(bad))
            where = f" at step {k}" if M.ndim == 3 else ""
            raise DataError(f"{name} is not positive semidefinite{where} (smallest eigenvalue {ev[k, 0]:.3g})")
    return M


def chol_lower(P, name: str = "P"):
    """Lower Cholesky factor of P; a one-line DataError naming ``name`` when P is not positive definite."""
    try:
        return np.linalg.cholesky(0.5 * (P + P.T))
    except np.linalg.LinAlgError:
        raise DataError(f"{name} is not positive definite (Cholesky failed)") from None


def innovation_solve(S, M, e, what: str = "innovation covariance S = C P C^T + R2"):
    """Solve with the innovation covariance S (ny, ny): returns (S^{-1} M, log N(e; 0, S) summed over e's
    columns).  Positive definiteness is checked by a Cholesky factor (also giving log det S); the solve is
    one LAPACK call on [M, e] (no inverse).  Plain numpy: scipy's wrappers cost more than the work here."""
    S = 0.5 * (S + S.T)
    try:
        L = np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        raise DataError(f"{what} is not positive definite (check R2)") from None
    ny = S.shape[0]
    E = e.reshape(ny, -1)
    X = np.linalg.solve(S, np.concatenate([M, E], axis=1))
    quad = float(np.sum(E * X[:, M.shape[1]:]))
    logdet = 2.0 * float(np.sum(np.log(np.diag(L))))
    return X[:, :M.shape[1]], -0.5 * (quad + E.shape[1] * (logdet + ny * _LOG2PI))


def joseph_correct(x, P, e, C, R2):
    """Measurement update, Eqs. (4.23)-(4.25), Joseph form (the project's single Kalman correction).

    ``e`` = y - yhat is the innovation (ny,) or (ny, r) (several state columns share P), ``C`` the
    (linearized) measurement matrix.  K = P C^T S^{-1} by a solve, never an inverse;
    P+ = (I - K C) P (I - K C)^T + K R2 K^T.  Returns (x+, P+, log N(e; 0, S))."""
    PCt = P @ C.T
    S = C @ PCt + R2
    Kt, ll = innovation_solve(S, PCt.T, e)
    K = Kt.T
    x = x + K @ e
    IKC = np.eye(P.shape[0]) - K @ C
    P = IKC @ P @ IKC.T + K @ R2 @ K.T
    return x, 0.5 * (P + P.T), ll


def rts_backward(x_filt, P_filt, x_pred, P_pred, cross):
    """Rauch-Tung-Striebel backward pass (Sec. 4.3) in cross-covariance form.

    ``cross[t]`` = Cov(x_t, x_{t+1} | y_0..y_t) (= P_{t|t} A_t^T for a linear model).  With the gain
    G_t = cross[t] P_{t+1|t}^{-1} (a solve, no inverse):
    x_{t|T} = x_{t|t} + G_t (x_{t+1|T} - x_{t+1|t}),  P_{t|T} = P_{t|t} + G_t (P_{t+1|T} - P_{t+1|t}) G_t^T.
    ``cross`` may be a callable t -> matrix.  Returns (x_smooth, P_smooth)."""
    T = x_filt.shape[0]
    xs = x_filt.copy()
    Ps = P_filt.copy()
    get = cross if callable(cross) else (lambda t: cross[t])
    for t in range(T - 2, -1, -1):
        try:
            G = np.linalg.solve(P_pred[t + 1], get(t).T).T
        except np.linalg.LinAlgError:
            raise DataError(f"P_pred is singular at step {t + 1} (RTS smoother; R1 singular?)") from None
        xs[t] = x_filt[t] + G @ (xs[t + 1] - x_pred[t + 1])
        P = P_filt[t] + G @ (Ps[t + 1] - P_pred[t + 1]) @ G.T
        Ps[t] = 0.5 * (P + P.T)
    return xs, Ps


@dataclass
class SmoothResult:
    """Output of ``smooth``: x_{t|T}, P_{t|T}, the data log-likelihood and the forward pass."""
    x_smooth: np.ndarray
    P_smooth: np.ndarray
    loglik: float
    filtered: FilterResult


class GaussianFilter(Filter):
    """Base of the Gaussian filters: belief (x, P); subclasses give predict/correct and ``smoother_cross``."""

    nu: int | None = None
    ny: int | None = None

    def initial_belief(self):
        return self.x0.copy(), self.P0.copy()

    def mean(self, belief):
        return belief[0]

    def cov(self, belief):
        return belief[1]

    def smoother_cross(self, t, x_filt, P_filt, u):
        """Cov(x_t, x_{t+1} | y_0..y_t) from the filtered belief at t (subclass hook)."""
        raise NotImplementedError

    def smooth(self, u, y) -> SmoothResult:
        """RTS-type smoother over a log (Kalman: RTS; EKF: linearized RTS; UKF: unscented RTS)."""
        fr = self.forward_trajectory(u, y)
        u2, _, _, _ = check_inputs(u, y, self.nu, self.ny)
        xs, Ps = rts_backward(fr.x_filt, fr.P_filt, fr.x_pred, fr.P_pred,
                              lambda t: self.smoother_cross(t, fr.x_filt[t], fr.P_filt[t],
                                                            None if u2 is None else u2[t]))
        return SmoothResult(xs, Ps, fr.loglik, fr)
