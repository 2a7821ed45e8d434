"""Neural dynamics models with Jacprop (thesis Ch. 8): gradients, Jacobians, training, Drake interop, errors."""
import warnings

import numpy as np
import pytest

from drake_est.errors import DataError
from drake_est.identification.nn import (NeuralDynamicsModel, forward, forward_jac, init_params, loss_and_grad,
                                         select_regularization)
from drake_est.identification.nn_tasks import (cartpole_step, eigenvalue_distance, jacobian_error,
                                               lowpass_noise, random_stable_system, simulate_cartpole,
                                               simulate_linear)


def _random_net(rng, sizes):
    return [(W, rng.normal(size=b.shape)) for W, b in init_params(sizes, rng, 1.0)]


@pytest.mark.parametrize("hidden", [(), (6,), (4, 3, 5)])
def test_loss_gradient_matches_finite_differences(hidden):
    """Exact gradient of prediction error + weight decay + Jacprop (8.9)-(8.10) vs central differences."""
    rng = np.random.default_rng(len(hidden))
    sizes = [5] + list(hidden) + [3]
    p = _random_net(rng, sizes)
    Z, Y, pw = rng.normal(size=(9, 5)), rng.normal(size=(9, 3)), rng.uniform(size=9)
    pairs = np.array([[0, 1], [1, 2], [3, 4], [4, 5], [7, 8], [2, 0]])
    N = rng.normal(size=(3, 5))
    cost, pc, jc, g = loss_and_grad(p, Z, Y, pw, pairs, jacprop=0.7, weight_decay=0.3, N=N)
    assert pc > 0 and (jc > 0 or not hidden)      # a linear network has a constant Jacobian
    h = 1e-6
    worst = 0.0
    for li in range(len(p)):
        for k in range(2):
            for j in np.ndindex(p[li][k].shape):
                def f(d):
                    q = [(W.copy(), b.copy()) for W, b in p]
                    q[li][k][j] += d
                    return loss_and_grad(q, Z, Y, pw, pairs, 0.7, 0.3, N, want_grad=False)[0]
                fd = (f(h) - f(-h)) / (2 * h)
                worst = max(worst, abs(fd - g[li][k][j]) / (1 + abs(fd)))
    assert worst < 1e-6


def test_jacprop_gradient_alone_is_nonzero_and_exact():
    """With only the Jacprop term the gradient must still match (guards the double-backprop path)."""
    rng = np.random.default_rng(7)
    p = _random_net(rng, [3, 4, 4, 2])
    Z = rng.normal(size=(4, 3))
    pairs = np.array([[0, 1], [1, 2], [2, 3]])
    _, pc, jc, g = loss_and_grad(p, Z, np.zeros((4, 2)), np.zeros(4), pairs, jacprop=1.0)
    assert pc == 0 and jc > 0
    W, b = p[0]
    fd = np.zeros_like(W)
    for j in np.ndindex(W.shape):
        for s in (1, -1):
            q = [(a.copy(), c.copy()) for a, c in p]
            q[0][0][j] += s * 1e-6
            fd[j] += s * loss_and_grad(q, Z, np.zeros((4, 2)), np.zeros(4), pairs, 1.0, want_grad=False)[0] / 2e-6
    assert np.abs(g[0][0]).max() > 1e-3
    np.testing.assert_allclose(g[0][0], fd, atol=1e-7)


def test_forward_jacobian_matches_finite_differences():
    rng = np.random.default_rng(2)
    p = _random_net(rng, [4, 7, 6, 3])
    Z = rng.normal(size=(5, 4))
    out, J = forward_jac(p, Z)
    np.testing.assert_allclose(out, forward(p, Z), atol=1e-14)
    E = np.eye(4)
    Jfd = np.stack([(forward(p, Z + 1e-6 * E[i]) - forward(p, Z - 1e-6 * E[i])) / 2e-6 for i in range(4)], -1)
    np.testing.assert_allclose(J, Jfd, atol=1e-8)


def _linear_data(seed=0, T=150, n=3, m=2):
    rng = np.random.default_rng(seed)
    A, B = random_stable_system(rng, n, m, dt=0.05)
    A, B = 0.9 * A, 0.3 * B           # well damped: validation stays inside the training range
    us = [lowpass_noise(rng, T, m, cutoff=0.3) for _ in range(3)]
    xs = [simulate_linear(A, B, u) for u in us]
    return A, B, xs, us


@pytest.mark.parametrize("form", ["f", "g", "nominal"])
def test_fit_learns_a_linear_system(form):
    A, B, xs, us = _linear_data()
    kw = dict(A0=0.9 * np.eye(3), B0=np.zeros((3, 2))) if form == "nominal" else {}
    model = NeuralDynamicsModel(hidden=(10,), form=form, epochs=300, learning_rate=1e-2, batch_size=64,
                                seed=0, progress_bar=False, **kw)
    model.fit(xs[:2], us[:2], xs[2], us[2])
    X, U = xs[2][:-1], us[2][:-1]
    base = np.mean(np.sum((xs[2][1:] - xs[2][:-1]) ** 2, axis=1))     # "x+ = x" predictor
    assert model.score(xs[2], us[2]) < 0.2 * base
    Am, Bm = model.linearize(X, U)
    assert Am.shape == (len(X), 3, 3) and Bm.shape == (len(X), 3, 2)
    assert np.median(np.abs(Am - A)) < 0.1
    assert model.history_["val_mse"] and model.best_epoch_ >= 1


def test_jacprop_makes_jacobians_smoother_along_trajectories():
    """Same data and seed: a strong Jacprop weight lowers the Jacobian variation sum_t ||J_{t+1} - J_t||."""
    rng = np.random.default_rng(4)
    xs, us = zip(*[simulate_cartpole(rng, T=80) for _ in range(2)])
    var = {}
    for jp in (0.0, 10.0):
        m = NeuralDynamicsModel(hidden=(16, 16), form="g", jacprop=jp, epochs=150, learning_rate=3e-3,
                                seed=1, progress_bar=False).fit(list(xs), list(us))
        J = m.jacobian(xs[0][:-1], us[0][:-1])
        var[jp] = np.sum(np.linalg.norm(np.diff(J, axis=0), axis=(1, 2)))
    assert var[10.0] < 0.5 * var[0.0]


def test_drake_multilayer_perceptron_roundtrip():
    A, B, xs, us = _linear_data(1, T=40)
    model = NeuralDynamicsModel(hidden=(6, 5), form="g", epochs=5, progress_bar=False).fit(xs, us)
    mlp, ctx = model.to_drake()
    Z = np.asfortranarray(np.hstack([xs[0], us[0]]).T)
    Y = mlp.BatchOutput(ctx, Z)
    np.testing.assert_allclose(Y.T + Z.T @ model.nominal_matrix.T, model.predict(xs[0], us[0]), atol=1e-12)
    back = NeuralDynamicsModel.from_drake(mlp, ctx, 3, form="g")
    np.testing.assert_allclose(back.jacobian(xs[0], us[0]), model.jacobian(xs[0], us[0]), atol=1e-14)


def test_inputs_may_have_one_row_less_than_states():
    """x_0..x_T with u_0..u_{T-1} (the LTV convention) trains exactly like u with an unused last row."""
    A, B, xs, us = _linear_data(8, T=30)
    kw = dict(hidden=(4,), epochs=3, progress_bar=False)
    a = NeuralDynamicsModel(**kw).fit(xs, [u[:-1] for u in us])
    b = NeuralDynamicsModel(**kw).fit(xs, [np.vstack([u[:-1], 99 * np.ones((1, 2))]) for u in us])
    for (Wa, ba), (Wb, bb) in zip(a.params_, b.params_):
        np.testing.assert_array_equal(Wa, Wb)
        np.testing.assert_array_equal(ba, bb)


def test_save_load_and_ltv_prior(tmp_path):
    A, B, xs, us = _linear_data(2, T=30)
    model = NeuralDynamicsModel(hidden=(4,), form="f", epochs=3, progress_bar=False).fit(xs, us)
    model.save(tmp_path / "m.json")
    back = NeuralDynamicsModel.load(tmp_path / "m.json")
    np.testing.assert_allclose(back.predict(xs[1], us[1]), model.predict(xs[1], us[1]), atol=0)
    k = model.ltv_prior_mean(xs[1], us[1])
    J = model.jacobian(xs[1], us[1])
    assert k.shape == (30, 5, 3)
    np.testing.assert_allclose(k, np.swapaxes(J, 1, 2))


def test_model_as_ltv_prior():
    """A tight prior from the learned model pins the LTV estimate to the model's Jacobians (Sec. 7.5)."""
    from drake_est.identification.ltv import ltv_smoother
    A, B, xs, us = _linear_data(6, T=40)
    model = NeuralDynamicsModel(hidden=(4,), form="g", epochs=3, progress_bar=False).fit(xs, us)
    x, u = xs[0], us[0][:-1]
    fit = ltv_smoother(x, u, lam=1.0, prior=model.ltv_prior(1e-8))
    J = model.jacobian(x[:-1], u)
    np.testing.assert_allclose(fit.A, J[:, :, :3], atol=1e-3)
    np.testing.assert_allclose(fit.B, J[:, :, 3:], atol=1e-3)
    with pytest.raises(DataError, match="cov"):
        model.ltv_prior(np.eye(2))


def test_bad_input_raises_one_line_data_error():
    rng = np.random.default_rng(0)
    x, u = rng.normal(size=(20, 2)), rng.normal(size=(20, 1))
    m = NeuralDynamicsModel(hidden=(3,), epochs=2, progress_bar=False)
    cases = [((x[:1], u[:1]), "at least 2"), ((x, u[:10]), "input samples"), ((x, np.vstack([u, u])), "expected 20 or 19"),
             (([x, x[:, :1]], [u, u]), "columns"), (([x], [u, u]), "input trajectories")]
    bad = x.copy()
    bad[5, 1] = np.nan
    cases.append(((bad, u), "sample 5, column 1"))
    for args, msg in cases:
        with pytest.raises(DataError, match=msg) as err:
            m.fit(*args)
        assert "\n" not in str(err.value)
    with pytest.raises(DataError, match="x_val"):
        m.fit(x, u, x_val=rng.normal(size=(5, 3)), u_val=u[:5])
    with pytest.raises(DataError, match="not fitted"):
        NeuralDynamicsModel().predict(x, u)
    with pytest.raises(DataError, match="form"):
        NeuralDynamicsModel(form="h")
    m.fit(x, u)
    with pytest.raises(DataError, match="columns"):
        m.predict(x[:, :1], u)


def test_divergence_stops_and_keeps_last_good_parameters():
    rng = np.random.default_rng(0)
    x = np.cumsum(rng.normal(size=(60, 2)), axis=0)
    m = NeuralDynamicsModel(hidden=(4,), form="f", epochs=20, learning_rate=1e300, progress_bar=False)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        m.fit(x, None)
    assert m.diverged_ and "diverged" in m.diverged_
    assert any("diverged" in str(w.message) for w in rec)
    assert all(np.all(np.isfinite(W)) for W, _ in m.params_)
    assert np.all(np.isfinite(m.predict(x, None)))


def test_select_regularization_picks_lowest_validation_error():
    A, B, xs, us = _linear_data(3, T=60)
    best, scores = select_regularization(xs[:2], us[:2], xs[2], us[2], param="weight_decay",
                                         values=(0.0, 10.0), hidden=(6,), epochs=40, learning_rate=1e-2,
                                         progress_bar=False)
    assert set(scores) == {0.0, 10.0}
    assert best.weight_decay == min(scores, key=scores.get)
    assert best.score(xs[2], us[2]) == pytest.approx(min(scores.values()))


def test_task_helpers():
    x, u = np.array([0.3, 0.2, 0.1, -0.4]), np.array([0.7])
    _, J = cartpole_step(x, u, jacobian=True)
    E = np.eye(4)
    Jfd = np.stack([(cartpole_step(x + 1e-6 * e, u) - cartpole_step(x - 1e-6 * e, u)) / 2e-6 for e in E]
                   + [(cartpole_step(x, u + 1e-6) - cartpole_step(x, u - 1e-6)) / 2e-6], -1)
    np.testing.assert_allclose(J, Jfd, atol=1e-8)
    A, _ = random_stable_system(np.random.default_rng(0), 10, 10)
    assert np.abs(np.linalg.eigvals(A)).max() < 1
    assert eigenvalue_distance(A, np.stack([A, A])) < 1e-10
    assert eigenvalue_distance(A, 0.5 * A) > 1
    assert jacobian_error(np.zeros((2, 2, 2)), np.ones((2, 2, 2))) == pytest.approx(2.0)


def test_neural_dynamics_system_matches_model_simulation():
    from pydrake.systems.analysis import Simulator
    from drake_est.systems.dynamics import NeuralDynamics, linearize_trajectory
    A, B, xs, us = _linear_data(5, T=40)
    model = NeuralDynamicsModel(hidden=(5,), form="g", epochs=5, progress_bar=False).fit(xs, us)
    u = np.array([0.2, -0.3])
    sys = NeuralDynamics(model, time_step=0.1, initial_state=xs[0][0])
    ctx = sys.CreateDefaultContext()
    sys.get_control_input_port().FixValue(ctx, u)
    Simulator(sys, ctx).AdvanceTo(0.95)               # updates at 0, 0.1, ..., 0.9
    ref = model.simulate(xs[0][0], np.tile(u, (10, 1)))[-1]
    np.testing.assert_allclose(sys.get_state_output_port().Eval(ctx), ref, atol=1e-12)
    At, Bt = linearize_trajectory(sys, xs[0], us[0])
    J = model.jacobian(xs[0], us[0])
    np.testing.assert_allclose(At, J[:, :, :3])
    np.testing.assert_allclose(Bt, J[:, :, 3:])
    with pytest.raises(DataError, match="time_step"):
        NeuralDynamics(model, 0.0)


def test_neural_dynamics_autodiff_linearize_equals_model_jacobian():
    """The AutoDiffXd version (TemplateSystem) lets Drake's Linearize differentiate the learned model."""
    from pydrake.systems.primitives import Linearize
    from drake_est.systems.dynamics import NeuralDynamics, contract_cases
    A, B, xs, us = _linear_data(7, T=30)
    model = NeuralDynamicsModel(hidden=(5, 4), form="nominal", A0=0.5 * np.eye(3), B0=np.ones((3, 2)),
                                epochs=3, progress_bar=False).fit(xs, us)
    sys = NeuralDynamics(model, time_step=0.05)
    ctx = sys.CreateDefaultContext()
    x, u = xs[0][4], us[0][4]
    ctx.SetDiscreteState(x)
    sys.get_control_input_port().FixValue(ctx, u)
    lin = Linearize(sys, ctx, equilibrium_check_tolerance=1e12)
    J = model.jacobian(x, u)
    np.testing.assert_allclose(lin.A(), J[:, :3], atol=1e-12)
    np.testing.assert_allclose(lin.B(), J[:, 3:], atol=1e-12)
    case = contract_cases()[0]
    assert "[model units]" in case.make().__doc__
