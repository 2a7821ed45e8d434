"""Particle filter (Sec. 4.2, Algorithm 1), FFBSi smoother and parameter estimation."""
import os

import numpy as np
import pytest

from drake_est.errors import DataError
from drake_est.estimation.kalman import KalmanFilter
from drake_est.estimation.params import maximize_loglik, pmmh
from drake_est.estimation.pf import ParticleFilter, effective_sample_size, systematic_resample
from drake_est.estimation.protocol import Filter

A = np.array([[0.95, 0.1], [0.0, 0.9]])
C = np.array([[1.0, 0.0]])
R1 = np.diag([0.02, 0.05])
R2 = np.array([[0.1]])
X0 = np.array([0.5, -0.2])
P0 = 0.3 * np.eye(2)


def _linear_data(T=100, seed=0):
    rng = np.random.default_rng(seed)
    x = X0 + np.linalg.cholesky(P0) @ rng.standard_normal(2)
    ys = []
    for _ in range(T):
        ys.append(C @ x + np.sqrt(R2[0, 0]) * rng.standard_normal(1))
        x = A @ x + np.linalg.cholesky(R1) @ rng.standard_normal(2)
    return np.array(ys)


def _linear_pf(N, seed=0, **kw):
    return ParticleFilter.gaussian(lambda x, u, t: x @ A.T, lambda x, u, t: x @ C.T,
                                   R1, R2, X0, P0, n_particles=N, seed=seed, **kw)


@pytest.fixture(scope="module")
def linear_case():
    y = _linear_data()
    kf = KalmanFilter(A, C, R1, R2, X0, P0)
    return y, kf.forward_trajectory(None, y), kf


def test_pf_matches_kalman_mean_and_loglik(linear_case):
    y, kr, _ = linear_case
    # four independent filters (seeds 0..3) pooled: the fraction of 3-sigma exceedances of one run of
    # 100 autocorrelated steps fluctuates too much to test on its own
    zs = []
    for seed in range(4):
        r = _linear_pf(5000, seed=seed).forward_trajectory(None, y)
        # Monte-Carlo standard error of a weighted mean: sqrt(Var / ESS)
        se = np.sqrt(np.diagonal(kr.P_filt, axis1=1, axis2=2) / r.extras["ess"][:, None])
        zs.append(np.abs(r.x_filt - kr.x_filt) / se)
        assert abs(r.loglik - kr.loglik) < 0.01 * abs(kr.loglik)
    z = np.array(zs)
    assert np.mean(z < 3.0) > 0.97, np.sort(z.ravel())[-10:]
    assert np.max(z) < 5.0
    # filtered covariances agree loosely
    assert np.allclose(r.P_filt, kr.P_filt, rtol=0.25, atol=5e-3)


def test_protocol_loop_and_seed_determinism(linear_case):
    y = linear_case[0][:40]
    pf = _linear_pf(300, seed=4)
    r = pf.forward_trajectory(None, y)
    g = Filter.forward_trajectory(pf, None, y)       # generic step-by-step loop of the protocol
    assert abs(r.loglik - g.loglik) < 1e-10
    np.testing.assert_allclose(r.x_pred, g.x_pred, atol=1e-10)
    # the general (non-vectorised) ParticleFilter loop gives the same numbers as the fast one
    s = ParticleFilter.forward_trajectory(pf, None, y)
    np.testing.assert_allclose(s.x_filt, r.x_filt, atol=1e-10)
    np.testing.assert_allclose(s.P_filt, r.P_filt, atol=1e-10)
    r2 = _linear_pf(300, seed=4).forward_trajectory(None, y)
    assert r2.loglik == r.loglik and np.array_equal(r2.x_filt, r.x_filt)
    r3 = _linear_pf(300, seed=5).forward_trajectory(None, y)
    assert r3.loglik != r.loglik
    assert r.extras["n_resampled"] >= 1


def _cartpole():
    g, l, h = 9.81, 1.0, 0.01

    def f(x, u, t):
        th, w = x[..., 0], x[..., 1]
        a = -(g / l) * np.sin(th) + (u[0] / l) * np.cos(th) - 0.1 * w
        return np.stack([th + h * w, w + h * a, x[..., 2] + h * x[..., 3], x[..., 3] + h * u[0]], axis=-1)

    def hm(x, u, t):
        return x[..., [0, 2]]

    def f1(x, u, t, out):
        a = -(g / l) * np.sin(x[0]) + (u[0] / l) * np.cos(x[0]) - 0.1 * x[1]
        out[0] = x[0] + h * x[1]
        out[1] = x[1] + h * a
        out[2] = x[2] + h * x[3]
        out[3] = x[3] + h * u[0]

    def h1(x, u, t, out):
        out[0] = x[0]
        out[1] = x[2]

    return f, hm, f1, h1


@pytest.mark.skipif(os.environ.get("DRAKE_EST_NO_NUMBA") == "1",
                    reason="compares the compiled paths with the numpy path (numba disabled)")
def test_numba_kernel_equals_numpy_path():
    f, hm, f1, h1 = _cartpole()
    T = 150
    rng = np.random.default_rng(2)
    u = np.sin(0.05 * np.arange(T))[:, None]
    y = 0.05 * rng.standard_normal((T, 2)) + np.c_[0.2 * np.ones(T), np.zeros(T)]
    y[17] = np.nan                                     # a missing measurement in both paths
    kw = dict(n_particles=300, seed=1, nu=1)
    pf = ParticleFilter.gaussian(f, hm, 1e-4 * np.eye(4), 0.0025 * np.eye(2), np.zeros(4), 0.1 * np.eye(4),
                                 f_point=f1, h_point=h1, **kw)
    fused = pf.forward_trajectory(u, y)
    assert fused.extras.get("compiled") is True
    os.environ["DRAKE_EST_NO_NUMBA"] = "1"
    try:
        plain = pf.forward_trajectory(u, y)
    finally:
        del os.environ["DRAKE_EST_NO_NUMBA"]
    assert "compiled" not in plain.extras
    assert plain.n_missing == fused.n_missing == 1
    for k in ("x_filt", "P_filt", "x_pred", "P_pred"):
        np.testing.assert_allclose(getattr(fused, k), getattr(plain, k), atol=1e-10, rtol=0)
    assert abs(fused.loglik - plain.loglik) < 1e-10 * max(1.0, abs(plain.loglik))
    assert fused.extras["n_resampled"] == plain.extras["n_resampled"] > 0
    # the generic path (numpy f, h; compiled weighting/resampling/propagation) gives the same numbers too,
    # with and without covariances, and with full (non-diagonal) noise covariances
    gen = ParticleFilter.gaussian(f, hm, 1e-4 * np.eye(4), 0.0025 * np.eye(2), np.zeros(4), 0.1 * np.eye(4), **kw)
    for cov in (True, False):
        g = gen.forward_trajectory(u, y, covariances=cov)
        for k in ("x_filt", "x_pred") + (("P_filt", "P_pred") if cov else ()):
            np.testing.assert_allclose(getattr(g, k), getattr(plain, k), atol=1e-10, rtol=0)
        assert abs(g.loglik - plain.loglik) < 1e-10 * max(1.0, abs(plain.loglik))
    Rf = 1e-4 * (np.eye(4) + 0.5 * np.ones((4, 4)))
    R2f = 0.0025 * np.array([[1.0, 0.4], [0.4, 1.0]])          # full R1 and R2: the triangular-solve paths
    fulls = [ParticleFilter.gaussian(f, hm, Rf, R2f, np.zeros(4), 0.1 * np.eye(4),
                                     f_point=fp, h_point=hp, **kw) for fp, hp in ((f1, h1), (None, None))]
    runs = [p_.forward_trajectory(u, y) for p_ in fulls]
    os.environ["DRAKE_EST_NO_NUMBA"] = "1"
    try:
        ref = fulls[1].forward_trajectory(u, y)
    finally:
        del os.environ["DRAKE_EST_NO_NUMBA"]
    for r_ in runs:
        np.testing.assert_allclose(r_.x_filt, ref.x_filt, atol=1e-10, rtol=0)
        np.testing.assert_allclose(r_.P_pred, ref.P_pred, atol=1e-10, rtol=0)
        assert abs(r_.loglik - ref.loglik) < 1e-10 * max(1.0, abs(ref.loglik))


def test_box_muller_normals():
    from drake_est.estimation.pf import box_muller_f32
    n = 400_001                                      # odd length: the last pair is half used
    out, sc = np.empty(n, np.float32), np.empty((2, (n + 1) // 2), np.float32)
    box_muller_f32(np.random.default_rng(3), out, sc)
    z = out.astype(float)
    se = 1.0 / np.sqrt(n)
    assert abs(z.mean()) < 4 * se
    assert abs(z.var() - 1.0) < 4 * np.sqrt(2.0) * se
    assert abs(np.mean(z ** 4) - 3.0) < 4 * np.sqrt(96.0) * se
    h = (n + 1) // 2                                 # the two halves share the radii: still uncorrelated
    assert abs(np.corrcoef(z[:h - 1], z[h:])[0, 1]) < 4 / np.sqrt(h)
    assert abs(np.corrcoef(z[:h - 1] ** 2, z[h:] ** 2)[0, 1]) < 4 / np.sqrt(h)
    assert np.all(np.isfinite(z)) and np.abs(z).max() < 5.8
    out2 = np.empty_like(out)
    box_muller_f32(np.random.default_rng(3), out2, sc)
    assert np.array_equal(out, out2)


def test_ffbsi_matches_rts(linear_case):
    y, _, kf = linear_case
    y = y[:60]
    ks = kf.smooth(None, y)
    sm = _linear_pf(1000, seed=2).smooth(None, y, n_trajectories=300)
    assert sm.trajectories.shape == (300, 60, 2)
    # the M backward trajectories are (nearly) independent draws: SE ~ sqrt(P_smooth / M), plus filter error
    se = np.sqrt(np.diagonal(ks.P_smooth, axis1=1, axis2=2) / 300 + np.diagonal(ks.P_smooth, axis1=1, axis2=2) / 300)
    z = np.abs(sm.x_smooth - ks.x_smooth) / se
    assert np.mean(z < 3.0) > 0.95, np.sort(z.ravel())[-5:]
    # covariance elements: SE of a sample covariance ~ sqrt((P_ii P_jj + P_ij^2) / M)
    Pk = ks.P_smooth
    d = np.diagonal(Pk, axis1=1, axis2=2)
    se_P = np.sqrt((d[:, :, None] * d[:, None, :] + Pk ** 2) / 300)
    assert np.mean(np.abs(sm.P_smooth - Pk) < 3 * se_P) > 0.95
    # smoothing beats filtering on the states
    fr = sm.filtered
    assert np.mean((sm.x_smooth - ks.x_smooth) ** 2) < np.mean((fr.x_filt - ks.x_smooth) ** 2)


def test_proposal_variant_locally_optimal(linear_case):
    """Fully adapted proposal q(x+|x, y+) = p(x+|x, y+) for the linear model: the weights are then
    the predictive likelihoods and the estimate stays unbiased."""
    y = linear_case[0]
    kr = linear_case[1]
    S = C @ R1 @ C.T + R2
    K = np.linalg.solve(S, C @ R1).T                     # R1 C^T S^-1
    Sig = R1 - K @ C @ R1
    Ls = np.linalg.cholesky(Sig)
    Ls1 = np.linalg.cholesky(R1)

    def gauss_logpdf(d, L):
        r = np.linalg.solve(L, d.T).T
        return -0.5 * np.sum(r * r, axis=1) - np.sum(np.log(np.diag(L))) - L.shape[0] * 0.5 * np.log(2 * np.pi)

    def trans(x, u, t, rng):
        return x @ A.T + rng.standard_normal(x.shape) @ Ls1.T

    def prop(x, u, t, yn, rng):
        m = x @ A.T
        m = m + (yn - m @ C.T) @ K.T
        return m + rng.standard_normal(x.shape) @ Ls.T

    def prop_lp(xn, x, u, t, yn):
        m = x @ A.T
        return gauss_logpdf(xn - m - (yn - m @ C.T) @ K.T, Ls)

    def trans_lp(xn, x, u, t):
        return gauss_logpdf(xn - x @ A.T, Ls1)

    def meas_lp(x, yv, u, t):
        return gauss_logpdf(yv - x @ C.T, np.sqrt(R2))

    pf = ParticleFilter(trans, meas_lp, lambda rng, N: X0 + rng.standard_normal((N, 2)) @ np.linalg.cholesky(P0).T,
                        2000, seed=3, proposal=prop, proposal_logpdf=prop_lp, transition_logpdf=trans_lp)
    r = pf.forward_trajectory(None, y)
    boot = ParticleFilter(trans, meas_lp, pf._x_init, 2000, seed=3).forward_trajectory(None, y)
    assert abs(r.loglik - kr.loglik) < 0.01 * abs(kr.loglik)
    # the adapted proposal keeps more effective particles than the bootstrap one
    assert np.nanmean(r.extras["ess"]) > np.nanmean(boot.extras["ess"])


def test_nan_measurement_is_predict_only(linear_case):
    y = linear_case[0][:30].copy()
    y[[3, 10, 11]] = np.nan
    pf = _linear_pf(200)
    r = pf.forward_trajectory(None, y)
    assert r.n_missing == 3
    np.testing.assert_allclose(r.x_filt[10], r.x_pred[10])
    assert np.isnan(r.extras["ess"][10]) and np.isfinite(r.loglik)
    full = pf.forward_trajectory(None, np.where(np.isnan(y), 0.0, y))
    assert full.loglik != r.loglik


def test_degeneracy_recovered_and_reported():
    """A measurement impossible under every particle (likelihood exactly zero) must not produce NaN."""
    def meas_lp(x, y, u, t):
        return np.where(np.abs(x[:, 0] - y[0]) < 0.5, 0.0, -np.inf)

    pf = ParticleFilter(lambda x, u, t, rng: x + 0.1 * rng.standard_normal(x.shape), meas_lp,
                        lambda rng, N: rng.standard_normal((N, 1)), 200, seed=0)
    y = np.array([[0.0], [0.1], [50.0], [0.2], [np.nan], [0.1]])
    r = pf.forward_trajectory(None, y)
    assert r.extras["degenerate_steps"] == [2] and r.extras["n_degenerate"] == 1
    assert np.all(np.isfinite(r.x_filt)) and np.all(np.isfinite(r.P_filt))
    assert r.loglik == -np.inf
    # NaN likelihoods (e.g. from NaN particles) are weight zero, never NaN estimates
    pf2 = ParticleFilter(lambda x, u, t, rng: x + rng.standard_normal(x.shape),
                         lambda x, y, u, t: np.where(x[:, 0] > 0, np.nan, -0.5 * (x[:, 0] - y[0]) ** 2),
                         lambda rng, N: rng.standard_normal((N, 1)), 100, seed=1)
    r2 = pf2.forward_trajectory(None, np.zeros((5, 1)))
    assert np.all(np.isfinite(r2.x_filt)) and np.isfinite(r2.loglik)


def test_resampling_helpers():
    w = np.array([0.1, 0.0, 0.6, 0.3])
    idx = systematic_resample(w, 0.5)
    assert list(idx) == [2, 2, 2, 3]        # positions 0.125, 0.375, 0.625, 0.875 on cumsum 0.1, 0.1, 0.7, 1
    rng = np.random.default_rng(0)
    w = rng.random(50)
    w /= w.sum()
    counts = np.bincount(systematic_resample(w, 0.37), minlength=50)
    assert np.all(np.abs(counts - 50 * w) < 1.0 + 1e-12)    # systematic: each count is floor or ceil of N w_i
    assert abs(effective_sample_size(np.log(np.full(8, 1 / 8))) - 8) < 1e-12
    assert abs(effective_sample_size(np.array([0.0, -np.inf, -np.inf])) - 1) < 1e-12


def test_bad_input_one_line_errors():
    f = lambda x, u, t: x @ A.T   # noqa: E731
    h = lambda x, u, t: x @ C.T   # noqa: E731
    with pytest.raises(DataError, match="n_particles"):
        ParticleFilter.gaussian(f, h, R1, R2, X0, P0, n_particles=1)
    with pytest.raises(DataError, match="R1 is not positive definite"):
        ParticleFilter.gaussian(f, h, -R1, R2, X0, P0, n_particles=10)
    with pytest.raises(DataError, match="R2 is not symmetric"):
        ParticleFilter.gaussian(f, h, R1, np.array([[1.0, 0.2], [0.0, 1.0]]), X0, P0, n_particles=10)
    with pytest.raises(DataError, match="P0"):
        ParticleFilter.gaussian(f, h, R1, R2, X0, np.eye(3), n_particles=10)
    bad = ParticleFilter.gaussian(lambda x, u, t: x[..., :1], h, R1, R2, X0, P0, n_particles=10)
    with pytest.raises(DataError, match="f returned shape"):
        bad.forward_trajectory(None, np.zeros((5, 1)))
    gen = ParticleFilter(lambda x, u, t, rng: x[:5], lambda x, y, u, t: np.zeros(len(x)),
                         np.zeros((10, 2)), 10)
    with pytest.raises(DataError, match="transition returned shape"):
        gen.forward_trajectory(None, np.zeros((3, 1)))
    with pytest.raises(DataError, match="y has 2 columns"):
        _linear_pf(10).forward_trajectory(None, np.zeros((5, 2)))
    with pytest.raises(DataError, match="infinity"):
        _linear_pf(10).forward_trajectory(None, np.array([[0.0], [np.inf]]))
    for err in (DataError("x"),):
        assert "\n" not in str(err)


def test_maximize_loglik_kalman_and_pf_crn():
    """Recover the AR coefficient a of x+ = a x + v, y = x + e by maximum likelihood, with the exact
    Kalman likelihood and with the PF likelihood under common random numbers."""
    a_true = 0.8
    rng = np.random.default_rng(0)
    T = 300
    x, ys = 0.0, []
    for _ in range(T):
        ys.append(x + 0.3 * rng.standard_normal())
        x = a_true * x + 0.5 * rng.standard_normal()
    y = np.array(ys)[:, None]

    def make_kf(th):
        return KalmanFilter(np.array([[th[0]]]), np.eye(1), np.eye(1) * 0.25, np.eye(1) * 0.09,
                            np.zeros(1), np.eye(1))

    def make_pf(th):
        return ParticleFilter.gaussian(lambda x, u, t: th[0] * x, lambda x, u, t: x, [[0.25]], [[0.09]],
                                       [0.0], [[1.0]], n_particles=200, seed=11)

    rk = maximize_loglik(make_kf, [0.3], None, y)
    rp = maximize_loglik(make_pf, [0.3], None, y)
    assert abs(rk.theta[0] - a_true) < 0.1
    assert abs(rp.theta[0] - rk.theta[0]) < 0.05
    assert rp.loglik >= make_pf(np.array([0.3])).loglik(None, y)


def test_pmmh_short_chain():
    rng = np.random.default_rng(1)
    T = 100
    x, ys = 0.0, []
    for _ in range(T):
        ys.append(x + 0.3 * rng.standard_normal())
        x = 0.8 * x + 0.5 * rng.standard_normal()
    y = np.array(ys)[:, None]

    def make(th, seed):
        return ParticleFilter.gaussian(lambda x, u, t: th[0] * x, lambda x, u, t: x, [[0.25]], [[0.09]],
                                       [0.0], [[1.0]], n_particles=300, seed=seed)

    def log_prior(th):
        return 0.0 if -1 < th[0] < 1 else -np.inf

    # exact posterior mean of a under the flat prior, from the Kalman likelihood on a grid
    grid = np.linspace(-0.99, 0.99, 199)
    ll = np.array([KalmanFilter(np.array([[a]]), np.eye(1), np.eye(1) * 0.25, np.eye(1) * 0.09, np.zeros(1),
                                np.eye(1)).loglik(None, y) for a in grid])
    p = np.exp(ll - ll.max())
    exact_mean = float(np.sum(grid * p) / np.sum(p))
    r = pmmh(make, log_prior, [0.2], None, y, n_iter=200, step_cov=[[0.02]], seed=0, show_progress=False)
    assert r.chain.shape == (200, 1)
    assert 0.05 < r.acceptance_rate < 0.95
    assert np.all(np.abs(r.chain) < 1)
    assert abs(r.posterior_mean(burn_in=50)[0] - exact_mean) < 0.15, (r.posterior_mean(50), exact_mean)
    r2 = pmmh(make, log_prior, [0.2], None, y, n_iter=20, step_cov=[[0.02]], seed=0, show_progress=False)
    assert np.array_equal(r.chain[:20], r2.chain)
    with pytest.raises(DataError, match="step_cov"):
        pmmh(make, log_prior, [0.5], None, y, n_iter=5, step_cov=[[-1.0]])


def test_vectorised_exp_matches_numpy():
    from drake_est.estimation.pf_kernels import vexp
    rng = np.random.default_rng(0)
    a = np.r_[-rng.random(997) * 700.0, 0.0, -np.inf, -750.0]
    out, kb = np.empty_like(a), np.empty(a.shape[0], np.int64)
    vexp(a, 0.0, out, kb)
    ref = np.exp(a)
    assert np.all(np.abs(out - ref) <= 1e-15 * ref + 1e-300)
    assert out[-2] == 0.0 and out[-3] == 1.0
    vexp(a[:10] + 5.0, 5.0, out[:10], kb[:10])
    np.testing.assert_allclose(out[:10], ref[:10], rtol=1e-14)


def _nan_f(x, u, t):
    xn = 0.9 * x
    return np.where((t == 3) & (x > 0.5), np.nan, xn)


def _nan_f_point(x, u, t, out):
    out[0] = 0.9 * x[0]
    if t == 3 and x[0] > 0.5:
        out[0] = np.nan


def _id_h(x, u, t):
    return x


def _id_h_point(x, u, t, out):
    out[0] = x[0]


@pytest.mark.skipif(os.environ.get("DRAKE_EST_NO_NUMBA") == "1",
                    reason="compares the compiled paths with the numpy path (numba disabled)")
def test_nonfinite_transition_replaced_same_in_every_path():
    """Particles that the transition sends to NaN are dropped and replaced by resampling, identically in the
    fused, generic-compiled and numpy paths."""
    y = np.random.default_rng(5).standard_normal((12, 1))
    kw = dict(n_particles=200, seed=3)
    fused = ParticleFilter.gaussian(_nan_f, _id_h, [[0.1]], [[0.5]], [0.0], [[1.0]], f_point=_nan_f_point,
                                    h_point=_id_h_point, **kw).forward_trajectory(None, y)
    gen = ParticleFilter.gaussian(_nan_f, _id_h, [[0.1]], [[0.5]], [0.0], [[1.0]], **kw)
    g = gen.forward_trajectory(None, y)
    os.environ["DRAKE_EST_NO_NUMBA"] = "1"
    try:
        ref = gen.forward_trajectory(None, y)
    finally:
        del os.environ["DRAKE_EST_NO_NUMBA"]
    assert np.all(np.isfinite(ref.x_filt)) and np.all(np.isfinite(ref.x_pred)) and np.isfinite(ref.loglik)
    for r in (fused, g):
        np.testing.assert_allclose(r.x_filt, ref.x_filt, atol=1e-10, rtol=0)
        np.testing.assert_allclose(r.x_pred, ref.x_pred, atol=1e-10, rtol=0)
        np.testing.assert_allclose(r.P_pred, ref.P_pred, atol=1e-10, rtol=0)
        assert abs(r.loglik - ref.loglik) < 1e-10 * max(1.0, abs(ref.loglik))
    # without the NaNs the predicted mean after step 3 differs: the replacement really happened
    clean = ParticleFilter.gaussian(lambda x, u, t: 0.9 * x, _id_h, [[0.1]], [[0.5]], [0.0], [[1.0]], **kw)
    assert abs(clean.forward_trajectory(None, y).x_pred[4, 0] - ref.x_pred[4, 0]) > 1e-3
