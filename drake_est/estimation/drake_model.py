"""Turn a discrete-time Drake model into ``f(x, u, t)`` (and its Jacobian) for the Gaussian filters.

* a discrete-time ``LeafSystem`` with one periodic discrete update and one discrete state group: x is its
  discrete state, u its first input port (if any); ``f`` evaluates ``EvalUniquePeriodicDiscreteUpdate``;
  the Jacobian df/dx comes from the system's AutoDiffXd scalar conversion (exact) when it has one, else None
  (the caller falls back to finite differences);
* a ``MultibodyPlant`` with a time step: x = [q; v], u = actuation; one step is advanced by a ``Simulator``
  over one period (the plant's discrete step is not exposed as a unique periodic update); the Jacobian comes
  from the same step on the plant's AutoDiffXd scalar conversion (``Simulator_[AutoDiffXd]``, exact).

``f`` broadcasts over leading dimensions of x (rows evaluated one by one through the Context).
"""
from __future__ import annotations

import numpy as np

from drake_est.errors import DataError


def discrete_model(system):
    """Returns (f, jac, nx, nu, period): f(x, u, t) over (..., nx); jac(x, u, t) -> (nx, nx) or None."""
    from pydrake.multibody.plant import MultibodyPlant

    ctx = system.CreateDefaultContext()
    if isinstance(system, MultibodyPlant):
        if not system.time_step() > 0:
            raise DataError("system: the MultibodyPlant must be discrete (time_step > 0)")
        from pydrake.systems.analysis import Simulator
        period = system.time_step()
        nx, nu = system.num_multibody_states(), system.num_actuated_dofs()
        uport = system.get_actuation_input_port()
        sim = Simulator(system, ctx)

        def step(x, u):
            if nu:
                uport.FixValue(ctx, np.zeros(nu) if u is None else np.asarray(u, float))
            else:
                uport.FixValue(ctx, np.zeros(0))
            ctx.SetTime(0.0)
            system.SetPositionsAndVelocities(ctx, x)
            sim.Initialize()
            sim.AdvanceTo(period)
            return system.GetPositionsAndVelocities(ctx).copy()

        jac = None
        try:
            ad = system.ToAutoDiffXd()
        except Exception:
            ad = None
        if ad is not None:
            from pydrake.autodiffutils import AutoDiffXd, ExtractGradient, InitializeAutoDiff
            from pydrake.systems.analysis import Simulator_
            ctx_ad = ad.CreateDefaultContext()
            sim_ad = Simulator_[AutoDiffXd](ad, ctx_ad)
            uport_ad = ad.get_actuation_input_port()

            def jac(x, u, t=0):
                uu = np.zeros(nu) if u is None else np.asarray(u, float)
                uport_ad.FixValue(ctx_ad, np.array([AutoDiffXd(float(v), np.zeros(nx)) for v in uu]))
                ctx_ad.SetTime(0.0)
                ad.SetPositionsAndVelocities(ctx_ad, InitializeAutoDiff(np.asarray(x, float)).ravel())
                sim_ad.Initialize()
                sim_ad.AdvanceTo(period)
                return ExtractGradient(ad.GetPositionsAndVelocities(ctx_ad)).reshape(nx, nx)
    else:
        try:
            period = system.GetUniquePeriodicDiscreteUpdateAttribute().period_sec()
        except Exception:
            raise DataError("system must have exactly one periodic discrete update (a discrete-time model)") \
                from None
        if ctx.num_discrete_state_groups() != 1:
            raise DataError("system must have exactly one discrete state group (the model state x)")
        nx = ctx.get_discrete_state_vector().size()
        uport = system.get_input_port(0) if system.num_input_ports() else None
        nu = uport.size() if uport is not None else 0

        def step(x, u):
            if uport is not None:
                uport.FixValue(ctx, np.zeros(nu) if u is None else np.asarray(u, float))
            ctx.SetDiscreteState(np.asarray(x, float))
            return system.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector().CopyToVector()[:nx].copy()

        jac = None
        try:
            ad = system.ToAutoDiffXd()
        except Exception:
            ad = None
        if ad is not None:
            from pydrake.autodiffutils import AutoDiffXd, ExtractGradient, InitializeAutoDiff
            ctx_ad = ad.CreateDefaultContext()
            uport_ad = ad.get_input_port(0) if nu else None

            def jac(x, u, t=0):
                if uport_ad is not None:
                    uu = np.zeros(nu) if u is None else np.asarray(u, float)
                    uport_ad.FixValue(ctx_ad, np.array([AutoDiffXd(float(v), np.zeros(nx)) for v in uu]))
                ctx_ad.SetDiscreteState(InitializeAutoDiff(np.asarray(x, float)).ravel())
                out = ad.EvalUniquePeriodicDiscreteUpdate(ctx_ad).get_vector().CopyToVector()[:nx]
                return ExtractGradient(out).reshape(nx, nx)

    def f(x, u, t):
        x = np.asarray(x, float)
        flat = x.reshape(-1, nx)
        out = np.empty_like(flat)
        for i in range(flat.shape[0]):
            out[i] = step(flat[i], u)
        return out.reshape(x.shape)

    return f, jac, nx, nu, period


def measurement_function(measurement, nx):
    """``measurement``: a callable h(x, u, t) (broadcasting over (..., nx)) or a matrix C (y = C x).
    Returns (h, H) with H(x, u, t) the Jacobian (C for a matrix, None for a callable)."""
    if callable(measurement):
        return measurement, None
    C = np.atleast_2d(np.asarray(measurement, float))
    if C.ndim != 2 or C.shape[1] != nx:
        raise DataError(f"measurement must be a callable h(x, u, t) or a (ny, {nx}) matrix, got shape {C.shape}")

    def h(x, u, t):
        return np.asarray(x, float) @ C.T
    return h, (lambda x, u, t: C)
