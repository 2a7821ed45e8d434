"""iLQR dynamics from a Drake system: values in double, Jacobians by AutoDiffXd (any Drake system that supports
scalar conversion, e.g. a ``MultibodyPlant``).

A continuous system is discretized by explicit Euler with ``substeps`` sub-steps of ``dt / substeps``
(x_{t+1} = x_t + dt/s * xdot, repeated); a discrete system (one periodic discrete update of period ``dt``)
uses its own update.  The input ``u`` is held over the step.
"""
from __future__ import annotations

import numpy as np

from drake_est.control.ilqr import Model
from drake_est.errors import DataError


def _input_port(system, input_port):
    if input_port is not None:
        return system.get_input_port(input_port) if isinstance(input_port, int) else input_port
    if hasattr(system, "get_actuation_input_port"):
        return system.get_actuation_input_port()
    for i in range(system.num_input_ports()):
        p = system.get_input_port(i)
        if p.size() > 0:
            return p
    raise DataError("the Drake system has no vector input port to optimize over")


class DrakeModel(Model):
    """x_{t+1} = F(x_t, u_t) of a Drake ``system`` with AutoDiffXd Jacobians (A_t, B_t).

    ``dt`` [s] step; ``input_port``: index or port object of the input u (default: the actuation input of a
    MultibodyPlant, else the first vector input port); ``fixed_inputs``: {port index: value} for other inputs."""

    def __init__(self, system, dt, input_port=None, substeps=1, fixed_inputs=None):
        if not (dt > 0):
            raise DataError(f"dt must be > 0, got {dt}")
        self.system = system
        self.dt = float(dt)
        self.substeps = int(substeps)
        port = _input_port(system, input_port)
        self._port_index = port.get_index()
        self.ad = system.ToAutoDiffXd()
        self.ctx = system.CreateDefaultContext()
        self.ctx_ad = self.ad.CreateDefaultContext()
        self.continuous = self.ctx.num_continuous_states() > 0
        self.n = self.ctx.num_continuous_states() if self.continuous else self.ctx.get_discrete_state_vector().size()
        self.m = port.size()
        if self.n == 0:
            raise DataError("the Drake system has no state")
        from pydrake.autodiffutils import AutoDiffXd
        for idx, val in (fixed_inputs or {}).items():
            system.get_input_port(idx).FixValue(self.ctx, np.asarray(val, float))
            self.ad.get_input_port(idx).FixValue(self.ctx_ad, np.asarray(val, float).astype(AutoDiffXd))
        self._u_port = system.get_input_port(self._port_index)
        self._u_port_ad = self.ad.get_input_port(self._port_index)
        if not self.continuous:
            self._dstate = system.AllocateDiscreteVariables()
            self._dstate_ad = self.ad.AllocateDiscreteVariables()

    # ---- one step in double
    def _xdot(self, x, u):
        self.ctx.SetContinuousState(x)
        self._u_port.FixValue(self.ctx, u)
        return self.system.EvalTimeDerivatives(self.ctx).CopyToVector()

    def step(self, t, x, u):
        x = np.asarray(x, float).copy()
        u = np.asarray(u, float)
        if self.continuous:
            h = self.dt / self.substeps
            for _ in range(self.substeps):
                x = x + h * self._xdot(x, u)
            return x
        self.ctx.SetDiscreteState(x)
        self._u_port.FixValue(self.ctx, u)
        self.system.CalcForcedDiscreteVariableUpdate(self.ctx, self._dstate)
        return self._dstate.get_vector().CopyToVector()

    # ---- Jacobians by AutoDiffXd
    def _step_ad(self, x, u):
        from pydrake.autodiffutils import InitializeAutoDiffTuple
        xa, ua = InitializeAutoDiffTuple(x, u)
        xa, ua = xa.ravel(), ua.ravel()
        if self.continuous:
            h = self.dt / self.substeps
            for _ in range(self.substeps):
                self.ctx_ad.SetContinuousState(xa)
                self._u_port_ad.FixValue(self.ctx_ad, ua)
                xa = xa + h * self.ad.EvalTimeDerivatives(self.ctx_ad).CopyToVector()
            return xa
        self.ctx_ad.SetDiscreteState(xa)
        self._u_port_ad.FixValue(self.ctx_ad, ua)
        self.ad.CalcForcedDiscreteVariableUpdate(self.ctx_ad, self._dstate_ad)
        return self._dstate_ad.get_vector().CopyToVector()

    def linearize(self, X, U, second_order=False):
        from pydrake.autodiffutils import ExtractGradient
        T = U.shape[0]
        n, m = self.n, self.m
        fx = np.empty((T, n, n))
        fu = np.empty((T, n, m))
        for t in range(T):
            G = ExtractGradient(self._step_ad(X[t], U[t]))
            fx[t] = G[:, :n]
            fu[t] = G[:, n:]
        return fx, fu, None, None, None
