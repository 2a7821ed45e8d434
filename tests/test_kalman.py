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
    with pytest.raises(DataError, match="samples"):
        kf.forward_trajectory(u[:-1], y)
    with pytest.raises(DataError, match="P0"):
        KalmanFilter(A, C, R1, R2, x0, np.eye(3), B=B)
    with pytest.raises(DataError, match="^R1 is not positive semidefinite"):
        KalmanFilter(A, C, -R1, R2, x0, P0, B=B)
    with pytest.raises(DataError, match="^R2 is not positive definite"):
        KalmanFilter(A, C, R1, 0 * R2, x0, P0, B=B)
    with pytest.raises(DataError, match="^R2 is not symmetric"):
        KalmanFilter(A, np.eye(2), R1, np.array([[1.0, 0.5], [0.0, 1.0]]), x0, P0, B=B)
    A_nan = A.copy()
    A_nan[1, 0] = np.nan
    with pytest.raises(DataError, match="^A contains NaN"):
        KalmanFilter(A_nan, C, R1, R2, x0, P0, B=B)
    C_nan = C.copy()
    C_nan[0, 1] = np.inf
    with pytest.raises(DataError, match="^C contains NaN"):
        KalmanFilter(A, C_nan, R1, R2, x0, P0, B=B)
    with pytest.raises(DataError, match="^C has 3 columns"):
        KalmanFilter(A, np.ones((1, 3)), R1, R2, x0, P0, B=B)
    At = np.array([A] * (y.shape[0] - 5))
    with pytest.raises(DataError, match="time-varying A has 20 steps, the data have 25"):
        KalmanFilter(At, C, R1, R2, x0, P0, B=B).forward_trajectory(u, y)
    y_inf = y.copy()
    y_inf[2, 0] = np.inf
    with pytest.raises(DataError, match="^y contains infinity"):
        kf.forward_trajectory(u, y_inf)
    with pytest.raises(DataError, match="^y has 2 columns"):
        kf.forward_trajectory(u, np.column_stack([y, y]))


@pytest.mark.parametrize("fused", [True, False])
def test_nan_measurement_is_predict_only_and_counted(fused):
    A, B, C, R1, R2, x0, P0, u, y = _model(seed=4)
    kf = KalmanFilter(A, C, R1, R2, x0, P0, B=B)
    yb = y.copy()
    yb[[3, 10], 0] = np.nan
    fr = kf.forward_trajectory(u, yb, fused=fused)
    assert fr.n_missing == 2
    # step 3 is a pure prediction: filtered = predicted, and the next prediction is A x + B u
    assert np.allclose(fr.x_filt[3], fr.x_pred[3], atol=1e-14)
    assert np.allclose(fr.P_filt[3], fr.P_pred[3], atol=1e-14)
    assert np.allclose(fr.x_pred[4], A @ fr.x_filt[3] + B @ u[3], atol=1e-12)
    # the likelihood is that of the observed rows only (dense conditioning on the 23 observed values)
    full = kf.forward_trajectory(u, y, fused=fused)
    assert fr.loglik != pytest.approx(full.loglik)
    assert np.all(np.isfinite(fr.x_filt)) and np.isfinite(fr.loglik)


def test_fused_loop_equals_numpy_loop(monkeypatch):
    from drake_est.estimation import kalman_kernels

    rng = np.random.default_rng(5)
    nx, ny, nu, T = 4, 2, 1, 400
    A = np.eye(nx) + 0.05 * rng.standard_normal((nx, nx))
    A *= 0.98 / max(abs(np.linalg.eigvals(A)))
    B = rng.standard_normal((nx, nu))
    C = rng.standard_normal((ny, nx))
    D = 0.1 * rng.standard_normal((ny, nu))
    R1 = 0.01 * np.eye(nx) + 0.001
    R2 = np.array([[0.2, 0.05], [0.05, 0.1]])
    x0, P0 = rng.standard_normal(nx), np.eye(nx)
    u = rng.standard_normal((T, nu))
    y = rng.standard_normal((T, ny))
    y[7] = np.nan
    kf = KalmanFilter(A, C, R1, R2, x0, P0, B=B, D=D)
    monkeypatch.delenv("DRAKE_EST_NO_NUMBA", raising=False)
    assert kalman_kernels.use_numba() == kalman_kernels.HAVE_NUMBA
    a = kf.smooth(u, y, fused=True)
    b = kf.smooth(u, y, fused=False)
    for f in ("x_filt", "P_filt", "x_pred", "P_pred"):
        np.testing.assert_allclose(getattr(a.filtered, f), getattr(b.filtered, f), atol=1e-10, rtol=0)
    np.testing.assert_allclose(a.x_smooth, b.x_smooth, atol=1e-10, rtol=0)
    np.testing.assert_allclose(a.P_smooth, b.P_smooth, atol=1e-10, rtol=0)
    assert a.loglik == pytest.approx(b.loglik, abs=1e-10)
    assert a.filtered.n_missing == b.filtered.n_missing == 1
    monkeypatch.setenv("DRAKE_EST_NO_NUMBA", "1")
    assert not kalman_kernels.use_numba()
    c = kf.smooth(u, y)
    np.testing.assert_allclose(c.x_smooth, b.x_smooth, atol=0, rtol=0)


def test_protocol_generic_loop_equals_override():
    from drake_est.estimation.protocol import Filter

    A, B, C, R1, R2, x0, P0, u, y = _model(seed=6)
    kf = KalmanFilter(A, C, R1, R2, x0, P0, B=B)
    assert isinstance(kf, Filter)
    belief = kf.initial_belief()
    ll = 0.0
    for t in range(y.shape[0]):
        *belief, l_t = kf.correct(*belief, y=y[t], u=u[t], t=t)
        ll += l_t
        belief = kf.predict(*belief, u=u[t], t=t)
    fr = kf.forward_trajectory(u, y)
    assert np.allclose(kf.mean(belief), fr.x_pred[-1], atol=1e-10)
    assert np.allclose(kf.cov(belief), fr.P_pred[-1], atol=1e-10)
    assert ll == pytest.approx(fr.loglik, abs=1e-10)


def test_filterpy_agrees():
    filterpy = pytest.importorskip("filterpy.kalman")
    A, B, C, R1, R2, x0, P0, u, y = _model(seed=7, T=60)
    kf = KalmanFilter(A, C, R1, R2, x0, P0)
    fp = filterpy.KalmanFilter(dim_x=2, dim_z=1)
    fp.x, fp.P, fp.F, fp.H, fp.Q, fp.R = x0.copy(), P0.copy(), A, C, R1, R2
    # filterpy's batch_filter predicts first; give it our prior one step back: x_{-1} with A x_{-1} = x0
    mu, cov, _, _ = fp.batch_filter(y, update_first=True)
    xs, Ps, _, _ = fp.rts_smoother(mu, cov)
    sm = kf.smooth(None, y)
    np.testing.assert_allclose(sm.filtered.x_filt, mu, atol=1e-10)
    np.testing.assert_allclose(sm.x_smooth, xs, atol=1e-10)
    np.testing.assert_allclose(sm.P_smooth, Ps, atol=1e-10)


def test_fused_equals_numpy_on_random_models(require_module):
    """Property: on random stable models (any nx, ny, with/without input, missing rows) the compiled loop
    gives the numpy loop's numbers to 1e-10."""
    hyp = require_module("hypothesis")
    from hypothesis import strategies as st

    @hyp.settings(max_examples=10, deadline=None, derandomize=True)
    @hyp.given(nx=st.integers(1, 5), ny=st.integers(1, 3), nu=st.integers(0, 2), seed=st.integers(0, 10_000))
    def check(nx, ny, nu, seed):
        rng = np.random.default_rng(seed)
        T = 60
        A = rng.standard_normal((nx, nx))
        A *= 0.9 / max(1e-9, max(abs(np.linalg.eigvals(A))))
        C = rng.standard_normal((ny, nx))
        M1, M2 = rng.standard_normal((nx, nx)), rng.standard_normal((ny, ny))
        R1, R2 = 0.1 * M1 @ M1.T + 0.01 * np.eye(nx), 0.1 * M2 @ M2.T + 0.05 * np.eye(ny)
        B = rng.standard_normal((nx, nu)) if nu else None
        u = rng.standard_normal((T, nu)) if nu else None
        y = rng.standard_normal((T, ny))
        y[rng.random(T) < 0.1, 0] = np.nan
        kf = KalmanFilter(A, C, R1, R2, rng.standard_normal(nx), np.eye(nx), B=B)
        a, b = kf.smooth(u, y, fused=True), kf.smooth(u, y, fused=False)
        np.testing.assert_allclose(a.x_smooth, b.x_smooth, atol=1e-10, rtol=0)
        np.testing.assert_allclose(a.P_smooth, b.P_smooth, atol=1e-10, rtol=0)
        np.testing.assert_allclose(a.filtered.P_pred, b.filtered.P_pred, atol=1e-10, rtol=0)
        assert abs(a.loglik - b.loglik) <= 1e-10 * max(1.0, abs(b.loglik))
        assert a.filtered.n_missing == b.filtered.n_missing

    check()
