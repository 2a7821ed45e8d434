"""Gaussian state estimators (thesis Sec. 4.3) as Drake ``LeafSystem``s: Kalman filter, EKF, UKF.

Thin wrappers around :class:`~drake_est.estimation.kalman.KalmanFilter`,
:class:`~drake_est.estimation.ekf.ExtendedKalmanFilter` and :class:`~drake_est.estimation.ukf.UnscentedKalmanFilter`
(every number comes from the filter's ``correct``/``predict``).  The discrete state (one ``BasicVector``) holds
the one-step prediction x_{k|k-1}, P_{k|k-1} (row-major), the step counter k and the accumulated
log-likelihood.  Every ``period`` (the measurement rate) the state advances by a correction with the
``measurement`` port (any NaN entry: no measurement, predict only) followed by a prediction with the
``control`` port, exactly as ``forward_trajectory`` does on a whole log.  The outputs ``estimate`` and
``covariance`` are the corrected x_{k|k}, P_{k|k} (direct feedthrough from ``measurement``).

One-line constructors: from matrices (:class:`KalmanFilterSystem`), from callables f, h
(``ExtendedKalmanFilterSystem(f, h, R1, R2, x0, P0, period)``), or from a Drake model
(``ExtendedKalmanFilterSystem.from_system(system, R1, R2, x0, P0, measurement=C)``, a discrete-time
``LeafSystem`` or a ``MultibodyPlant`` with a time step).  The particle filter's system lives in
:mod:`drake_est.systems.particle_filter`.
"""
from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from drake_est.errors import DataError
from drake_est.estimation.ekf import ExtendedKalmanFilter
from drake_est.estimation.kalman import KalmanFilter
from drake_est.estimation.ukf import UnscentedKalmanFilter

_PORT_DOC = """
    Input ports: ``measurement`` (ny) y_k [model units] (NaN entries: no measurement this step);
    ``control`` (nu, only when nu > 0) u_k [model units].
    Output ports: ``estimate`` (nx) x_{k|k} [model units]; ``covariance`` (nx*nx, row-major) P_{k|k}
    [model units^2]; ``log_likelihood`` (1) accumulated log p(y_0..y_{k-1}) [nats].
"""


class _GaussianFilterSystem(LeafSystem):
    """Shared machinery of the Gaussian estimator systems (see the module docstring)."""

    def __init__(self, filt, period: float, nu: int):
        super().__init__()
        if not period > 0:
            raise DataError(f"period must be > 0, got {period}")
        self._filter = filt
        self._period = float(period)
        self._nx, self._ny, self._nu = filt.nx, int(filt.ny), int(nu)
        x0, P0 = filt.initial_belief()
        init = np.concatenate([np.asarray(x0, float).reshape(-1), np.asarray(P0, float).reshape(-1), [0.0, 0.0]])
        self._state = self.DeclareDiscreteState(BasicVector(init))
        self._measurement = self.DeclareVectorInputPort("measurement", self._ny)
        self._control = self.DeclareVectorInputPort("control", self._nu) if self._nu else None
        self.DeclarePeriodicDiscreteUpdateEvent(self._period, 0.0, self._update)
        dep = {self.xd_ticket(), self._measurement.ticket()}
        if self._control is not None:
            dep.add(self._control.ticket())
        nx = self._nx
        self._estimate = self.DeclareVectorOutputPort("estimate", nx, self._calc_x, prerequisites_of_calc=dep)
        self._covariance = self.DeclareVectorOutputPort("covariance", nx * nx, self._calc_P,
                                                        prerequisites_of_calc=dep)
        self._loglik = self.DeclareVectorOutputPort("log_likelihood", 1, self._calc_ll,
                                                    prerequisites_of_calc={self.xd_ticket()})

    @classmethod
    def wrap(cls, filt, period: float):
        """A system of this class around an existing filter object (used by ``from_system``)."""
        self = cls.__new__(cls)
        _GaussianFilterSystem.__init__(self, filt, period, filt.nu or 0)
        return self

    @property
    def filter(self):
        """The plain filter object this system wraps."""
        return self._filter

    def get_measurement_input_port(self):
        return self._measurement

    def get_control_input_port(self):
        return self._control

    def get_estimate_output_port(self):
        return self._estimate

    def get_covariance_output_port(self):
        return self._covariance

    def get_log_likelihood_output_port(self):
        return self._loglik

    def _read(self, context):
        v = context.get_discrete_state(self._state).get_value()
        nx = self._nx
        return (np.array(v[:nx]), np.array(v[nx:nx + nx * nx]).reshape(nx, nx), int(round(v[-2])), float(v[-1]))

    def _corrected(self, context):
        x, P, k, ll = self._read(context)
        y = np.asarray(self._measurement.Eval(context), float)
        u = np.asarray(self._control.Eval(context), float) if self._control is not None else None
        if not np.isnan(y).any():
            x, P, l_k = self._filter.correct(x, P, y, u, k)
            ll += l_k
        return x, P, k, ll, u

    def _update(self, context, discrete_state):
        x, P, k, ll, u = self._corrected(context)
        xn, Pn = self._filter.predict(x, P, u, k)
        discrete_state.get_mutable_vector(self._state).SetFromVector(
            np.concatenate([np.asarray(xn, float).reshape(-1), np.asarray(Pn, float).reshape(-1), [k + 1, ll]]))

    def _calc_x(self, context, output):
        output.SetFromVector(self._corrected(context)[0])

    def _calc_P(self, context, output):
        output.SetFromVector(self._corrected(context)[1].reshape(-1))

    def _calc_ll(self, context, output):
        output.SetFromVector([self._read(context)[3]])


class KalmanFilterSystem(_GaussianFilterSystem):
    """Discrete-time Kalman filter (Eqs. (4.16)-(4.25)) for constant A, B, C, D, R1, R2, updated every
    ``period`` [s].
    """

    def __init__(self, A, B, C, R1, R2, x0, P0, period: float, D=None):
        A, C = np.atleast_2d(np.asarray(A, float)), np.atleast_2d(np.asarray(C, float))
        nx, ny = A.shape[0], C.shape[0]
        B = np.zeros((nx, 0)) if B is None else np.asarray(B, float).reshape(nx, -1)
        nu = B.shape[1]
        kf = KalmanFilter(A, C, np.atleast_2d(R1), np.atleast_2d(R2), np.asarray(x0, float).reshape(nx),
                          np.atleast_2d(P0), B=B if nu else None,
                          D=None if D is None else np.asarray(D, float).reshape(ny, nu))
        super().__init__(kf, period, nu)


class ExtendedKalmanFilterSystem(_GaussianFilterSystem):
    """Extended Kalman filter (linearized Sec. 4.3 filter) for x+ = f(x, u, t) + v, y = h(x, u, t) + e,
    updated every ``period`` [s]; ``t`` passed to f and h is the step index k.
    """

    def __init__(self, f, h, R1, R2, x0, P0, period: float, nu: int = 0, **kw):
        super().__init__(ExtendedKalmanFilter(f, h, R1, R2, x0, P0, nu=nu or None, **kw), period, nu)

    @classmethod
    def from_system(cls, system, R1, R2, x0, P0, measurement, **kw):
        """From a discrete-time Drake ``LeafSystem`` or a discrete ``MultibodyPlant`` (see
        :meth:`ExtendedKalmanFilter.from_system`); the period is the model's."""
        ekf = ExtendedKalmanFilter.from_system(system, R1, R2, x0, P0, measurement=measurement, **kw)
        return cls.wrap(ekf, ekf.period)


class UnscentedKalmanFilterSystem(_GaussianFilterSystem):
    """Unscented Kalman filter (sigma points, see :mod:`drake_est.estimation.ukf`) for x+ = f(x, u, t) + v,
    y = h(x, u, t) + e, updated every ``period`` [s]; ``t`` passed to f and h is the step index k.
    """

    def __init__(self, f, h, R1, R2, x0, P0, period: float, nu: int = 0, **kw):
        super().__init__(UnscentedKalmanFilter(f, h, R1, R2, x0, P0, nu=nu or None, **kw), period, nu)

    @classmethod
    def from_system(cls, system, R1, R2, x0, P0, measurement, **kw):
        """From a discrete-time Drake ``LeafSystem`` or a discrete ``MultibodyPlant``; the period is the model's."""
        ukf = UnscentedKalmanFilter.from_system(system, R1, R2, x0, P0, measurement=measurement, **kw)
        return cls.wrap(ukf, ukf.period)



for _cls in (KalmanFilterSystem, ExtendedKalmanFilterSystem, UnscentedKalmanFilterSystem):
    _cls.__doc__ = _cls.__doc__.rstrip() + "\n" + _PORT_DOC


# --------------------------------------------------------------------------------------------- contract
def _contract_model():
    A = np.array([[1.0, 0.01], [-0.05, 0.99]])
    B = np.array([[0.0], [0.01]])
    C = np.array([[1.0, 0.0]])

    def f(x, u, t):
        return x @ A.T + u @ B.T

    def h(x, u, t):
        return np.sin(x[..., :1])

    return A, B, C, f, h, 1e-4 * np.eye(2), np.array([[0.01]]), np.array([0.1, 0.0]), 0.05 * np.eye(2)


def contract_cases():
    from drake_est.systems.contract import ContractCase

    A, B, C, f, h, R1, R2, x0, P0 = _contract_model()
    y, u = np.array([0.12]), np.array([0.5])

    def expected(system):
        # updates at t = 0, 0.01, ..., 0.04 (t_final 0.045 lies between updates): x_filt[5] of a 6-step log
        r = system.filter.forward_trajectory(np.tile(u, (6, 1)), np.tile(y, (6, 1)))
        return {"estimate": r.x_filt[5], "covariance": r.P_filt[5].reshape(-1),
                "log_likelihood": [system.filter.forward_trajectory(np.tile(u, (5, 1)), np.tile(y, (5, 1))).loglik]}

    makers = {
        "KalmanFilterSystem": lambda: KalmanFilterSystem(A, B, C, R1, R2, x0, P0, period=0.01),
        "ExtendedKalmanFilterSystem": lambda: ExtendedKalmanFilterSystem(f, h, R1, R2, x0, P0, period=0.01, nu=1),
        "UnscentedKalmanFilterSystem": lambda: UnscentedKalmanFilterSystem(f, h, R1, R2, x0, P0, period=0.01,
                                                                           nu=1),
    }
    return [ContractCase(make=mk, inputs={"measurement": y, "control": u}, t_final=0.045, expected=expected,
                         label=name) for name, mk in makers.items()]
