"""``LtvIdentifier``: the online parameter Kalman filter of Ch. 7 as a Drake ``LeafSystem``.

Streams (x_t, u_t) and outputs the current estimates A_t, B_t of the LTV model x_{t+1} = A_t x_t + B_t u_t
and the covariance of k_t = vec([A_t B_t]^T), updated once per ``period`` by the random-walk Kalman filter
(7.2) (:func:`drake_est.identification.ltv.ltv_filter_step`, which runs the project's Kalman steps).  All
filter memory lives in the discrete state of the Context.  (Moved from
``drake_est.identification.ltv_system``, which re-exports it.)
"""
from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from drake_est.errors import DataError
from drake_est.identification.ltv import ltv_filter_init, ltv_filter_step


class LtvIdentifier(LeafSystem):
    """Online LTV identification (random-walk parameter Kalman filter, Eq. (7.2) with H = I).

    Input ports
      * ``state``  x_t (n) [state units]
      * ``input``  u_t (m) [input units]
    Output ports
      * ``state_matrix``  (n*n, row-major) current estimate of A_t [-]
      * ``input_matrix``  (n*m, row-major) current estimate of B_t [state units / input units]
      * ``parameter_covariance``  (K*K, row-major; K = n(n+m)) covariance of k_t = vec([A B]^T) [entries of
        A, B squared]

    Discrete state: [vec(k) (p*n), vec(P) (p*p), x_prev (n), u_prev (m), has_prev (1)], p = n+m.
    Each ``period`` the filter corrects with the regression x_t = [A B][x_prev; u_prev] and then
    adds the random-walk drift sigma_e^2/lam^2 Lambda^{-1} to P.
    """

    def __init__(self, n: int, m: int, lam: float, period: float, sigma_e: float = 1.0, Lambda=None,
                 k0=None, p0: float = 1e4):
        super().__init__()
        if n < 1 or m < 0 or period <= 0 or lam <= 0:
            raise DataError("LtvIdentifier needs n >= 1, m >= 0, period > 0 and lam > 0")
        self._n, self._m, self._p = n, m, n + m
        self._lam, self._sigma_e, self._Lambda = float(lam), float(sigma_e), Lambda
        k, P = ltv_filter_init(n, m, k0, p0)
        x0 = np.concatenate([k.reshape(-1), P.reshape(-1), np.zeros(n + m + 1)])
        self._state = self.DeclareDiscreteState(BasicVector(x0))
        self._state_in = self.DeclareVectorInputPort("state", n)
        self._input_in = self.DeclareVectorInputPort("input", max(m, 0))
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        dep = {self.xd_ticket()}
        self._A_out = self.DeclareVectorOutputPort("state_matrix", n * n, self._calc_A, prerequisites_of_calc=dep)
        self._B_out = self.DeclareVectorOutputPort("input_matrix", n * m, self._calc_B, prerequisites_of_calc=dep)
        K = n * (n + m)
        self._cov_out = self.DeclareVectorOutputPort("parameter_covariance", K * K, self._calc_cov,
                                                     prerequisites_of_calc=dep)

    def get_state_input_port(self):
        return self._state_in

    def get_input_input_port(self):
        return self._input_in

    def get_state_matrix_output_port(self):
        return self._A_out

    def get_input_matrix_output_port(self):
        return self._B_out

    def get_parameter_covariance_output_port(self):
        return self._cov_out

    def _unpack(self, v):
        n, m, p = self._n, self._m, self._p
        i = 0
        k = v[i:i + p * n].reshape(p, n); i += p * n
        P = v[i:i + p * p].reshape(p, p); i += p * p
        xp = v[i:i + n]; i += n
        up = v[i:i + m]; i += m
        return k, P, xp, up, v[i]

    def _update(self, context, discrete_state):
        v = context.get_discrete_state(self._state).get_value()
        k, P, xp, up, has = self._unpack(np.array(v))
        x = self._state_in.Eval(context)
        u = self._input_in.Eval(context) if self._m else np.zeros(0)
        if has > 0.5:
            k, P, _ = ltv_filter_step(k, P, xp, up, x, self._lam, self._sigma_e, self._Lambda)
        out = np.concatenate([k.reshape(-1), P.reshape(-1), x, u, [1.0]])
        discrete_state.get_mutable_vector(self._state).SetFromVector(out)

    def _AB(self, context):
        k, P, *_ = self._unpack(np.array(context.get_discrete_state(self._state).get_value()))
        return k.T, P

    def _calc_A(self, context, output):
        AB, _ = self._AB(context)
        output.SetFromVector(AB[:, :self._n].reshape(-1))

    def _calc_B(self, context, output):
        AB, _ = self._AB(context)
        output.SetFromVector(AB[:, self._n:].reshape(-1))

    def _calc_cov(self, context, output):
        _, P = self._AB(context)
        output.SetFromVector(np.kron(np.eye(self._n), P).reshape(-1))


def contract_cases():
    from drake_est.identification.ltv import ltv_filter
    from drake_est.systems.contract import ContractCase

    x, u = np.array([0.3, -0.2]), np.array([0.5])

    def make():
        return LtvIdentifier(2, 1, lam=10.0, period=0.01, sigma_e=0.2)

    def expected(system):
        # updates at t = 0..0.04: the first stores (x, u), the next four correct with x_t = [A B][x; u]
        r = ltv_filter(np.tile(x, (5, 1)), np.tile(u, (4, 1)), 10.0, sigma_e=0.2)
        return {"state_matrix": r.A[-1].reshape(-1), "input_matrix": r.B[-1].reshape(-1)}

    return [ContractCase(make=make, inputs={"state": x, "input": u}, t_final=0.045, expected=expected,
                         label="LtvIdentifier")]
