"""LTV identification (thesis Ch. 7): smoother vs closed form and MathematicalProgram, priors,
likelihood, group lasso vs Clarabel, DP vs brute force, change points, bad input."""
import numpy as np
import pytest

from drake_est.errors import DataError, IdentifiabilityError
from drake_est.identification import ltv


def _dense(Phi, y, lam, c, Lam=None, Pi=None, Pimu=None):
    """Dense closed form (7.4) for a scalar-output regression: (A^T A + lam^2 D^T D)^{-1} A^T y."""
    T, p = Phi.shape
    d = len(c) - 1
    Ds = np.zeros((T - d, T))
    for t in range(T - d):
        Ds[t, t:t + d + 1] = c
    Lam = np.eye(p) if Lam is None else Lam
    R = np.kron(Ds.T @ Ds, Lam)
    A = np.zeros((T, T * p))
    for t in range(T):
        A[t, t * p:(t + 1) * p] = Phi[t]
    H = A.T @ A + lam ** 2 * R
    b = A.T @ y
    if Pi is not None:
        H = H + np.kron(np.eye(T), Pi)
        b = b + np.tile(Pi @ Pimu, T)
    k = np.linalg.solve(H, b).reshape(T, p)
    Hi = np.linalg.inv(H)
    return k, np.array([Hi[t * p:(t + 1) * p, t * p:(t + 1) * p] for t in range(T)])


@pytest.fixture(scope="module")
def reg():
    rng = np.random.default_rng(0)
    T, p = 60, 3
    Phi = rng.standard_normal((T, p))
    k = np.column_stack([np.sin(np.arange(T) / 9), np.ones(T), np.linspace(-1, 1, T)])
    y = np.sum(Phi * k, 1) + 0.1 * rng.standard_normal(T)
    return Phi, y


@pytest.mark.parametrize("order", [1, 2])
def test_smoother_equals_closed_form_with_covariance(reg, order):
    Phi, y = reg
    r = ltv.tv_regression_smoother(Phi, y, 2.5, order=order, sigma_e=1.0)
    k, cov = _dense(Phi, y, 2.5, ltv._poly(order))
    assert np.allclose(r.k, k, atol=1e-10)
    assert np.allclose(r.cov, cov, atol=1e-10)


def test_general_operator_and_lambda_matrix(reg):
    Phi, y = reg
    c = [0.3, -1.2, 1.0]                         # P(z) = z^2 - 1.2 z + 0.3
    Lam = np.diag([1.0, 10.0, 0.1])
    r = ltv.tv_regression_smoother(Phi, y, 1.5, P=c, Lambda=Lam, sigma_e=1.0)
    k, cov = _dense(Phi, y, 1.5, np.array(c), Lam)
    assert np.allclose(r.k, k, atol=1e-9)
    assert np.allclose(r.cov, cov, atol=1e-9)
    # a heavy weight on one parameter makes it (nearly) constant, the others keep varying
    r2 = ltv.tv_regression_smoother(Phi, y, 1.0, Lambda=[1.0, 1e6, 1.0])
    assert np.ptp(r2.k[:, 1]) < 0.02 * np.ptp(r2.k[:, 0])


@pytest.mark.parametrize("order", [1, 2])
def test_rts_kalman_smoother_equals_banded(reg, order):
    Phi, y = reg
    a = ltv.tv_regression_smoother(Phi, y, 2.0, order=order, sigma_e=0.5)
    b = ltv.tv_regression_smoother(Phi, y, 2.0, order=order, sigma_e=0.5, method="rts")
    assert np.max(np.abs(a.k - b.k)) <= 1e-6 * np.max(np.abs(a.k))
    assert np.allclose(a.cov, b.cov, rtol=1e-4, atol=1e-8)


@pytest.mark.parametrize("order", [1, 2])
def test_state_space_smoother_equals_mathematicalprogram_qp(order):
    """Acceptance: the Kalman-smoother solution of (7.3)/(7.5) equals the QP in MathematicalProgram."""
    x, u, y, A, B = ltv.jump_system(T=150, seed=1)
    r = ltv.ltv_smoother(x[:-1], u, 5.0, order=order, y=y)
    Aq, Bq = ltv.ltv_qp_reference(x[:-1], u, 5.0, order=order, y=y, solver="clarabel")
    ref = np.concatenate([Aq.reshape(150, -1), Bq.reshape(150, -1)], axis=1)
    est = np.concatenate([r.A.reshape(150, -1), r.B.reshape(150, -1)], axis=1)
    assert np.max(np.abs(est - ref)) <= 1e-6 * np.max(np.abs(ref))
    assert r.cov.shape == (150, 6, 6)
    assert np.all(np.linalg.eigvalsh(r.cov) > 0)


def test_state_space_covariance_is_kronecker_of_row_problem():
    x, u, y, A, B = ltv.jump_system(T=80, seed=2)
    r = ltv.ltv_smoother(x[:-1], u, 3.0, y=y, sigma_e=0.2)
    phi = np.hstack([x[:-1], u])
    for i in range(2):            # each row of [A B] is an independent regression sharing phi
        ri = ltv.tv_regression_smoother(phi, y[:, i], 3.0, sigma_e=0.2)
        assert np.allclose(r.k.reshape(80, 2, 3)[:, i], ri.k, atol=1e-10)
        assert np.allclose(r.cov_row, ri.cov, atol=1e-12)


def test_gaussian_prior_matches_dense_and_kalman_correction(reg):
    Phi, y = reg
    mu = np.array([0.2, 1.0, 0.0])
    S0 = np.diag([0.5, 0.01, 2.0])
    r = ltv.tv_regression_smoother(Phi, y, 2.0, prior_mean=mu, prior_cov=S0, sigma_e=1.0)
    k, cov = _dense(Phi, y, 2.0, ltv._poly(1), Pi=np.linalg.inv(S0), Pimu=mu)
    assert np.allclose(r.k, k, atol=1e-10)
    assert np.allclose(r.cov, cov, atol=1e-10)
    # Eqs. (7.16)-(7.18) inside the Kalman filter give the same posterior
    rk = ltv.tv_regression_smoother(Phi, y, 2.0, prior_mean=mu, prior_cov=S0, sigma_e=1.0, method="rts")
    assert np.allclose(rk.k, k, atol=1e-6)
    # a callable prior (e.g. the Jacobian of a learned model) gives the same answer
    rc = ltv.tv_regression_smoother(Phi, y, 2.0, prior_mean=lambda t: (mu, S0), sigma_e=1.0)
    assert np.allclose(rc.k, r.k)


def test_prior_rescues_unexcited_direction():
    """Sec. 7.5: without excitation of u the problem is refused; a dynamics prior makes it well posed."""
    rng = np.random.default_rng(3)
    T = 100
    A0 = np.array([[0.9, 0.1], [0.0, 0.8]])
    x = np.zeros((T + 1, 2))
    x[0] = [1.0, -1.0]
    for t in range(T):
        x[t + 1] = A0 @ x[t] + 0.05 * rng.standard_normal(2)
    u = np.zeros((T, 1))
    with pytest.raises(IdentifiabilityError, match="u1"):
        ltv.ltv_smoother(x, u, 10.0)
    prior_AB = np.hstack([A0, [[0.2], [1.0]]])
    r = ltv.ltv_smoother(x, u, 10.0, prior=lambda t, xt, ut: (prior_AB, 0.01 * np.eye(3)), sigma_e=0.05)
    assert np.allclose(r.B, [[0.2], [1.0]], atol=1e-6)          # B comes from the prior
    assert np.max(np.abs(r.A - A0)) < 0.1


def test_loglik_is_the_diffuse_gaussian_likelihood(reg):
    Phi, y = reg
    Phi, y = Phi[:30, :2], y[:30]
    T, p = Phi.shape
    s, lam, kap = 0.7, 2.0, 1e7
    for order in (1, 2):
        c = ltv._poly(order)
        d = order
        r = ltv.tv_regression_smoother(Phi, y, lam, order=order, sigma_e=s)
        # dense: k_0..k_{d-1} ~ N(0, kap I), increments P(z)k_t ~ N(0, s^2/lam^2 I)
        L = np.zeros((T * p, T * p))
        for i in range(T * p):
            w = np.zeros((T, p))
            w.reshape(-1)[i] = 1
            k = np.zeros((T, p))
            k[:d] = w[:d]
            for t in range(T - d):
                k[t + d] = (w[t + d] - c[:d] @ k[t:t + d]) / c[d]
            L[:, i] = k.reshape(-1)
        var = np.concatenate([np.full(d * p, kap), np.full((T - d) * p, s ** 2 / lam ** 2)])
        A = np.zeros((T, T * p))
        for t in range(T):
            A[t, t * p:(t + 1) * p] = Phi[t]
        Sy = s ** 2 * np.eye(T) + A @ L @ np.diag(var) @ L.T @ A.T
        ll = -0.5 * (y @ np.linalg.solve(Sy, y) + np.linalg.slogdet(Sy)[1] + T * np.log(2 * np.pi))
        assert r.loglik == pytest.approx(ll + d * p / 2 * np.log(2 * np.pi * kap), abs=1e-3)


def test_lambda_by_maximum_likelihood_drift_example():
    """Sec. 7.7 / Fig. 7.4: sigma_v = 0.01, sigma_w = 0.001, the likelihood peaks near lambda = 10."""
    x, u, A, B = ltv.drift_system(T=1500, seed=0)
    lam, lams, lls = ltv.ltv_select_lambda_ml(x, u, lams=np.logspace(0, 3, 13))
    assert 4.0 < lam < 25.0
    assert lls[0] < lls.max() and lls[-1] < lls.max()


@pytest.mark.parametrize("order", [1, 2])
def test_group_lasso_admm_reaches_clarabel_optimum(order):
    x, u, y, A, B = ltv.jump_system(T=240, t_switch=120, seed=4)
    lam = 8.0
    Ar, Br, cref = ltv.ltv_group_lasso_reference(x[:-1], u, lam, order=order, y=y)
    g = ltv.ltv_group_lasso(x[:-1], u, lam, order=order, y=y, eps_abs=1e-8, eps_rel=1e-7, ftol=1e-9)
    assert g.info["converged"]
    assert abs(g.cost - cref) <= 1e-4 * cref
    assert np.max(np.abs(g.A - Ar)) < 5e-3


def test_linearized_admm_decreases_towards_optimum(reg):
    Phi, y = reg
    kr, cref = ltv.tv_regression_group_lasso_reference(Phi[:40], y[:40], 1.0)
    short = ltv.tv_regression_group_lasso(Phi[:40], y[:40], 1.0, linearized=True, max_iter=200, eps_abs=0, eps_rel=0)
    long = ltv.tv_regression_group_lasso(Phi[:40], y[:40], 1.0, linearized=True, max_iter=20000, eps_abs=0, eps_rel=0)
    assert long.cost < short.cost
    assert abs(long.cost - cref) < 1e-2 * cref


def test_jump_change_located_by_group_lasso():
    x, u, y, A, B = ltv.jump_system(T=400, seed=0)
    g = ltv.ltv_group_lasso(x[:-1], u, 20.0, y=y)
    t = ltv.change_points(g.k, n=1)[0]
    assert abs(t - 200) <= 2
    assert 200 in range(min(g.change_times), max(g.change_times) + 1)
    # two-step refinement (7.10): LTI fits between the knots recover both systems
    rf = ltv.ltv_refine_with_knots(x[:-1], u, [t], y=y)
    assert np.max(np.abs(rf.A[10] - A[10])) < 0.1 and np.max(np.abs(rf.A[-10] - A[-10])) < 0.15


def test_dp_matches_brute_force_small_instance():
    rng = np.random.default_rng(5)
    Phi = rng.standard_normal((14, 2))
    y = rng.standard_normal(14)
    for M in (1, 2, 3):
        cost, cut = ltv.segments_brute_force(Phi, y, M)
        s = ltv.tv_regression_segments(Phi, y, M)
        assert s.change_times == cut
        assert s.cost == pytest.approx(cost, rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("max_blocks", [400, 60])
def test_dp_recovers_switch_times_exactly_noise_free(max_blocks):
    x_len = 1200
    rng = np.random.default_rng(6)
    Phi = np.column_stack([rng.standard_normal(x_len), np.ones(x_len)])
    times = [333, 700, 1001]
    levels = np.array([[1.0, 0.0], [0.5, 1.0], [-0.5, 1.0], [2.0, -1.0]])
    seg = np.searchsorted(times, np.arange(x_len), side="right")
    y = np.sum(Phi * levels[seg], 1)
    s = ltv.tv_regression_segments(Phi, y, 3, max_blocks=max_blocks)
    assert s.change_times == times
    assert np.allclose(s.params, levels, atol=1e-8)
    # state-space form: the jump system without noise
    x, u, _, A, B = ltv.jump_system(T=300, t_switch=137, sigma=0.0, seed=1)
    x[0] = [1.0, -1.0]
    x = ltv.simulate_ltv(A, B, u, x0=[1.0, -1.0])
    r = ltv.ltv_segments(x, u, 1)
    assert r.change_times == [137]
    assert np.allclose(r.A[0], A[0], atol=1e-8) and np.allclose(r.A[-1], A[-1], atol=1e-8)


def test_friction_style_regression_api():
    """The API used by the model-discrepancy diagnosis: y_t = [v_t, sign(v_t)] k_t with an abrupt change."""
    rng = np.random.default_rng(7)
    T = 6000
    v = np.sin(np.arange(T) * 2 * np.pi / 1500.0) + 0.2
    Phi = np.column_stack([v, np.sign(v)])
    k = np.where(np.arange(T)[:, None] < 4321, [0.5, 1.0], [0.5, 1.5])
    y = np.sum(Phi * k, 1) + 0.05 * rng.standard_normal(T)
    s = ltv.tv_regression_segments(Phi, y, 1)
    assert abs(s.change_times[0] - 4321) <= 3
    g = ltv.tv_regression_group_lasso(Phi, y, 5.0)
    assert abs(ltv.change_points(g.k, n=1)[0] - 4321) <= 2 * g.info["block"] + 3
    sm = ltv.tv_regression_smoother(Phi, y, 100.0)
    assert sm.k.shape == (T, 2) and sm.cov.shape == (T, 2, 2)


def test_bad_input_messages():
    x, u, y, A, B = ltv.jump_system(T=50, seed=0)
    with pytest.raises(DataError, match="one more sample"):
        ltv.ltv_smoother(x, u[:-3], 1.0)
    xb = x.copy()
    xb[7, 1] = np.nan
    with pytest.raises(DataError, match="NaN"):
        ltv.ltv_smoother(xb, u, 1.0)
    with pytest.raises(IdentifiabilityError, match="lam = 0"):
        ltv.ltv_smoother(x, u, 0.0)
    with pytest.raises(DataError, match="lam"):
        ltv.ltv_smoother(x, u, -1.0)
    with pytest.raises(DataError, match="Phi has"):
        ltv.tv_regression_smoother(np.ones((10, 2)), np.ones(9), 1.0)
    with pytest.raises(IdentifiabilityError, match="not excited"):
        ltv.tv_regression_group_lasso(np.column_stack([np.ones(30), np.ones(30)]), np.ones(30), 1.0)
    with pytest.raises(DataError, match="T >="):
        ltv.tv_regression_segments(np.ones((5, 2)), np.ones(5), 3)
