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


def test_mbrl_ltv_with_successive_nn_prior_runs_and_keeps_the_kl_bound():
    from drake_est.systems.cartpole_plant import CartPoleTrueSystem
    model, cost, x0, _, lo, hi = benchmark_problem()
    r = mbrl(CartPoleTrueSystem(), model, cost, x0, 400, model="ltv-nn", iterations=2, seed=0, lower=lo, upper=hi,
             nn_first_steps=150, nn_steps=50, nn_prior_cov=10.0)
    assert len(r.costs) == 2 and all(np.isfinite(r.costs))
    assert all(k <= b * 1.1 + 1e-9 for k, b in zip(r.kl, r.kl_bounds))


@pytest.fixture(scope="module")
def small_pretrained():
    from drake_est.control.mbrl import pretrain_network_prior
    return pretrain_network_prior(n_rollouts=4, T=200, steps=400, seed=0)


def test_network_prior_warm_start_continues_and_its_linearization_is_affine_consistent(small_pretrained):
    from drake_est.control.mbrl import NetworkPrior
    net = small_pretrained
    model = CartPoleModel()
    rng = np.random.default_rng(3)
    T = 100
    X, U, _ = model.forward(np.array([2.0, 0, 0, 0]), np.zeros((T + 1, 4)), rng.normal(size=(T, 1)),
                            np.zeros((T, 1, 4)), np.zeros((T, 1)), 0.0, np.full((T, 1), -10.0), np.full((T, 1), 10.0))
    P = net.linearization(X, U)
    assert P.shape == (T, 4, 6)
    # A x + B u + c reproduces the network's own one-step prediction at the linearization points
    lin = np.einsum("tij,tj->ti", P[:, :, :4], X[:-1]) + P[:, :, 4] * U + P[:, :, 5]
    np.testing.assert_allclose(lin, net.model_.predict(X[:-1], U), atol=1e-10)
    # pretrained on the same physics: its A is much closer to the true Jacobian than the identity is
    fx, fu = model.linearize(X, U)[:2]
    err = np.linalg.norm(P[:, :, :4] - fx, axis=(1, 2)).mean()
    assert err < 0.5 * np.linalg.norm(fx - np.eye(4), axis=(1, 2)).mean()
    # warm start: a further fit continues from the current weights (steps add up, weights move a little)
    w_before = net.params_s[0][0].copy()
    n0 = net.total_steps
    import copy
    net2 = copy.deepcopy(net)
    net2.fit([X], [U], steps=5)
    assert net2.total_steps == n0 + 5
    assert 0 < np.abs(net2.params_s[0][0] - w_before).max() < 0.1
    with pytest.raises(DataError, match="steps"):
        NetworkPrior(steps=0)
    with pytest.raises(DataError, match="not trained"):
        NetworkPrior().linearization(X, U)


def test_pretrained_prior_changes_the_ltv_fit(small_pretrained):
    """Sec. 11.2 / Eq. (7.15): a tight prior pulls the LTV fit toward the network's linearization, a very wide
    one gives back the fit without prior."""
    model = CartPoleModel()
    rng = np.random.default_rng(1)
    T = 200
    X, U, _ = model.forward(np.array([np.pi - 0.1, 0, 0, 0]), np.zeros((T + 1, 4)), rng.normal(size=(T, 1)) * 2,
                            np.zeros((T, 1, 4)), np.zeros((T, 1)), 0.0, np.full((T, 1), -10.0), np.full((T, 1), 10.0))
    P = small_pretrained.linearization(X, U)
    free, _ = fit_ltv(X, U)
    tight, _ = fit_ltv(X, U, prior=P, prior_cov=1e-8 * np.eye(6))
    wide, _ = fit_ltv(X, U, prior=P, prior_cov=1e12 * np.eye(6))

    def dist(m):
        return np.linalg.norm(m.A - P[:, :, :4], axis=(1, 2)).mean()
    assert dist(tight) < 0.5 * dist(free)
    np.testing.assert_allclose(wide.A, free.A, atol=1e-4 * max(1.0, np.abs(free.A).max()))
    for m in (free, tight):      # both still explain the data along the trajectory
        pred = np.einsum("tij,tj->ti", m.A, X[:-1]) + np.einsum("tij,tj->ti", m.B, U) + m.c
        assert np.linalg.norm(pred - X[1:]) < 1e-3 * np.linalg.norm(X[1:] - X[:-1])
    with pytest.raises(DataError, match="sigma_e"):
        fit_ltv(X, U, prior=P, prior_cov=np.eye(6), sigma_e=-1.0)


def test_mbrl_with_pretrained_prior_runs_and_the_prior_matters(small_pretrained):
    from drake_est.systems.cartpole_plant import CartPoleTrueSystem
    model, cost, x0, _, lo, hi = benchmark_problem()
    kw = dict(model="ltv-nn-pretrained", iterations=2, seed=0, lower=lo, upper=hi, pretrained=small_pretrained)
    r = mbrl(CartPoleTrueSystem(), model, cost, x0, 400, nn_prior_cov=1e-6, **kw)
    r_wide = mbrl(CartPoleTrueSystem(), model, cost, x0, 400, nn_prior_cov=1e12, **kw)
    r_ltv = mbrl(CartPoleTrueSystem(), model, cost, x0, 400, model="ltv", iterations=2, seed=0, lower=lo, upper=hi)
    assert all(np.isfinite(r.costs)) and all(k <= b * 1.1 + 1e-9 for k, b in zip(r.kl, r.kl_bounds))
    assert r.costs[0] == r_wide.costs[0] == r_ltv.costs[0]           # same first experiment
    assert abs(r.costs[1] - r_wide.costs[1]) > 1e-3 * r_wide.costs[1]  # the tight prior changed the controller
    assert abs(r_wide.costs[1] - r_ltv.costs[1]) < 1e-2 * r_ltv.costs[1]  # a very wide one is the plain LTV


def test_mbrl_nn_arguments_are_validated(small_pretrained):
    model, cost, x0, _, lo, hi = benchmark_problem()
    with pytest.raises(DataError, match="pretrained"):
        mbrl(None, model, cost, x0, 10, model="ltv", pretrained=small_pretrained)
    with pytest.raises(DataError, match="nn_prior_cov"):
        mbrl(None, model, cost, x0, 10, model="ltv-nn", nn_prior_cov=0.0)
    with pytest.raises(DataError, match="pretrained: expected a NetworkPrior"):
        mbrl(None, model, cost, x0, 10, model="ltv-nn-pretrained", pretrained=np.eye(4))
    with pytest.raises(DataError, match="nn_first_steps"):
        mbrl(None, model, cost, x0, 10, model="ltv-nn", nn_first_steps=0)


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


def test_variant_stats_first_iterations_and_seed_counts():
    from drake_est.reproduce.mbrl import _variant_stats, first_within
    J = 100.0
    curves = np.array([[300, 200, 104, 101],      # within 5 % from iteration 3
                       [300, 150, 120, 103],      # from iteration 4
                       [300, 290, 280, 270]])     # never
    st = _variant_stats(curves, J, 105.0)
    assert st["seeds_within_5pct"] == 2 and st["n_seeds"] == 3
    assert st["median_over_seeds_first_iteration_within_5pct"] == 4.0   # median of (3, 4, never)
    assert st["first_iteration_median_within_5pct"] == first_within(np.median(curves, axis=0), 105.0) == 4
    np.testing.assert_allclose(st["median_ratio"], np.median(curves, axis=0) / J)
    st2 = _variant_stats(curves[[0, 2, 2]], J, 105.0)                     # most seeds never get there
    assert st2["median_over_seeds_first_iteration_within_5pct"] is None and st2["seeds_within_5pct"] == 1


@pytest.mark.slow
def test_reproduce_mbrl_cartpole_tiny_runs_all_variants(tmp_path):
    from drake_est.reproduce.mbrl import mbrl_cartpole
    r = mbrl_cartpole(tmp_path, n_seeds=1, iterations=5, jobs=1)
    assert set(r["variants"]) == {"ltv", "lti", "ltv-nn", "ltv-nn-pretrained"}
    assert all(len(v["median_cost"]) == 5 for v in r["variants"].values())
    assert (tmp_path / "mbrl_cartpole_fig11_1.png").stat().st_size > 10_000
    assert r["wall_seconds"] > 0 and r["nn_prior"]["pretraining"]["gradient_steps"] == 6000


def test_readme_mbrl_tables_are_printed_from_the_measured_json():
    """docs/readme/ilqr.md holds exactly the tables that `variants_markdown` makes of the kept JSON runs."""
    import json
    from pathlib import Path

    from drake_est.reproduce.mbrl import variants_markdown

    root = Path(__file__).resolve().parents[1]
    doc = (root / "docs" / "readme" / "ilqr.md").read_text()
    for name, label in (("mbrl-cartpole_seeds0-19.json", "seeds 0–19"),
                        ("mbrl-cartpole_seeds100-119.json", "seeds 100–119")):
        res = json.loads((root / "benchmarks" / "results" / "mbrl" / name).read_text())
        table = variants_markdown(res, label)
        assert table in doc, f"the README table for {name} is not what the JSON gives"
        assert res["acceptance_ltv_within_5pct_in_20_and_lti_not"] is True
