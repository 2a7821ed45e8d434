"""Gaussian estimator LeafSystems (systems/estimators.py): in a Simulator they reproduce the plain filters."""
import numpy as np
import pytest

from drake_est.estimation import ExtendedKalmanFilter, KalmanFilter, UnscentedKalmanFilter


def _data(seed=3, T=15):
    rng = np.random.default_rng(seed)
    A = np.array([[0.9, 0.2], [-0.1, 0.8]])
    B = np.array([[0.0], [1.0]])
    C = np.array([[1.0, 0.5]])
    R1, R2 = np.diag([0.05, 0.02]), np.array([[0.3]])
    x0, P0 = np.array([0.5, -0.2]), np.diag([1.0, 2.0])
    u = rng.standard_normal((T, 1))
    y = rng.standard_normal((T, 1))
    y[4] = np.nan                                         # a missing measurement: predict only
    return A, B, C, R1, R2, x0, P0, u, y


def _run(sys, u, y, h):
    from pydrake.systems.analysis import Simulator

    sim = Simulator(sys)
    ctx = sim.get_mutable_context()
    xs, Ps = [], []
    for t in range(y.shape[0]):
        sys.get_control_input_port().FixValue(ctx, u[t])
        sys.get_measurement_input_port().FixValue(ctx, y[t])
        xs.append(sys.get_estimate_output_port().Eval(ctx).copy())
        Ps.append(sys.get_covariance_output_port().Eval(ctx).reshape(2, 2).copy())
        sim.AdvanceTo((t + 0.5) * h)
    return np.array(xs), np.array(Ps), sys.get_log_likelihood_output_port().Eval(ctx)[0]


def _fh(A, B, C):
    return (lambda x, u, t: x @ A.T + u @ B.T), (lambda x, u, t: np.tanh(x @ C.T))


@pytest.mark.parametrize("kind", ["kf", "ekf", "ukf"])
def test_system_equals_plain_filter(kind):
    from drake_est.systems.estimators import (ExtendedKalmanFilterSystem, KalmanFilterSystem,
                                              UnscentedKalmanFilterSystem)

    A, B, C, R1, R2, x0, P0, u, y = _data()
    h = 0.1
    f, hm = _fh(A, B, C)
    if kind == "kf":
        sys = KalmanFilterSystem(A, B, C, R1, R2, x0, P0, period=h)
        plain = KalmanFilter(A, C, R1, R2, x0, P0, B=B)
    elif kind == "ekf":
        sys = ExtendedKalmanFilterSystem(f, hm, R1, R2, x0, P0, period=h, nu=1)
        plain = ExtendedKalmanFilter(f, hm, R1, R2, x0, P0, nu=1)
    else:
        sys = UnscentedKalmanFilterSystem(f, hm, R1, R2, x0, P0, period=h, nu=1)
        plain = UnscentedKalmanFilter(f, hm, R1, R2, x0, P0, nu=1)
    fr = plain.forward_trajectory(u, y)
    xs, Ps, ll = _run(sys, u, y, h)
    np.testing.assert_allclose(xs, fr.x_filt, atol=1e-12)
    np.testing.assert_allclose(Ps, fr.P_filt, atol=1e-12)
    # the state's log-likelihood holds steps 0..T-1 after the update at t = (T-1) h
    assert ll == pytest.approx(fr.loglik, abs=1e-9)
    assert fr.n_missing == 1


def test_from_drake_system_in_one_line():
    from pydrake.systems.primitives import LinearSystem

    from drake_est.systems.estimators import ExtendedKalmanFilterSystem, UnscentedKalmanFilterSystem

    A, B, C, R1, R2, x0, P0, u, y = _data(seed=4)
    model = LinearSystem(A, B, np.eye(2), np.zeros((2, 1)), 0.1)
    ref = KalmanFilter(A, C, R1, R2, x0, P0, B=B).forward_trajectory(u, y)
    for cls in (ExtendedKalmanFilterSystem, UnscentedKalmanFilterSystem):
        sys = cls.from_system(model, R1, R2, x0, P0, measurement=C)
        xs, Ps, ll = _run(sys, u, y, 0.1)
        np.testing.assert_allclose(xs, ref.x_filt, atol=1e-10)
        assert ll == pytest.approx(ref.loglik, abs=1e-9)


def test_old_kalman_system_path_and_contract_cases():
    from pydrake.systems.analysis import Simulator

    from drake_est.estimation.kalman_system import KalmanFilterSystem as Old
    from drake_est.systems import estimators

    assert Old is estimators.KalmanFilterSystem
    cases = estimators.contract_cases()
    assert {c.label for c in cases} == {"KalmanFilterSystem", "ExtendedKalmanFilterSystem",
                                        "UnscentedKalmanFilterSystem"}
    for case in cases:
        outs = []
        for _ in range(2):
            sys = case.make()
            sim = Simulator(sys)
            ctx = sim.get_mutable_context()
            for name, val in case.inputs.items():
                sys.GetInputPort(name).FixValue(ctx, val)
            sim.AdvanceTo(case.t_final)
            got = {n: sys.GetOutputPort(n).Eval(ctx).copy() for n in ("estimate", "covariance", "log_likelihood")}
            for name, val in case.expected_outputs(sys).items():
                np.testing.assert_allclose(got[name], val, rtol=case.rtol, atol=case.atol, err_msg=case.label)
            outs.append(got)
        for n in outs[0]:
            np.testing.assert_array_equal(outs[0][n], outs[1][n])
        for i in range(sys.num_output_ports()):
            name = sys.get_output_port(i).get_name()
            assert name == name.lower() and f"``{name}``" in type(sys).__doc__
