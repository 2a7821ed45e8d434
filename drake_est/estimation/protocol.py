"""The filter protocol shared by every estimator in :mod:`drake_est.estimation` (thesis Ch. 4).

Modelled on LowLevelParticleFilters.jl: a filter is an object holding the model (parameters in the
constructor); its *belief* about the state is a tuple of arrays passed in and out explicitly, so that a
Drake ``LeafSystem`` can keep it in the Context:

* Gaussian filters (Kalman, EKF, UKF): ``(x, P)``;
* particle filters: ``(particles, logw)``.

Per step (conventions of Sec. 4.3): the prior is ``x[0] ~ N(x0, P0)``; at time t the filter first
*corrects* with ``y[t]`` and then *predicts* with ``u[t]``.

    belief = f.initial_belief()
    *belief, ll = f.correct(*belief, y=y_t, u=u_t, t=t)
    belief = f.predict(*belief, u=u_t, t=t)

``forward_trajectory(u, y)`` runs that loop over a log and returns a :class:`FilterResult`; a NaN in a
measurement row means "no measurement at this step": the step only predicts, and the count is reported
in ``FilterResult.n_missing``.  ``loglik(u, y)`` is the log-likelihood of the data (used for parameter
estimation).  Filters may override ``forward_trajectory`` with a fused/compiled loop as long as the
numbers equal the generic loop's (tested to 1e-10).
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np

from drake_est.errors import DataError


@dataclass
class FilterResult:
    """Output of ``forward_trajectory``.

    ``x_filt[t]``/``P_filt[t]`` = x_{t|t}, P_{t|t}; ``x_pred[t]``/``P_pred[t]`` = x_{t|t-1}, P_{t|t-1}
    (``x_pred[T]`` is the one-step prediction past the data); ``loglik`` = sum_t log p(y_t | y_{0:t-1});
    ``n_missing`` counts measurement rows that held NaN (predict-only steps); ``extras`` holds
    filter-specific diagnostics (e.g. the particle filter's effective sample sizes and resampling count)."""
    x_filt: np.ndarray
    P_filt: np.ndarray
    x_pred: np.ndarray
    P_pred: np.ndarray
    loglik: float
    n_missing: int = 0
    extras: dict = field(default_factory=dict)


def check_inputs(u, y, nu: int | None = None, ny: int | None = None):
    """Validate a log for ``forward_trajectory``: returns (u or None, y, T, missing-mask).

    ``y`` is (T, ny); rows containing NaN are missing measurements (counted, not refused); +-inf is
    refused.  ``u`` is (T, nu) or None and must be finite."""
    y = np.asarray(y, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    if y.ndim < 2:
        raise DataError(f"y must be a (T, ny) array, got shape {y.shape}")
    if np.any(np.isinf(y)):
        bad = np.argwhere(np.isinf(y))[0]
        raise DataError(f"y contains infinity (first at index {tuple(int(i) for i in bad)})")
    T = y.shape[0]
    if ny is not None and y.shape[1] != ny:
        raise DataError(f"y has {y.shape[1]} columns, the model measures ny = {ny}")
    missing = np.isnan(y).reshape(T, -1).any(axis=1)
    if u is not None:
        u = np.asarray(u, dtype=float)
        if u.ndim == 1:
            u = u[:, None]
        if u.shape[0] != T:
            raise DataError(f"u has {u.shape[0]} samples but y has {T}")
        if nu is not None and u.shape[1] != nu:
            raise DataError(f"u has {u.shape[1]} columns, the model takes nu = {nu}")
        if not np.all(np.isfinite(u)):
            bad = np.argwhere(~np.isfinite(u))[0]
            raise DataError(f"u contains NaN/Inf (first at index {tuple(int(i) for i in bad)})")
    return u, y, T, missing


class Filter(ABC):
    """Base class of all filters: implement ``initial_belief``, ``predict``, ``correct``, ``mean``, ``cov``."""

    nx: int

    @abstractmethod
    def initial_belief(self) -> tuple:
        """The prior belief at t = 0 (before the first measurement)."""

    @abstractmethod
    def predict(self, *belief, u=None, t: int = 0) -> tuple:
        """Time update with input u[t]: returns the belief at t+1 given data up to t."""

    @abstractmethod
    def correct(self, *belief, y, u=None, t: int = 0) -> tuple:
        """Measurement update with y[t]: returns (*belief, loglik contribution log p(y_t | y_{0:t-1}))."""

    @abstractmethod
    def mean(self, belief) -> np.ndarray:
        """State estimate of a belief."""

    @abstractmethod
    def cov(self, belief) -> np.ndarray:
        """Covariance of a belief."""

    # -- generic loops ---------------------------------------------------------------------------
    def forward_trajectory(self, u, y) -> FilterResult:
        """Generic filter loop over a log: y (T, ny), u (T, nu) or None."""
        u, y, T, missing = check_inputs(u, y, getattr(self, "nu", None), getattr(self, "ny", None))
        belief = self.initial_belief()
        nx = self.nx
        xshape = np.shape(self.mean(belief))        # (nx,), or (nx, r) for a multi-column Kalman state
        xf = np.empty((T,) + xshape)
        Pf = np.empty((T, nx, nx))
        xp = np.empty((T + 1,) + xshape)
        Pp = np.empty((T + 1, nx, nx))
        ll = 0.0
        for t in range(T):
            xp[t], Pp[t] = self.mean(belief), self.cov(belief)
            ut = None if u is None else u[t]
            if not missing[t]:
                *belief, l_t = self.correct(*belief, y=y[t], u=ut, t=t)
                belief = tuple(belief)
                ll += l_t
            xf[t], Pf[t] = self.mean(belief), self.cov(belief)
            belief = self.predict(*belief, u=ut, t=t)
        xp[T], Pp[T] = self.mean(belief), self.cov(belief)
        return FilterResult(xf, Pf, xp, Pp, float(ll), int(missing.sum()))

    def loglik(self, u, y) -> float:
        """Data log-likelihood log p(y_{0:T-1} | u) (for parameter estimation)."""
        return self.forward_trajectory(u, y).loglik
