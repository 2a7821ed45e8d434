"""Controller LeafSystems: :class:`IlqrController` (iLQR/DDP plan + time-varying feedback, thesis Ch. 11) and
:class:`CartAccelerationActuator` (the acceleration input of the cart-pole (8.12) on a force-actuated plant).

Thin wrappers: every number comes from :mod:`drake_est.control.ilqr` / :func:`cart_force`.
"""
from __future__ import annotations

import numpy as np
from pydrake.systems.framework import EventStatus, LeafSystem, LeafSystem_
from pydrake.systems.scalar_conversion import TemplateSystem

from drake_est.control.ilqr import IlqrOptions, ilqr
from drake_est.errors import DataError


# =============================================================================================
# iLQR controller
# =============================================================================================
def plan_layout(T, n, m):
    """Offsets of the plan vector [t0, U (T*m), X ((T+1)*n), K (T*m*n)]."""
    a = 1
    b = a + T * m
    c = b + (T + 1) * n
    d = c + T * m * n
    return a, b, c, d


def pack_plan(t0, res):
    return np.concatenate([[t0], res.U.ravel(), res.X.ravel(), res.K.ravel()])


def unpack_plan(v, T, n, m):
    a, b, c, d = plan_layout(T, n, m)
    return v[0], v[a:b].reshape(T, m), v[b:c].reshape(T + 1, n), v[c:d].reshape(T, m, n)


def plan_control(plan, t, x, dt, lower, upper):
    """u = u_ff(i) + K(i) (x - x_nom(i)) clipped to [lower, upper], i = floor((t - t0)/dt) held at the last step."""
    t0, U, X, K = plan
    T = U.shape[0]
    i = int(np.floor((t - t0) / dt + 1e-9))
    i = min(max(i, 0), T - 1)
    u = U[i] + K[i] @ (np.asarray(x, float) - X[i])
    return np.minimum(np.maximum(u, lower), upper)


class IlqrController(LeafSystem):
    """iLQR/DDP controller: plans with :func:`drake_est.control.ilqr.ilqr` and outputs
    u = u_ff(t) + K(t) (x - x_nom(t)) clipped to the bounds.

    Input port ``state`` [the model's state units, e.g. rad and rad/s for a MultibodyPlant's q, v];
    output port ``control`` [the model's input units, e.g. N m]; output port ``nominal_state`` [same units as
    ``state``] (the planned x_nom(t), for tracking-error logging).

    The plan (start time, U, X, K) is discrete state in the Context.  It is computed by an initialization
    event from the measured state (``replan_period=None``: plan once) and, if ``replan_period`` [s] is given,
    recomputed receding-horizon from the measured state every period, warm-started from the previous plan
    shifted in time.  ``model``: a :class:`drake_est.control.ilqr.Model` (e.g. ``DrakeModel(plant, dt)``);
    ``cost``: e.g. :class:`QuadraticCost`; ``horizon`` steps of ``dt`` [s]."""

    def __init__(self, model, cost, horizon, dt, lower=None, upper=None, replan_period=None, U_init=None,
                 options: IlqrOptions | None = None, plan=None):
        super().__init__()
        self._fixed_plan = None
        if plan is not None:
            # a given plan (X (T+1,n), U (T,m), K (T,m,n)), e.g. a learned controller: no solve at initialization
            X, U, K = (np.asarray(a, float) for a in plan)
            self._fixed_plan = (X, U, K)
        if int(horizon) < 1:
            raise DataError(f"horizon must be >= 1, got {horizon}")
        if not (dt > 0):
            raise DataError(f"dt must be > 0, got {dt}")
        self.model, self.cost = model, cost
        self.T, self.dt = int(horizon), float(dt)
        n, m = model.n, model.m
        self.n, self.m = n, m
        self.lower = np.broadcast_to(-np.inf if lower is None else np.asarray(lower, float), (m,)).copy()
        self.upper = np.broadcast_to(np.inf if upper is None else np.asarray(upper, float), (m,)).copy()
        if np.any(self.lower > self.upper):
            j = int(np.argmax(self.lower > self.upper))
            raise DataError(f"infeasible bounds: lower > upper for input {j + 1}")
        self.U_init = np.zeros((self.T, m)) if U_init is None else np.asarray(U_init, float).reshape(self.T, m)
        self.options = options or IlqrOptions(max_iter=100)
        self._state = self.DeclareVectorInputPort("state", n)
        size = plan_layout(self.T, n, m)[-1]
        self._plan = self.DeclareDiscreteState(size)
        self._control = self.DeclareVectorOutputPort("control", m, self._calc_control)
        self._nominal = self.DeclareVectorOutputPort("nominal_state", n, self._calc_nominal)
        self.DeclareInitializationDiscreteUpdateEvent(self._initial_plan)
        self.replan_period = replan_period
        if replan_period is not None:
            if not (replan_period > 0):
                raise DataError(f"replan_period must be > 0, got {replan_period}")
            self.DeclarePeriodicDiscreteUpdateEvent(float(replan_period), float(replan_period), self._replan)

    # accessors
    def get_state_input_port(self):
        return self._state

    def get_control_output_port(self):
        return self._control

    def get_nominal_state_output_port(self):
        return self._nominal

    def solve(self, x0, U_warm):
        """The plan from state x0 (the plain algorithm the system wraps)."""
        return ilqr(self.model, self.cost, x0, U_warm, self.lower, self.upper, options=self.options)

    def _plan_from(self, context, discrete_state, U_warm):
        res = self.solve(self._state.Eval(context), U_warm)
        discrete_state.get_mutable_vector(self._plan).SetFromVector(pack_plan(context.get_time(), res))
        return EventStatus.Succeeded()

    def _initial_plan(self, context, discrete_state):
        if self._fixed_plan is not None:
            X, U, K = self._fixed_plan
            v = np.concatenate([[context.get_time()], U.ravel(), X.ravel(), K.ravel()])
            discrete_state.get_mutable_vector(self._plan).SetFromVector(v)
            return EventStatus.Succeeded()
        return self._plan_from(context, discrete_state, self.U_init)

    @classmethod
    def from_plan(cls, X, U, K, dt, lower=None, upper=None):
        """A controller that executes a given plan u = U(t) + K(t) (x - X(t)) (no model, no replanning)."""
        U = np.asarray(U, float)
        X = np.asarray(X, float)

        class _Shape:
            n, m = X.shape[1], U.shape[1]
        return cls(_Shape(), None, U.shape[0], dt, lower, upper, plan=(X, U, K))

    def _replan(self, context, discrete_state):
        t0, U, _, _ = unpack_plan(context.get_discrete_state(self._plan).value(), self.T, self.n, self.m)
        shift = int(round((context.get_time() - t0) / self.dt))
        Uw = np.concatenate([U[min(shift, self.T):], np.repeat(U[-1:], min(shift, self.T), axis=0)])
        return self._plan_from(context, discrete_state, Uw)

    def _plan_now(self, context):
        return unpack_plan(context.get_discrete_state(self._plan).value(), self.T, self.n, self.m)

    def _calc_control(self, context, output):
        u = plan_control(self._plan_now(context), context.get_time(), self._state.Eval(context), self.dt,
                         self.lower, self.upper)
        output.SetFromVector(u)

    def _calc_nominal(self, context, output):
        t0, _, X, _ = self._plan_now(context)
        i = min(max(int(np.floor((context.get_time() - t0) / self.dt + 1e-9)), 0), self.T)
        output.SetFromVector(X[i])


# =============================================================================================
# cart acceleration actuator
# =============================================================================================
def cart_force(x_plant, u, g=9.81, l=1.0, d=0.1, m_cart=1.0, m_pole=1.0):
    """Cart force [N] that gives cart acceleration u on the cart-pole of models/cartpole.urdf (point mass
    m_pole at distance l, bob at (p - l sin theta, -l cos theta)); x_plant = (p, theta, v, omega).

    Analytic: F = (M + m) u - m l (theta'' cos theta - omega^2 sin theta), theta'' from (8.11)."""
    _, th, _, w = x_plant
    thdd = -(g / l) * np.sin(th) + (u / l) * np.cos(th) - d * w
    return (m_cart + m_pole) * u - m_pole * l * (thdd * np.cos(th) - w ** 2 * np.sin(th))


@TemplateSystem.define("CartAccelerationActuator_")
def CartAccelerationActuator_(T):
    class Impl(LeafSystem_[T]):
        """Force on the cart that realizes the commanded cart acceleration (input of (8.12)) on a
        force-actuated cart-pole ``plant``, from the plant's mass matrix, bias and gravity terms (first row of
        M [u, theta''] + C v - tau_g with theta'' from the unactuated row).

        Input ports ``state`` [m, rad, m/s, rad/s] (plant order p, theta, v, omega) and ``cart_acceleration``
        [m/s^2]; output port ``cart_force`` [N].  Scalar types float and AutoDiffXd (``ToAutoDiffXd()``
        converts the internal copy of the plant too), so :class:`drake_est.control.drake_model.DrakeModel`
        can differentiate a Diagram holding it."""

        def _construct(self, plant, converter=None):
            LeafSystem_[T].__init__(self, converter)
            self._plant = plant
            self._pctx = plant.CreateDefaultContext()
            self._damping = float(plant.get_joint(plant.GetJointByName("hinge").index()).default_damping())
            self._state = self.DeclareVectorInputPort("state", 4)
            self._acc = self.DeclareVectorInputPort("cart_acceleration", 1)
            self._force = self.DeclareVectorOutputPort("cart_force", 1, self._calc)

        def _construct_copy(self, other, converter=None):
            plant = other._plant.ToScalarType[T]()
            Impl._construct(self, plant, converter=converter)

        def get_state_input_port(self):
            return self._state

        def get_cart_acceleration_input_port(self):
            return self._acc

        def get_cart_force_output_port(self):
            return self._force

        def _calc(self, context, output):
            x = self._state.Eval(context)
            u = self._acc.Eval(context)[0]
            p = self._plant
            ctx = self._pctx
            p.SetPositionsAndVelocities(ctx, x)
            M = p.CalcMassMatrix(ctx)
            # Drake's Build() may probe the port with NaN inputs: NaN in, NaN out, without a warning
            with np.errstate(invalid="ignore"):
                rhs = p.CalcGravityGeneralizedForces(ctx) - p.CalcBiasTerm(ctx)
                rhs[1] = rhs[1] - self._damping * x[3]
                # unactuated row: M10 u + M11 thdd = rhs1  ->  thdd; actuated row gives the force
                thdd = (rhs[1] - M[1, 0] * u) / M[1, 1]
                output.SetFromVector([M[0, 0] * u + M[0, 1] * thdd - rhs[0]])

    return Impl


CartAccelerationActuator = CartAccelerationActuator_[None]


# =============================================================================================
def _small_ilqr_controller():
    from drake_est.control.cartpole import CartPoleModel
    from drake_est.control.ilqr import QuadraticCost
    model = CartPoleModel(h=0.01)
    cost = QuadraticCost(np.diag([1.0, 0.1, 0.1, 0.1]), [[0.01]])
    return IlqrController(model, cost, horizon=30, dt=0.01, lower=-10, upper=10,
                          options=IlqrOptions(max_iter=30))


def contract_cases():
    from drake_est.systems.contract import ContractCase
    x = np.array([np.pi - 0.1, 0.0, 0.0, 0.0])

    def exp_ilqr(s):
        res = s.solve(x, np.zeros((s.T, 1)))
        return {"control": plan_control((0.0, res.U, res.X, res.K), 0.05, x, s.dt, s.lower, s.upper),
                "nominal_state": res.X[5]}

    def make_act():
        from pydrake.multibody.parsing import Parser
        from pydrake.multibody.plant import MultibodyPlant

        from drake_est.robots import models_dir
        plant = MultibodyPlant(0.0)
        Parser(plant).AddModels(str(models_dir() / "cartpole.urdf"))
        plant.Finalize()
        return CartAccelerationActuator(plant)

    xs = np.array([0.2, 0.7, -0.3, 1.1])
    return [ContractCase(make=_small_ilqr_controller, inputs={"state": x}, t_final=0.05, expected=exp_ilqr,
                         rtol=1e-8, atol=1e-8, label="cart-pole plan once"),
            ContractCase(make=make_act, inputs={"state": xs, "cart_acceleration": np.array([2.5])},
                         expected=lambda s: {"cart_force": np.array([cart_force(xs, 2.5)])}, label="cart-pole")]
