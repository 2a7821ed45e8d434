"""iLQR/DDP (drake_est.control): box-QP, numba vs numpy iterates, bounds, DDP, Drake derivatives, KL trust
region, bad input, divergence, IlqrController in a Diagram."""
import numpy as np
import pytest

from drake_est.control import (FunctionModel, LinearGaussianController, LtvModel, QuadraticCost, boxqp, ilqr,
                               ilqr_kl, trajectory_kl)
from drake_est.control import kernels
from drake_est.control.cartpole import J_STAR, CartPoleModel, benchmark_problem, cartpole_rhs
from drake_est.errors import DataError


# ------------------------------------------------------------------------------------------------ box-QP
def _brute_force_qp(H, g, lo, hi):
    """Exact box-QP solution by enumerating the active sets (small m)."""
    import itertools
    m = len(g)
    best, xbest = np.inf, None
    for pattern in itertools.product((0, 1, 2), repeat=m):      # 0 free, 1 lower, 2 upper
        x = np.zeros(m)
        fixed = np.array([p != 0 for p in pattern])
        for i, p in enumerate(pattern):
            x[i] = lo[i] if p == 1 else hi[i] if p == 2 else 0.0
        f = ~fixed
        if f.any():
            x[f] = np.linalg.solve(H[np.ix_(f, f)], -(g[f] + H[np.ix_(f, fixed)] @ x[fixed]))
        if np.all(x >= lo - 1e-12) and np.all(x <= hi + 1e-12):
            v = 0.5 * x @ H @ x + g @ x
            if v < best:
                best, xbest = v, x
    return xbest


@pytest.mark.parametrize("seed", range(6))
def test_boxqp_matches_enumeration_and_numba_twin(seed):
    rng = np.random.default_rng(seed)
    m = 3
    A = rng.normal(size=(m, m))
    H = A @ A.T + 0.1 * np.eye(m)
    g = rng.normal(size=m) * 3
    lo, hi = -np.ones(m) * 0.5, np.ones(m) * 0.7
    r = boxqp(H, g, lo, hi)
    np.testing.assert_allclose(r.x, _brute_force_qp(H, g, lo, hi), atol=1e-6)
    assert np.all(r.x >= lo) and np.all(r.x <= hi)
    x, free, L = np.empty(m), np.empty(m, bool), np.empty((m, m))
    status, _ = kernels.boxqp_nb(H, g, lo, hi, np.zeros(m), x, free, L, 100)
    np.testing.assert_allclose(x, r.x, atol=1e-12)
    assert status == r.status and np.array_equal(free, r.free)


def test_boxqp_reports_indefinite_hessian():
    r = boxqp(np.diag([1.0, -1.0]), np.array([1.0, 1.0]), -np.ones(2) * np.inf, np.ones(2) * np.inf)
    assert r.status == -1


# ------------------------------------------------------------------------------------------------ cart-pole
def test_cartpole_benchmark_reaches_j_star_within_bounds():
    model, cost, x0, U0, lo, hi = benchmark_problem()
    r = ilqr(model, cost, x0, U0, lo, hi)
    assert r.converged, r.message
    assert abs(r.J - J_STAR) <= 1e-6 * J_STAR
    assert np.abs(r.U).max() <= 10.0
    assert np.any(np.isclose(np.abs(r.U), 10.0))            # the bounds are active (bang-bang start)
    assert np.all(np.diff(r.costs[:-1]) <= 1e-9)            # monotone decrease


def test_numba_and_numpy_paths_give_the_same_iterates():
    model_nb, cost, x0, _, lo, hi = benchmark_problem(numba=True)
    model_np = CartPoleModel(numba=False)
    T = 60
    U0 = np.zeros((T, 1))
    for second in (False, True):
        a = ilqr(model_nb, cost, x0, U0, lo, hi, numba=True, max_iter=15, second_order=second)
        b = ilqr(model_np, cost, x0, U0, lo, hi, numba=False, max_iter=15, second_order=second)
        assert a.iterations == b.iterations
        np.testing.assert_allclose(a.costs, b.costs, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(a.U, b.U, atol=1e-10)
        np.testing.assert_allclose(a.K, b.K, atol=1e-8)


def test_no_numba_env_forces_numpy(monkeypatch):
    monkeypatch.setenv("DRAKE_EST_NO_NUMBA", "1")
    assert not kernels.use_numba()
    assert not kernels.use_numba(True)


def test_full_ddp_reaches_the_same_optimum():
    model, cost, x0, U0, lo, hi = benchmark_problem()
    a = ilqr(model, cost, x0, U0[:150], lo, hi)
    b = ilqr(model, cost, x0, U0[:150], lo, hi, second_order=True)
    assert a.converged and b.converged
    assert abs(a.J - b.J) <= 1e-6 * a.J


def test_function_model_matches_compiled_model():
    model, cost, x0, _, lo, hi = benchmark_problem()
    h = 0.01

    def f(t, x, u):
        return x + h * cartpole_rhs(x, u)

    def jac(t, x, u):
        A = np.eye(4)
        A[0, 1] = h
        A[1, 0] = h * (-9.81 * np.cos(x[0]) - u[0] * np.sin(x[0]))
        A[1, 1] = 1 - 0.1 * h
        A[2, 3] = h
        return A, np.array([[0.0], [h * np.cos(x[0])], [0.0], [h]])

    fm = FunctionModel(f, jac, 4, 1)
    U0 = np.zeros((80, 1))
    a = ilqr(fm, cost, x0, U0, lo, hi, max_iter=20)
    b = ilqr(model, cost, x0, U0, lo, hi, max_iter=20)
    np.testing.assert_allclose(a.costs, b.costs, rtol=1e-9)


# ------------------------------------------------------------------------------------------------ Drake
def test_drake_autodiff_jacobians_match_finite_differences():
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
    from pydrake.systems.framework import DiagramBuilder

    from drake_est.control.drake_model import DrakeModel
    from drake_est.robots import models_dir
    b = DiagramBuilder()
    plant, _ = AddMultibodyPlantSceneGraph(b, 0.0)
    Parser(plant).AddModels(str(models_dir() / "cartpole.urdf"))
    plant.Finalize()
    dm = DrakeModel(plant, 0.01)
    rng = np.random.default_rng(1)
    X, U = rng.normal(size=(3, 4)), rng.normal(size=(2, 1))
    fx, fu, *_ = dm.linearize(X, U)
    eps = 1e-6
    A = np.array([(dm.step(0, X[0] + eps * e, U[0]) - dm.step(0, X[0] - eps * e, U[0])) / (2 * eps)
                  for e in np.eye(4)]).T
    B = (dm.step(0, X[0], U[0] + eps) - dm.step(0, X[0], U[0] - eps)) / (2 * eps)
    np.testing.assert_allclose(fx[0], A, atol=1e-7)
    np.testing.assert_allclose(fu[0, :, 0], B, atol=1e-7)


def test_drake_cartpole_equals_equations_8_11_8_12():
    from drake_est.systems.cartpole_plant import CartPoleTrueSystem
    s = CartPoleTrueSystem()
    rng = np.random.default_rng(2)
    for _ in range(20):
        x, u = rng.normal(size=4) * 2, rng.normal() * 5
        np.testing.assert_allclose(s.xdot(x, u), cartpole_rhs(x, u), atol=1e-10)


# ------------------------------------------------------------------------------------------------ KL
def _ltv_problem(T=50):
    model = CartPoleModel()
    _, cost, x0, _, lo, hi = benchmark_problem()
    r = ilqr(model, cost, x0, np.zeros((T, 1)), lo, hi, max_iter=3)
    fx, fu, *_ = model.linearize(r.X, r.U)
    c = r.X[1:] - np.einsum("tij,tj->ti", fx, r.X[:-1]) - np.einsum("tij,tj->ti", fu, r.U)
    old = LinearGaussianController(r.X, r.U, np.zeros((T, 1, 4)), np.full((T, 1, 1), 1.0), None, None)
    return LtvModel(fx, fu, c), cost, x0, old


def test_kl_trust_region_bounds_the_step():
    ltv, cost, x0, old = _ltv_problem()
    small = ilqr_kl(ltv, cost, x0, old, kl_step=0.5)
    big = ilqr_kl(ltv, cost, x0, old, kl_step=50.0)
    assert small.kl <= 0.5 * 1.1 + 1e-9
    assert big.kl <= 50 * 1.1 + 1e-9
    assert big.J <= small.J + 1e-9              # a larger trust region reaches a lower model cost
    kl_check, per_step = trajectory_kl(ltv, small.controller, old, x0)
    assert abs(kl_check - small.kl) < 1e-9 and np.all(per_step >= -1e-12)
    # identical controllers have zero divergence
    assert abs(trajectory_kl(ltv, old, old, x0)[0]) < 1e-10


def test_controller_covariance_is_quu_inverse():
    model, cost, x0, U0, lo, hi = benchmark_problem()
    r = ilqr(model, cost, x0, U0[:40], None, None)
    ctrl = r.controller()
    for t in (0, 20, 39):
        np.testing.assert_allclose(ctrl.cov[t] @ r.Quu[t], np.eye(1), atol=1e-10)


# ------------------------------------------------------------------------------------------------ bad input
def test_bad_input_raises_one_line_errors():
    model, cost, x0, U0, lo, hi = benchmark_problem()
    with pytest.raises(DataError, match="lower > upper"):
        ilqr(model, cost, x0, U0, 1.0, -1.0)
    with pytest.raises(DataError, match="horizon"):
        ilqr(model, cost, x0, np.zeros((0, 1)), lo, hi)
    with pytest.raises(DataError, match="x0 has 3"):
        ilqr(model, cost, x0[:3], U0, lo, hi)
    with pytest.raises(DataError, match="columns"):
        ilqr(model, cost, x0, np.zeros((10, 2)), lo, hi)
    with pytest.raises(DataError, match="cost matrix Q"):
        QuadraticCost(np.eye(3), [[1.0]], Qf=np.eye(4))
    nan_model = FunctionModel(lambda t, x, u: x * np.nan, lambda t, x, u: (np.eye(2), np.ones((2, 1))), 2, 1)
    with pytest.raises(DataError, match="dynamics returned NaN"):
        ilqr(nan_model, QuadraticCost(np.eye(2), [[1.0]]), np.ones(2), np.zeros((5, 1)))
    good = FunctionModel(lambda t, x, u: x + u[0], lambda t, x, u: (np.eye(2), np.ones((2, 1))), 2, 1)

    class NanCost(QuadraticCost):
        def value(self, X, U):
            return np.nan
    with pytest.raises(DataError, match="cost returned NaN"):
        ilqr(good, NanCost(np.eye(2), [[1.0]]), np.ones(2), np.zeros((5, 1)))
    for e in (DataError,):
        try:
            ilqr(model, cost, x0, U0, 1.0, -1.0)
        except e as err:
            assert "\n" not in str(err)


def test_divergence_is_detected_and_last_good_trajectory_returned():
    # dynamics that blow up (NaN) once |u| exceeds 0.5: every full step is rejected
    def f(t, x, u):
        return np.array([x[0] + u[0]]) if abs(u[0]) < 0.5 else np.array([np.nan])

    model = FunctionModel(f, lambda t, x, u: (np.eye(1), np.eye(1)), 1, 1)
    cost = QuadraticCost([[1.0]], [[1e-6]])
    r = ilqr(model, cost, np.array([100.0]), np.zeros((3, 1)), alphas=(1.0,), mu_max=1e3)
    assert r.diverged and "diverged" in r.message
    assert np.all(np.isfinite(r.X)) and r.J == pytest.approx(cost.value(r.X, r.U))


# ------------------------------------------------------------------------------------------------ LeafSystem
def test_ilqr_controller_in_a_diagram_with_the_drake_cartpole():
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import ZeroOrderHold

    from drake_est.systems.cartpole_plant import add_cartpole
    from drake_est.systems.controllers import IlqrController
    model, cost, x0, _, lo, hi = benchmark_problem()
    builder = DiagramBuilder()
    plant, act = add_cartpole(builder)
    from drake_est.systems.cartpole_plant import PLANT_FROM_THESIS, THESIS_FROM_PLANT
    from pydrake.systems.primitives import MatrixGain
    P = np.eye(4)[THESIS_FROM_PLANT]            # thesis-order state = P @ plant state
    to_thesis = builder.AddSystem(MatrixGain(P))
    ctrl = builder.AddSystem(IlqrController(model, cost, horizon=150, dt=0.01, lower=lo, upper=hi))
    zoh = builder.AddSystem(ZeroOrderHold(0.01, 1))
    builder.Connect(plant.get_state_output_port(), to_thesis.get_input_port())
    builder.Connect(to_thesis.get_output_port(), ctrl.get_state_input_port())
    builder.Connect(ctrl.get_control_output_port(), zoh.get_input_port())
    builder.Connect(zoh.get_output_port(), act.get_cart_acceleration_input_port())
    diagram = builder.Build()
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    plant.SetPositionsAndVelocities(plant.GetMyMutableContextFromRoot(ctx), x0[PLANT_FROM_THESIS])
    sim.AdvanceTo(1.0)
    x_end = P @ plant.GetPositionsAndVelocities(plant.GetMyContextFromRoot(ctx))
    ref = ilqr(model, cost, x0, np.zeros((150, 1)), lo, hi, max_iter=100)
    # the continuous plant under the feedback plan follows the explicit-Euler model's plan (mismatch O(h))
    assert np.abs(x_end - ref.X[100])[[0, 2, 3]].max() < 0.05
    assert abs(x_end[1] - ref.X[100, 1]) < 0.2
    u = ctrl.get_control_output_port().Eval(ctrl.GetMyContextFromRoot(ctx))
    assert abs(u[0]) <= 10.0


def test_drake_model_differentiates_the_cartpole_diagram_with_the_actuator():
    """CartAccelerationActuator converts to AutoDiffXd, so DrakeModel's Jacobians of the Diagram (plant order)
    match the analytic ones of the cart-pole (8.11)-(8.12) (thesis order) after the permutation."""
    from pydrake.systems.framework import DiagramBuilder

    from drake_est.control.cartpole import CartPoleModel
    from drake_est.control.drake_model import DrakeModel
    from drake_est.systems.cartpole_plant import PLANT_FROM_THESIS, add_cartpole
    builder = DiagramBuilder()
    _, act = add_cartpole(builder)
    builder.ExportInput(act.get_cart_acceleration_input_port(), "cart_acceleration")
    dm = DrakeModel(builder.Build(), 0.01, input_port=0)
    rng = np.random.default_rng(3)
    X = rng.normal(size=(4, 4)) + np.array([np.pi - 0.5, 0, 0, 0])     # thesis order
    U = rng.normal(size=(3, 1)) * 3
    fx_d, fu_d, *_ = dm.linearize(X[:, PLANT_FROM_THESIS], U)
    fx_a, fu_a, *_ = CartPoleModel(h=0.01).linearize(X, U)
    P = np.eye(4)[PLANT_FROM_THESIS]             # plant state = P @ thesis state
    np.testing.assert_allclose(fx_d, P @ fx_a @ P.T, atol=1e-10)
    np.testing.assert_allclose(fu_d, P @ fu_a, atol=1e-10)
    assert np.abs(fu_d).max() > 1e-3            # the input really enters through the actuator
