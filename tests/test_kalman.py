"""Kalman filter / RTS smoother (Sec. 4.3) against dense Gaussian conditioning, and as a Drake system."""
import numpy as np
import pytest
from scipy.stats import multivariate_normal

from drake_est.errors import DataError
from drake_est.estimation.kalman import KalmanFilter


def _model(seed=0, T=25):
    rng = np.random.default_rng(seed)
    A = np.array([[0.9, 0.2], [-0.1, 0.8]])
    B = np.array([[0.0], [1.0]])
    C = np.array([[1.0, 0.5]])
    R1 = np.diag([0.05, 0.02])
    R2 = np.array([[0.3]])
    x0 = np.array([0.5, -0.2])
    P0 = np.diag([1.0, 2.0])
    u = rng.standard_normal((T, 1))
    x = np.zeros((T, 2))
    x[0] = x0 + rng.multivariate_normal(np.zeros(2), P0)
    for t in range(T - 1):
        x[t + 1] = A @ x[t] + B @ u[t] + rng.multivariate_normal(np.zeros(2), R1)
    y = x @ C.T + rng.normal(0, np.sqrt(R2[0, 0]), (T, 1))
    return A, B, C, R1, R2, x0, P0, u, y


def _dense_posterior(A, B, C, R1, R2, x0, P0, u, y):
    """Joint Gaussian of (x_0..x_{T-1}, y) by stacking; returns smoothed means/covs and log p(y)."""
    T, nx = y.shape[0], A.shape[0]
    # x = M w + m,  w = (x0 deviation, v_0..v_{T-2})
    M = np.zeros((T * nx, T * nx))
    m = np.zeros(T * nx)
    m[:nx] = x0
    M[:nx, :nx] = np.eye(nx)
    for t in range(1, T):
        M[t * nx:(t + 1) * nx] = A @ M[(t - 1) * nx:t * nx]
        M[t * nx:(t + 1) * nx, t * nx:(t + 1) * nx] += np.eye(nx)
        m[t * nx:(t + 1) * nx] = A @ m[(t - 1) * nx:t * nx] + B @ u[t - 1]
    W = np.zeros((T * nx, T * nx))
    W[:nx, :nx] = P0
    for t in range(1, T):
        W[t * nx:(t + 1) * nx, t * nx:(t + 1) * nx] = R1
    Sx = M @ W @ M.T
    Cb = np.kron(np.eye(T), C)
    Sy = Cb @ Sx @ Cb.T + np.kron(np.eye(T), R2)
    my = Cb @ m
    K = np.linalg.solve(Sy, Cb @ Sx).T
    mean = m + K @ (y.reshape(-1) - my)
    cov = Sx - K @ Cb @ Sx
    ll = multivariate_normal(my, Sy).logpdf(y.reshape(-1))
    return mean.reshape(T, nx), cov, ll


def test_smoother_and_loglik_match_dense_conditioning():
    A, B, C, R1, R2, x0, P0, u, y = _model()
    kf = KalmanFilter(A, C, R1, R2, x0, P0, B=B)
    sm = kf.smooth(u, y)
    mean, cov, ll = _dense_posterior(A, B, C, R1, R2, x0, P0, u, y)
    assert np.allclose(sm.x_smooth, mean, atol=1e-10)
    for t in range(y.shape[0]):
        assert np.allclose(sm.P_smooth[t], cov[2 * t:2 * t + 2, 2 * t:2 * t + 2], atol=1e-10)
    assert sm.loglik == pytest.approx(ll, abs=1e-8)
    assert kf.loglik(u, y) == pytest.approx(ll, abs=1e-8)
    # the last filtered estimate equals the last smoothed one
    assert np.allclose(sm.filtered.x_filt[-1], sm.x_smooth[-1])


def test_time_varying_and_multicolumn_state():
    A, B, C, R1, R2, x0, P0, u, y = _model(seed=1)
    T = y.shape[0]
    At = np.array([A * (1 + 0.01 * t) for t in range(T)])
    kf = KalmanFilter(At, C, R1, R2, x0, P0, B=B)
    single = kf.smooth(u, y).x_smooth
    # two columns sharing the covariance: each column equals its own run
    kf2 = KalmanFilter(At, C, R1, R2, np.column_stack([x0, 2 * x0]), P0, B=B)
    y2 = np.stack([y, 2 * y], axis=2)
    u2 = np.stack([u, 2 * u], axis=2)
    two = kf2.smooth(u2, y2).x_smooth
    assert np.allclose(two[:, :, 0], single, atol=1e-12)
    assert np.allclose(two[:, :, 1], 2 * single, atol=1e-12)


def test_joseph_form_keeps_covariance_psd_with_tiny_noise():
    A, B, C, R1, R2, x0, P0, u, y = _model(seed=2, T=200)
    kf = KalmanFilter(A, np.eye(2), R1 * 1e-9, 1e-14 * np.eye(2), x0, 1e6 * np.eye(2), B=B)
    fr = kf.forward_trajectory(u, np.column_stack([y, y]))
    for P in fr.P_filt:
        assert np.allclose(P, P.T)
        assert np.linalg.eigvalsh(P).min() > -1e-12


def test_bad_input():
    A, B, C, R1, R2, x0, P0, u, y = _model()
    kf = KalmanFilter(A, C, R1, R2, x0, P0, B=B)
    y_bad = y.copy()
    y_bad[3, 0] = np.nan
    with pytest.raises(DataError, match="NaN"):
        kf.forward_trajectory(u, y_bad)
    with pytest.raises(DataError, match="samples"):
        kf.forward_trajectory(u[:-1], y)
    with pytest.raises(DataError, match="P0"):
        KalmanFilter(A, C, R1, R2, x0, np.eye(3), B=B)


def test_kalman_filter_system_matches_forward_trajectory():
    from pydrake.systems.analysis import Simulator

    from drake_est.estimation.kalman_system import KalmanFilterSystem

    A, B, C, R1, R2, x0, P0, u, y = _model(seed=3, T=15)
    h = 0.1
    sys = KalmanFilterSystem(A, B, C, R1, R2, x0, P0, period=h)
    sim = Simulator(sys)
    ctx = sim.get_mutable_context()
    fr = KalmanFilter(A, C, R1, R2, x0, P0, B=B).forward_trajectory(u, y)
    for t in range(y.shape[0]):
        sys.GetInputPort("u").FixValue(ctx, u[t])
        sys.GetInputPort("y").FixValue(ctx, y[t])
        xh = sys.GetOutputPort("state_estimate").Eval(ctx)
        P = sys.GetOutputPort("covariance").Eval(ctx).reshape(2, 2)
        assert np.allclose(xh, fr.x_filt[t], atol=1e-12)
        assert np.allclose(P, fr.P_filt[t], atol=1e-12)
        sim.AdvanceTo((t + 0.5) * h)
    assert sys.GetOutputPort("log_likelihood").Eval(ctx)[0] == pytest.approx(fr.loglik, abs=1e-9)
