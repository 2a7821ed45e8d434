"""``ParticleFilterEstimator``: the particle filter of Sec. 4.2 (Algorithm 1) as a Drake ``LeafSystem``.

A thin wrapper around :class:`drake_est.estimation.pf.ParticleFilter`: every ``period`` it corrects with
the ``measurement`` port (a NaN entry = no measurement: predict only) and predicts with the ``control``
port.  The discrete state is one ``BasicVector``: the N x nx particles (row-major), the N log-weights, the
step counter k and the accumulated log-likelihood.  Random draws come from the filter's seed and k (the
filter's ``normals(k)``/``uniform(k)``/``rng(k)``), never from hidden generator state, so two Contexts
are independent and a Simulator reproduces :meth:`ParticleFilter.forward_trajectory` exactly.

Build it in one line from callables (:meth:`ParticleFilterEstimator.gaussian`) or from a Drake model
(:meth:`ParticleFilterEstimator.from_system`: a discrete-time ``LeafSystem`` or a ``MultibodyPlant`` with
a time step, plus noise covariances).
"""
from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from drake_est.errors import DataError
from drake_est.estimation.pf import ParticleFilter, chol_psd, logsumexp, weighted_moments


class ParticleFilterEstimator(LeafSystem):
    """Particle-filter state estimator, periodic discrete update at the measurement rate.

    Input ports: ``measurement`` (ny) y_k [model units] (NaN entries: no measurement this step);
    ``control`` (nu, only when nu > 0) u_k [model units].
    Output ports: ``estimate`` (nx) x_{k|k}, the weighted particle mean after weighting with the current
    measurement [model units]; ``covariance`` (nx*nx, row-major) its weighted covariance [model units^2];
    ``particles`` (N*nx, row-major) the particle cloud x_{k|k-1} held in the state [model units];
    ``log_likelihood`` (1) accumulated log p(y_0..y_{k-1}) [nats].
    """

    def __init__(self, pf: ParticleFilter, period: float, nu: int = 0):
        super().__init__()
        if not period > 0:
            raise DataError(f"period must be > 0, got {period}")
        if pf.ny is None:
            raise DataError("the particle filter must know ny (pass ny= to ParticleFilter)")
        self._pf = pf
        self._N, self._nx, self._ny, self._nu = pf.N, pf.nx, int(pf.ny), int(nu)
        x, logw = pf.initial_belief()
        init = np.concatenate([x.reshape(-1), logw, [0.0, 0.0]])
        self._state = self.DeclareDiscreteState(BasicVector(init))
        self._measurement = self.DeclareVectorInputPort("measurement", self._ny)
        self._control = self.DeclareVectorInputPort("control", self._nu) if self._nu else None
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        dep = {self.xd_ticket(), self._measurement.ticket()}
        if self._control is not None:
            dep.add(self._control.ticket())
        self._estimate = self.DeclareVectorOutputPort("estimate", self._nx, self._calc_estimate,
                                                      prerequisites_of_calc=dep)
        self._covariance = self.DeclareVectorOutputPort("covariance", self._nx * self._nx, self._calc_cov,
                                                        prerequisites_of_calc=dep)
        self._particles = self.DeclareVectorOutputPort("particles", self._N * self._nx, self._calc_particles,
                                                       prerequisites_of_calc={self.xd_ticket()})
        self._loglik = self.DeclareVectorOutputPort("log_likelihood", 1, self._calc_ll,
                                                    prerequisites_of_calc={self.xd_ticket()})

    # -- one-line constructors ---------------------------------------------------------------------
    @classmethod
    def gaussian(cls, f, h, R1, R2, x0, P0, period: float, n_particles: int = 500, seed: int = 0,
                 nu: int = 0):
        """From callables: x+ = f(x,u,t) + v, y = h(x,u,t) + e (see :meth:`ParticleFilter.gaussian`)."""
        pf = ParticleFilter.gaussian(f, h, R1, R2, x0, P0, n_particles=n_particles, seed=seed,
                                     nu=nu if nu else None)
        return cls(pf, period, nu=nu)

    @classmethod
    def from_system(cls, system, h, R1, R2, x0, P0, n_particles: int = 500, seed: int = 0):
        """From a Drake model: a discrete-time ``LeafSystem`` (one periodic discrete update, its discrete
        state is x, its first input port (if any) is u) or a ``MultibodyPlant`` with a time step
        (x = [q; v], u = actuation).  ``h`` is a callable h(x, u, t) broadcasting over (..., nx) or a
        matrix C (y = C x).  R1/R2: process/measurement noise covariances.  The period is the model's."""
        from pydrake.multibody.plant import MultibodyPlant

        ctx = system.CreateDefaultContext()
        if isinstance(system, MultibodyPlant):
            if not system.time_step() > 0:
                raise DataError("system: the MultibodyPlant must be discrete (time_step > 0)")
            period = system.time_step()
            nx = system.num_multibody_states()
            uport = system.get_actuation_input_port()
            nu = system.num_actuated_dofs()

            def set_x(x):
                system.SetPositionsAndVelocities(ctx, x)
        else:
            try:
                period = system.GetUniquePeriodicDiscreteUpdateAttribute().period_sec()
            except Exception:
                raise DataError("system must have exactly one periodic discrete update (a discrete-time "
                                "model)") from None
            if ctx.num_discrete_state_groups() != 1:
                raise DataError("system must have exactly one discrete state group (the model state x)")
            nx = ctx.get_discrete_state_vector().size()
            uport = system.get_input_port(0) if system.num_input_ports() else None
            nu = uport.size() if uport is not None else 0

            def set_x(x):
                ctx.SetDiscreteState(x)
        # the model's state after one discrete update, per particle.  A discrete MultibodyPlant does not
        # expose its step as a unique periodic update here, so it is advanced by a Simulator over one period
        # (Simulator.Initialize performs the update scheduled at t = 0, AdvanceTo(period) stops before the next).
        sim = None
        if isinstance(system, MultibodyPlant):
            from pydrake.systems.analysis import Simulator
            sim = Simulator(system, ctx)

        def step_one(x, u):
            if uport is not None:
                uport.FixValue(ctx, np.zeros(nu) if u is None else u)
            if sim is not None:
                ctx.SetTime(0.0)
                set_x(x)
                sim.Initialize()
                sim.AdvanceTo(period)
                return system.GetPositionsAndVelocities(ctx).copy()
            set_x(x)
            return system.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector().CopyToVector()[:nx]

        def f(x, u, t):
            x = np.asarray(x, float)
            flat = x.reshape(-1, nx)
            out = np.empty_like(flat)
            for i in range(flat.shape[0]):
                out[i] = step_one(flat[i], u)
            return out.reshape(x.shape)

        if not callable(h):
            C = np.atleast_2d(np.asarray(h, float))
            if C.shape[1] != nx:
                raise DataError(f"h: measurement matrix has {C.shape[1]} columns, the model state has nx = {nx}")
            h = lambda x, u, t: x @ C.T  # noqa: E731
        if chol_psd(R1, "R1").shape[0] != nx:
            raise DataError(f"R1 is {np.shape(R1)}, the model state has nx = {nx}")
        return cls.gaussian(f, h, R1, R2, x0, P0, period, n_particles=n_particles, seed=seed, nu=nu)

    # -- accessors --------------------------------------------------------------------------------
    @property
    def filter(self) -> ParticleFilter:
        return self._pf

    def get_measurement_input_port(self):
        return self._measurement

    def get_control_input_port(self):
        return self._control

    def get_estimate_output_port(self):
        return self._estimate

    def get_covariance_output_port(self):
        return self._covariance

    def get_particles_output_port(self):
        return self._particles

    def get_log_likelihood_output_port(self):
        return self._loglik

    # -- callbacks --------------------------------------------------------------------------------
    def _read(self, context):
        v = context.get_discrete_state(self._state).get_value()
        N, nx = self._N, self._nx
        x = np.array(v[:N * nx]).reshape(N, nx)
        logw = np.array(v[N * nx:N * nx + N])
        return x, logw, int(round(v[-2])), float(v[-1])

    def _inputs(self, context):
        y = np.asarray(self._measurement.Eval(context), float)
        u = np.asarray(self._control.Eval(context), float) if self._control is not None else None
        return y, u

    def _update(self, context, discrete_state):
        x, logw, k, ll = self._read(context)
        y, u = self._inputs(context)
        if not np.isnan(y).any():
            x, logw, l_k = self._pf.correct(x, logw, y=y, u=u, t=k)
            ll += l_k
        x, logw = self._pf.predict(x, logw, u=u, t=k)
        discrete_state.get_mutable_vector(self._state).SetFromVector(
            np.concatenate([x.reshape(-1), logw, [k + 1.0, ll]]))

    def _weighted(self, context):
        """Particles weighted with the current measurement (before resampling): x_{k|k}, P_{k|k}."""
        x, logw, k, _ = self._read(context)
        y, u = self._inputs(context)
        a = logw
        if not np.isnan(y).any():
            g = np.asarray(self._pf.measurement_logpdf(x, y, u, k), float)
            a = np.where(np.isnan(logw + g), -np.inf, logw + g)
            if not np.isfinite(logsumexp(a)):
                a = logw                      # every weight zero: the prior predictive (as the filter does)
        w = np.exp(a - logsumexp(a))
        return weighted_moments(x, w)

    def _calc_estimate(self, context, output):
        output.SetFromVector(self._weighted(context)[0])

    def _calc_cov(self, context, output):
        output.SetFromVector(self._weighted(context)[1].reshape(-1))

    def _calc_particles(self, context, output):
        output.SetFromVector(self._read(context)[0].reshape(-1))

    def _calc_ll(self, context, output):
        output.SetFromVector([self._read(context)[3]])


def _contract_filter():
    A = np.array([[1.0, 0.01], [-0.05, 0.99]])
    B = np.array([0.0, 0.01])

    def f(x, u, t):
        return x @ A.T + B * u[0]

    def h(x, u, t):
        return x[..., :1]

    return f, h, 1e-4 * np.eye(2), np.array([[0.01]]), np.array([0.1, 0.0]), 0.05 * np.eye(2)


def contract_cases():
    from drake_est.systems.contract import ContractCase

    f, h, R1, R2, x0, P0 = _contract_filter()
    y, u = np.array([0.12]), np.array([0.5])

    def make():
        return ParticleFilterEstimator.gaussian(f, h, R1, R2, x0, P0, period=0.01, n_particles=64, seed=3, nu=1)

    def expected(system):
        # updates at t = 0, 0.01, ..., 0.04 (t_final 0.045 lies between updates): x_filt[5] of a 6-step log
        r = system.filter.forward_trajectory(np.tile(u, (6, 1)), np.tile(y, (6, 1)))
        return {"estimate": r.x_filt[5], "covariance": r.P_filt[5].reshape(-1)}

    return [ContractCase(make=make, inputs={"measurement": y, "control": u}, t_final=0.045, expected=expected,
                         label="ParticleFilterEstimator gaussian")]
