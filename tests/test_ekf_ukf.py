"""EKF and UKF (Sec. 4.3): equal to the Kalman filter on linear-Gaussian models, Drake-system constructors,
a nonlinear sanity check, and bad input."""
import numpy as np
import pytest

from drake_est.errors import DataError
from drake_est.estimation import ExtendedKalmanFilter, KalmanFilter, UnscentedKalmanFilter


def _linear(seed=0, T=40, nx=3, ny=2):
    rng = np.random.default_rng(seed)
    A = np.eye(nx) + 0.1 * rng.standard_normal((nx, nx))
    A *= 0.95 / max(abs(np.linalg.eigvals(A)))
    B = rng.standard_normal((nx, 1))
    C = rng.standard_normal((ny, nx))
    R1 = 0.02 * np.eye(nx) + 0.005
    R2 = 0.1 * np.eye(ny)
    x0, P0 = rng.standard_normal(nx), 0.5 * np.eye(nx)
    u = rng.standard_normal((T, 1))
    x = x0.copy()
    y = np.empty((T, ny))
    for t in range(T):
        y[t] = C @ x + rng.multivariate_normal(np.zeros(ny), R2)
        x = A @ x + B @ u[t] + rng.multivariate_normal(np.zeros(nx), R1)
    y[5] = np.nan                                   # one missing measurement: predict only
    return A, B, C, R1, R2, x0, P0, u, y


def _fh(A, B, C):
    def f(x, u, t):
        return x @ A.T + u @ B.T

    def h(x, u, t):
        return x @ C.T
    return f, h


def _assert_same(sm, ref, tol):
    for k in ("x_filt", "P_filt", "x_pred", "P_pred"):
        np.testing.assert_allclose(getattr(sm.filtered, k), getattr(ref.filtered, k), atol=tol, rtol=0, err_msg=k)
    np.testing.assert_allclose(sm.x_smooth, ref.x_smooth, atol=tol, rtol=0)
    np.testing.assert_allclose(sm.P_smooth, ref.P_smooth, atol=tol, rtol=0)
    assert sm.loglik == pytest.approx(ref.loglik, abs=tol)
    assert sm.filtered.n_missing == ref.filtered.n_missing == 1


def test_ekf_and_ukf_equal_kalman_on_linear_model():
    A, B, C, R1, R2, x0, P0, u, y = _linear()
    ref = KalmanFilter(A, C, R1, R2, x0, P0, B=B).smooth(u, y)
    f, h = _fh(A, B, C)
    ekf = ExtendedKalmanFilter(f, h, R1, R2, x0, P0, F=lambda x, u, t: A, H=lambda x, u, t: C, nu=1)
    _assert_same(ekf.smooth(u, y), ref, 1e-10)
    assert ekf.loglik(u, y) == pytest.approx(ref.loglik, abs=1e-10)
    ukf = UnscentedKalmanFilter(f, h, R1, R2, x0, P0, nu=1)
    _assert_same(ukf.smooth(u, y), ref, 1e-10)
    # other sigma-point parameters give the same answer on a linear model
    ukf2 = UnscentedKalmanFilter(f, h, R1, R2, x0, P0, alpha=0.5, beta=2.0, kappa=1.0, nu=1)
    _assert_same(ukf2.smooth(u, y), ref, 1e-9)
    # finite-difference Jacobians: rounding of the differences only
    ekf_fd = ExtendedKalmanFilter(f, h, R1, R2, x0, P0, nu=1)
    _assert_same(ekf_fd.smooth(u, y), ref, 1e-7)


def test_from_drake_linear_system_uses_autodiff_and_equals_kalman():
    from pydrake.systems.primitives import LinearSystem

    A, B, C, R1, R2, x0, P0, u, y = _linear(seed=1, T=30)
    sys = LinearSystem(A, B, np.eye(3), np.zeros((3, 1)), 0.1)
    ref = KalmanFilter(A, C, R1, R2, x0, P0, B=B).smooth(u, y)
    ekf = ExtendedKalmanFilter.from_system(sys, R1, R2, x0, P0, measurement=C)
    assert ekf.period == pytest.approx(0.1) and ekf.F is not None        # AutoDiffXd Jacobian
    np.testing.assert_allclose(ekf.jacobian_f(x0, u[0], 0), A, atol=1e-14)
    _assert_same(ekf.smooth(u, y), ref, 1e-10)
    ukf = UnscentedKalmanFilter.from_system(sys, R1, R2, x0, P0, measurement=C)
    _assert_same(ukf.smooth(u, y), ref, 1e-10)


def test_from_discrete_multibody_plant_runs():
    from drake_est.systems.builders import MakeIrb140ControllerPlant

    plant = MakeIrb140ControllerPlant(time_step=1e-3)     # IRB140: x = [q; v] (12), 6 actuators, gravity
    nx, nq = plant.num_multibody_states(), plant.num_positions()
    C = np.eye(nx)[:nq]
    x0 = np.r_[0.0, 0.3, 0.2, 0.0, 0.1, 0.0, np.zeros(6)]
    R1, R2, P0 = 1e-8 * np.eye(nx), 1e-4 * np.eye(nq), 1e-4 * np.eye(nx)
    ekf = ExtendedKalmanFilter.from_system(plant, R1, R2, x0, P0, measurement=C)
    ukf = UnscentedKalmanFilter.from_system(plant, R1, R2, x0, P0, measurement=C)
    # the Jacobian comes from AutoDiffXd through the plant's discrete step, and agrees with differences
    assert ekf.F is not None
    from drake_est.estimation.ekf import fd_jacobian
    xv = x0 + np.r_[np.zeros(6), 0.1 * np.ones(6)]
    np.testing.assert_allclose(ekf.jacobian_f(xv, np.zeros(6), 0), fd_jacobian(ekf.f, xv, np.zeros(6), 0, nx),
                               atol=1e-8)
    T = 4
    u = np.zeros((T, 6))
    xs = [x0]
    for t in range(T - 1):
        xs.append(ekf.f(xs[-1], u[t], t))
    xs = np.array(xs)
    assert np.abs(xs[-1, nq:]).max() > 1e-4                # gravity moves the arm: f is the plant's step
    for filt in (ekf, ukf):
        fr = filt.forward_trajectory(u, xs @ C.T)
        assert np.abs(fr.x_filt - xs).max() < 1e-3


def test_nonlinear_pendulum_tracks_truth():
    rng = np.random.default_rng(2)
    dt, T = 0.05, 200

    def f(x, u, t):
        th, w = x[..., 0], x[..., 1]
        return np.stack([th + dt * w, w - dt * 9.81 * np.sin(th)], axis=-1)

    def h(x, u, t):
        return np.sin(x[..., :1])

    R1, R2 = np.diag([1e-6, 1e-4]), np.array([[0.01]])
    x = np.array([1.0, 0.0])
    xs, ys = [], []
    for t in range(T):
        xs.append(x)
        ys.append(h(x, None, t) + rng.normal(0, 0.1, 1))
        x = f(x, None, t) + rng.multivariate_normal(np.zeros(2), R1)
    xs, ys = np.array(xs), np.array(ys)
    for filt in (ExtendedKalmanFilter(f, h, R1, R2, [0.8, 0.0], 0.1 * np.eye(2)),
                 UnscentedKalmanFilter(f, h, R1, R2, [0.8, 0.0], 0.1 * np.eye(2))):
        sm = filt.smooth(None, ys)
        rmse_f = np.sqrt(np.mean((sm.filtered.x_filt[50:, 0] - xs[50:, 0]) ** 2))
        rmse_s = np.sqrt(np.mean((sm.x_smooth[50:, 0] - xs[50:, 0]) ** 2))
        assert rmse_f < 0.05, type(filt).__name__
        assert rmse_s < rmse_f


def test_bad_input():
    A, B, C, R1, R2, x0, P0, u, y = _linear()
    f, h = _fh(A, B, C)
    with pytest.raises(DataError, match="^R1 is not positive semidefinite"):
        ExtendedKalmanFilter(f, h, -R1, R2, x0, P0)
    with pytest.raises(DataError, match="^R2 is not positive definite"):
        UnscentedKalmanFilter(f, h, R1, np.zeros((2, 2)), x0, P0)
    with pytest.raises(DataError, match="^P0 is not positive definite"):
        UnscentedKalmanFilter(f, h, R1, R2, x0, np.zeros((3, 3)))
    with pytest.raises(DataError, match="^R2 has shape"):
        ExtendedKalmanFilter(f, h, R1, np.eye(3), x0, P0)
    with pytest.raises(DataError, match="^f returned shape"):
        ExtendedKalmanFilter(lambda x, u, t: x[..., :2], h, R1, R2, x0, P0).forward_trajectory(u, y)
    with pytest.raises(DataError, match="^f returned shape"):
        UnscentedKalmanFilter(lambda x, u, t: x[..., :2], h, R1, R2, x0, P0).forward_trajectory(u, y)
    with pytest.raises(DataError, match="^y has 3 columns"):
        UnscentedKalmanFilter(f, h, R1, R2, x0, P0).forward_trajectory(u, np.ones((4, 3)))
    with pytest.raises(DataError, match="^x0 contains NaN"):
        UnscentedKalmanFilter(f, h, R1, R2, [np.nan, 0, 0], P0)
    # a covariance that loses definiteness mid-run is named with its step
    ukf = UnscentedKalmanFilter(f, h, R1, R2, x0, P0)
    with pytest.raises(DataError, match="^P_pred is not positive definite at step 0"):
        ukf.correct(x0, -np.eye(3), y[0], u[0], 0)


def test_from_python_leafsystem_without_autodiff_uses_finite_differences():
    from pydrake.systems.framework import BasicVector, LeafSystem

    A, B, C, R1, R2, x0, P0, u, y = _linear(seed=5, T=20)

    class Model(LeafSystem):                               # no scalar conversion: Jacobian by differences
        def __init__(self):
            super().__init__()
            self._x = self.DeclareDiscreteState(BasicVector(np.zeros(3)))
            self._u = self.DeclareVectorInputPort("u", 1)
            self.DeclarePeriodicDiscreteUpdateEvent(0.1, 0.0, self._step)

        def _step(self, context, ds):
            x = context.get_discrete_state(self._x).get_value()
            ds.get_mutable_vector(self._x).SetFromVector(A @ x + B @ self._u.Eval(context))

    ekf = ExtendedKalmanFilter.from_system(Model(), R1, R2, x0, P0, measurement=C)
    assert ekf.F is None and ekf.period == pytest.approx(0.1)
    ref = KalmanFilter(A, C, R1, R2, x0, P0, B=B).smooth(u, y)
    _assert_same(ekf.smooth(u, y), ref, 1e-7)
