"""ParticleFilterEstimator (LeafSystem) against the plain ParticleFilter."""
import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LinearSystem, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from drake_est.errors import DataError
from drake_est.estimation import ParticleFilter
from drake_est.systems.particle_filter import ParticleFilterEstimator, _contract_filter, contract_cases

DT = 0.01


def _simulate(est, u, y):
    """Feed u, y (T rows) as zero-order holds; return the estimate, covariance and log-likelihood at each
    update time t_k (before the update at t_k runs: the estimate is x_{k|k})."""
    T = y.shape[0]
    b = DiagramBuilder()
    sysm = b.AddSystem(est)
    times = DT * np.arange(T + 1)
    ys = TrajectorySource(PiecewisePolynomial.ZeroOrderHold(times, np.vstack([y, y[-1:]]).T))
    b.Connect(b.AddSystem(ys).get_output_port(), sysm.get_measurement_input_port())
    if u is not None:
        us = TrajectorySource(PiecewisePolynomial.ZeroOrderHold(times, np.vstack([u, u[-1:]]).T))
        b.Connect(b.AddSystem(us).get_output_port(), sysm.get_control_input_port())
    d = b.Build()
    sim = Simulator(d)
    ctx = sysm.GetMyContextFromRoot(sim.get_mutable_context())
    xs, Ps = [], []
    for k in range(T):
        if k:   # (Simulator.Initialize runs the update at t = 0, so x_{0|0} is read before it)
            sim.AdvanceTo(k * DT)             # the update at t_k runs at the start of the next step
        xs.append(sysm.get_estimate_output_port().Eval(ctx).copy())
        Ps.append(sysm.get_covariance_output_port().Eval(ctx).copy())
    sim.AdvanceTo(T * DT)
    ll = sysm.get_log_likelihood_output_port().Eval(ctx)[0]
    parts = sysm.get_particles_output_port().Eval(ctx)
    return np.array(xs), np.array(Ps), ll, parts


def _data(T=40, seed=0):
    rng = np.random.default_rng(seed)
    f, h, R1, R2, x0, P0 = _contract_filter()
    u = np.sin(0.3 * np.arange(T))[:, None]
    x = x0.copy()
    ys = []
    for t in range(T):
        ys.append(h(x, u[t], t) + 0.1 * rng.standard_normal(1))
        x = f(x, u[t], t) + 0.01 * rng.standard_normal(2)
    return u, np.array(ys)


def test_simulator_equals_plain_filter():
    f, h, R1, R2, x0, P0 = _contract_filter()
    u, y = _data()
    y[7] = np.nan                                        # a missing measurement: predict only
    est = ParticleFilterEstimator.gaussian(f, h, R1, R2, x0, P0, period=DT, n_particles=200, seed=5, nu=1)
    xs, Ps, ll, parts = _simulate(est, u, y)
    r = est.filter.forward_trajectory(u, y)
    np.testing.assert_allclose(xs, r.x_filt, atol=1e-9)
    np.testing.assert_allclose(Ps, r.P_filt.reshape(len(y), -1), atol=1e-9)
    assert abs(ll - r.loglik) < 1e-8
    assert r.n_missing == 1 and r.extras["n_resampled"] > 0
    # particles of the state = the filter's particle cloud after the last prediction
    assert parts.shape == (200 * 2,)
    cloud = parts.reshape(200, 2)      # (weights are not an output: only a consistency check)
    assert np.all(np.abs(cloud.mean(0) - r.x_pred[-1]) < 2 * cloud.std(0))


def test_two_contexts_independent():
    f, h, R1, R2, x0, P0 = _contract_filter()
    est = ParticleFilterEstimator.gaussian(f, h, R1, R2, x0, P0, period=DT, n_particles=50, seed=1, nu=1)
    c1, c2 = est.CreateDefaultContext(), est.CreateDefaultContext()
    for c, yv in ((c1, 0.1), (c2, -0.3)):
        est.get_measurement_input_port().FixValue(c, [yv])
        est.get_control_input_port().FixValue(c, [0.2])
    for _ in range(3):   # interleaved updates
        for c in (c1, c2):
            c.SetDiscreteState(est.EvalUniquePeriodicDiscreteUpdate(c).get_vector().CopyToVector())
    e1 = est.get_estimate_output_port().Eval(c1)
    r1 = est.filter.forward_trajectory(np.full((4, 1), 0.2), np.full((4, 1), 0.1))
    np.testing.assert_allclose(e1, r1.x_filt[3], atol=1e-10)


def test_from_linear_system_matches_callables():
    A = np.array([[1.0, 0.01], [-0.05, 0.99]])
    B = np.array([[0.0], [0.01]])
    lin = LinearSystem(A, B, np.eye(2), np.zeros((2, 1)), DT)
    f, h, R1, R2, x0, P0 = _contract_filter()
    est = ParticleFilterEstimator.from_system(lin, np.array([[1.0, 0.0]]), R1, R2, x0, P0, n_particles=40, seed=2)
    ref = ParticleFilter.gaussian(f, h, R1, R2, x0, P0, n_particles=40, seed=2, nu=1)
    u, y = _data(T=15)
    np.testing.assert_allclose(est.filter.forward_trajectory(u, y).x_filt, ref.forward_trajectory(u, y).x_filt,
                               atol=1e-10)


def test_from_multibody_plant_runs_in_simulator():
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant

    urdf = """<robot name="p"><link name="base"/><link name="arm"><inertial><origin xyz="0 0 -0.5"/>
      <mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
      <joint name="j" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 1 0"/></joint>
      <transmission type="SimpleTransmission" name="t"><actuator name="a"/><joint name="j"/></transmission>
      </robot>"""
    plant = MultibodyPlant(DT)
    Parser(plant).AddModelsFromString(urdf, "urdf")
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base"))
    plant.Finalize()
    est = ParticleFilterEstimator.from_system(plant, np.array([[1.0, 0.0]]), 1e-5 * np.eye(2),
                                              np.array([[1e-3]]), [0.3, 0.0], 0.01 * np.eye(2),
                                              n_particles=30, seed=0)
    T = 8
    y = 0.3 * np.ones((T, 1))
    u = np.zeros((T, 1))
    xs, _, ll, _ = _simulate(est, u, y)
    r = est.filter.forward_trajectory(u, y)
    np.testing.assert_allclose(xs, r.x_filt, atol=1e-9)
    assert np.all(np.isfinite(xs)) and abs(xs[-1, 0] - 0.3) < 0.1


def test_contract_case_and_errors():
    case = contract_cases()[0]
    sysm = case.make()
    ctx = sysm.CreateDefaultContext()
    for name, v in case.inputs.items():
        sysm.GetInputPort(name).FixValue(ctx, v)
    sim = Simulator(sysm, ctx)
    sim.AdvanceTo(case.t_final)
    for name, v in case.expected_outputs(sysm).items():
        np.testing.assert_allclose(sysm.GetOutputPort(name).Eval(ctx), v, rtol=case.rtol, atol=case.atol)
    doc = type(sysm).__doc__
    for i in range(sysm.num_output_ports()):
        assert f"``{sysm.get_output_port(i).get_name()}``" in doc
    f, h, R1, R2, x0, P0 = _contract_filter()
    with pytest.raises(DataError, match="period"):
        ParticleFilterEstimator.gaussian(f, h, R1, R2, x0, P0, period=0.0)
    with pytest.raises(DataError, match="n_particles"):
        ParticleFilterEstimator.gaussian(f, h, R1, R2, x0, P0, period=0.1, n_particles=1)
