"""Model-based RL (Algorithm 7): model fits, KL-constrained improvement on the Drake cart-pole, bad input."""
import numpy as np
import pytest

from drake_est.control.cartpole import CartPoleModel, benchmark_problem
from drake_est.control.mbrl import fit_lti, fit_ltv, mbrl
from drake_est.errors import DataError


def test_fit_lti_recovers_an_affine_system():
    rng = np.random.default_rng(0)
    A = np.array([[0.9, 0.1], [-0.2, 0.95]])
    B = np.array([[0.0], [0.5]])
    c = np.array([0.1, -0.3])
    Xs, Us = [], []
    for _ in range(2):
        U = rng.normal(size=(50, 1))
        X = np.zeros((51, 2))
        for t in range(50):
            X[t + 1] = A @ X[t] + B @ U[t] + c
        Xs.append(X)
        Us.append(U)
    Ah, Bh, ch = fit_lti(Xs, Us)
    np.testing.assert_allclose(Ah, A, atol=1e-10)
    np.testing.assert_allclose(Bh, B, atol=1e-10)
    np.testing.assert_allclose(ch, c, atol=1e-10)


def test_fit_ltv_predicts_the_cartpole_along_the_trajectory():
    model = CartPoleModel()
    rng = np.random.default_rng(1)
    T = 400
    U = rng.normal(size=(T, 1)) * 2
    x0 = np.array([np.pi - 0.1, 0, 0, 0])
    X, U, ok = model.forward(x0, np.zeros((T + 1, 4)), U, np.zeros((T, 1, 4)), np.zeros((T, 1)), 0.0,
                             np.full((T, 1), -10.0), np.full((T, 1), 10.0))
    ltv, lam = fit_ltv(X, U)
    pred = np.einsum("tij,tj->ti", ltv.A, X[:-1]) + np.einsum("tij,tj->ti", ltv.B, U) + ltv.c
    rel = np.linalg.norm(pred - X[1:]) / np.linalg.norm(X[1:] - X[:-1])
    assert rel < 0.05                       # one-step prediction error small against the increments
    assert lam > 0


def test_mbrl_ltv_improves_on_the_drake_cartpole():
    from drake_est.systems.cartpole_plant import CartPoleTrueSystem
    model, cost, x0, _, lo, hi = benchmark_problem()
    true = CartPoleTrueSystem()
    r = mbrl(true, model, cost, x0, 400, model="ltv", iterations=4, seed=0, lower=lo, upper=hi)
    assert len(r.costs) == 4 and len(r.kl) == 4
    assert min(r.costs[1:]) < 0.9 * r.costs[0]
    assert all(k <= b * 1.1 + 1e-9 for k, b in zip(r.kl, r.kl_bounds))   # the KL bound (11.14) holds
    assert np.abs(r.U_rollout).max() <= 10.0


def test_mbrl_bad_input():
    model, cost, x0, _, lo, hi = benchmark_problem()
    with pytest.raises(DataError, match="model must be one of"):
        mbrl(None, model, cost, x0, 10, model="nn")
    with pytest.raises(DataError, match="iterations"):
        mbrl(None, model, cost, x0, 10, model="ltv", iterations=0)


@pytest.mark.slow
def test_mbrl_ltv_with_nn_prior_runs_and_keeps_the_kl_bound():
    from drake_est.systems.cartpole_plant import CartPoleTrueSystem
    model, cost, x0, _, lo, hi = benchmark_problem()
    r = mbrl(CartPoleTrueSystem(), model, cost, x0, 400, model="ltv-nn", iterations=2, seed=0, lower=lo, upper=hi)
    assert len(r.costs) == 2 and all(np.isfinite(r.costs))
    assert all(k <= b * 1.1 + 1e-9 for k, b in zip(r.kl, r.kl_bounds))


def test_fit_ltv_skips_singular_lambdas_and_raises_when_all_are():
    from drake_est.errors import IdentifiabilityError
    model = CartPoleModel()
    T = 100
    U = np.random.default_rng(0).normal(size=(T, 1))   # 4 equations per step for 6 parameters per row:
    x0 = np.array([np.pi - 0.1, 0, 0, 0])
    X, U, _ = model.forward(x0, np.zeros((T + 1, 4)), U, np.zeros((T, 1, 4)), np.zeros((T, 1)), 0.0,
                            np.full((T, 1), -10.0), np.full((T, 1), 10.0))
    with pytest.raises(IdentifiabilityError, match="lams"):
        fit_ltv(X, U, lams=[0.0, 1e-8])                  # singular without enough random-walk prior
    _, lam = fit_ltv(X, U, lams=[0.0, 1e-8, 10.0])
    assert lam == 10.0


def test_mbrl_noise_scale_is_validated_and_zero_noise_repeats_the_mean_rollout():
    from drake_est.systems.cartpole_plant import CartPoleTrueSystem
    model, cost, x0, _, lo, hi = benchmark_problem()
    with pytest.raises(DataError, match="noise_scale"):
        mbrl(None, model, cost, x0, 10, model="ltv", noise_scale=-1.0)
    r = mbrl(CartPoleTrueSystem(), model, cost, x0, 50, model="lti", iterations=1, noise_scale=0.0,
             lower=lo, upper=hi)
    assert r.rollout_costs[0] == r.costs[0]
