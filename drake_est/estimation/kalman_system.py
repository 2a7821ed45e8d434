"""``KalmanFilterSystem``: the Kalman filter of Sec. 4.3 as a Drake ``LeafSystem``.

A thin wrapper around :class:`drake_est.estimation.kalman.KalmanFilter` (constant A, B, C, D,
R1, R2).  The discrete state holds the one-step prediction (x_{t|t-1}, P_{t|t-1}); the outputs are
the filtered estimate x_{t|t} and covariance P_{t|t}, computed from that state and the current
measurement (direct feedthrough from ``y``); every ``period`` the state advances by a Joseph-form
correction with y_t followed by a prediction with u_t, exactly as
:meth:`KalmanFilter.forward_trajectory` does on a whole log.
"""
from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from drake_est.errors import DataError
from drake_est.estimation.kalman import KalmanFilter


class KalmanFilterSystem(LeafSystem):
    """Discrete-time Kalman filter.

    Input ports: ``u`` (nu) control input [model units]; ``y`` (ny) measurement [model units].
    Output ports: ``state_estimate`` (nx) x_{t|t}; ``covariance`` (nx*nx, row-major) P_{t|t};
    ``log_likelihood`` (1) accumulated log p(y_0..y_{t-1}) of the measurements processed so far.
    """

    def __init__(self, A, B, C, R1, R2, x0, P0, period: float, D=None):
        super().__init__()
        A, C = np.atleast_2d(np.asarray(A, float)), np.atleast_2d(np.asarray(C, float))
        nx, ny = A.shape[0], C.shape[0]
        B = np.zeros((nx, 0)) if B is None else np.asarray(B, float).reshape(nx, -1)
        nu = B.shape[1]
        if period <= 0:
            raise DataError("period must be > 0")
        self._kf = KalmanFilter(A, C, np.atleast_2d(R1), np.atleast_2d(R2), np.asarray(x0, float).reshape(nx),
                                np.atleast_2d(P0), B=B, D=None if D is None else np.asarray(D, float).reshape(ny, nu))
        self._nx, self._nu, self._ny = nx, nu, ny
        init = np.concatenate([self._kf.x0, self._kf.P0.reshape(-1), [0.0]])
        self._state = self.DeclareDiscreteState(BasicVector(init))
        self._u = self.DeclareVectorInputPort("u", nu)
        self._y = self.DeclareVectorInputPort("y", ny)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        dep = {self.xd_ticket(), self._y.ticket(), self._u.ticket()}
        self.DeclareVectorOutputPort("state_estimate", nx, self._calc_x, prerequisites_of_calc=dep)
        self.DeclareVectorOutputPort("covariance", nx * nx, self._calc_P, prerequisites_of_calc=dep)
        self.DeclareVectorOutputPort("log_likelihood", 1, self._calc_ll, prerequisites_of_calc={self.xd_ticket()})

    @property
    def filter(self) -> KalmanFilter:
        return self._kf

    def _read(self, context):
        v = np.array(context.get_discrete_state(self._state).get_value())
        nx = self._nx
        return v[:nx], v[nx:nx + nx * nx].reshape(nx, nx), v[-1]

    def _corrected(self, context):
        x, P, ll = self._read(context)
        y = self._y.Eval(context)
        u = self._u.Eval(context) if self._nu else None
        xc, Pc, l = self._kf.correct(x, P, y, u)
        return xc, Pc, ll + l, u

    def _update(self, context, discrete_state):
        xc, Pc, ll, u = self._corrected(context)
        xn, Pn = self._kf.predict(xc, Pc, u)
        discrete_state.get_mutable_vector(self._state).SetFromVector(np.concatenate([xn, Pn.reshape(-1), [ll]]))

    def _calc_x(self, context, output):
        output.SetFromVector(self._corrected(context)[0])

    def _calc_P(self, context, output):
        output.SetFromVector(self._corrected(context)[1].reshape(-1))

    def _calc_ll(self, context, output):
        output.SetFromVector([self._read(context)[2]])
