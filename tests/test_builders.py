"""Diagram builders (drake_est/systems/builders.py): plants, tracking controller, friction, compliance hook."""
import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.trajectories import PiecewisePolynomial

from drake_est.errors import DataError
from drake_est.systems.builders import (AddIrb140Plant, AddJointCompliance, AddJointFriction, AddStateLogger,
                                        AddTwoLinkArm, Irb140SimulationConfig, MakeIrb140Simulation,
                                        MakeTwoLinkArmPlant, PlantConfig, TrackingControllerConfig,
                                        spring_damper_torque)
from drake_est.systems.friction import FrictionModel


def test_irb140_plant_continuous_discrete_and_payload():
    cont = AddIrb140Plant(DiagramBuilder(), PlantConfig(time_step=0.0))
    disc = AddIrb140Plant(DiagramBuilder(), PlantConfig(time_step=1e-3))
    heavy = AddIrb140Plant(DiagramBuilder(), PlantConfig(payload=(5.0, [0.0, 0.0, 0.1])))
    assert cont.time_step() == 0.0 and disc.time_step() == pytest.approx(1e-3)
    assert cont.num_positions() == 6 and cont.num_actuators() == 6
    q = np.array([0.1, 0.3, -0.2, 0.0, 0.5, 0.0])

    def gravity(plant):
        ctx = plant.CreateDefaultContext()
        plant.SetPositions(ctx, q)
        return plant.CalcGravityGeneralizedForces(ctx)
    # the payload adds load on the shoulder/elbow: |gravity torque| grows on joint 2
    assert abs(gravity(heavy)[1]) > abs(gravity(cont)[1]) + 1.0


def test_tracking_config_gains_and_validation():
    c = TrackingControllerConfig.from_bandwidth(25.0, ki_ratio=0.5)
    kp, ki, kd = c.gains(3)
    assert np.all(kp == 625.0) and np.all(kd == 50.0) and np.all(ki == 312.5)
    with pytest.raises(DataError, match="kd"):
        TrackingControllerConfig(kd=-1.0).gains(2)
    with pytest.raises(DataError, match="kp"):
        TrackingControllerConfig(kp=np.nan).gains(2)


def test_make_irb140_simulation_tracks_and_logs_the_friction_model():
    ts = np.linspace(0.0, 2.0, 50)
    q = np.zeros((6, ts.size))
    qd = np.zeros((6, ts.size))
    q[0], qd[0] = 0.5 * np.sin(np.pi * ts), 0.5 * np.pi * np.cos(np.pi * ts)
    q[4] = 0.6
    traj = PiecewisePolynomial.CubicHermite(ts, q, qd)
    kc, kv = np.full(6, 3.0), np.full(6, 2.0)
    friction = FrictionModel.coulomb_viscous(kc, kv, sign_eps=1e-2)
    config = Irb140SimulationConfig(controller=TrackingControllerConfig(kp=400.0, kd=40.0, ki=200.0),
                                    log_period=0.01)
    diagram, h = MakeIrb140Simulation(config, traj, friction=friction)
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    h.plant.SetPositions(h.plant.GetMyMutableContextFromRoot(ctx), traj.value(0).ravel())
    sim.get_mutable_integrator().set_maximum_step_size(0.005)
    sim.AdvanceTo(2.0)
    lx = h.state_log.FindLog(ctx)
    t, X = lx.sample_times(), lx.data().T
    F = h.friction_log.FindLog(ctx).data().T
    keep = t > 0.5
    err = np.abs(X[keep, 0] - np.array([traj.value(ti)[0, 0] for ti in t[keep]]))
    assert err.max() < 0.01
    # the logged friction is the plain Coulomb + viscous law (smoothed sign) at the logged velocities
    v = X[keep, 6:]
    m = min(F[keep].shape[0], v.shape[0])
    np.testing.assert_allclose(F[keep][:m], (kv * v + kc * np.tanh(v / 1e-2))[:m], atol=1e-6)
    # without friction the builder wires the controller straight to the actuation
    diagram2, h2 = MakeIrb140Simulation(config, traj)
    assert h2.friction is None and h2.friction_log is None


def test_two_link_arm_mass_matrix_is_the_thin_rod_formula():
    plant, (j1, j2) = MakeTwoLinkArmPlant(1e-3)
    ctx = plant.CreateDefaultContext()
    m1, m2, l1, l2 = 2.0, 1.0, 0.5, 0.4
    for q2 in (0.0, 0.7, -1.9):
        plant.SetPositions(ctx, [0.3, q2])
        M = plant.CalcMassMatrix(ctx)
        c = np.cos(q2)
        M11 = m1 * l1 ** 2 / 3 + m2 * (l1 ** 2 + l2 ** 2 / 3 + l1 * l2 * c)
        M12 = m2 * (l2 ** 2 / 3 + l1 * l2 * c / 2)
        np.testing.assert_allclose(M, [[M11, M12], [M12, m2 * l2 ** 2 / 3]], rtol=1e-12, atol=1e-14)
    # gravity acts along the joint axes: no gravity torque anywhere
    assert np.allclose(plant.CalcGravityGeneralizedForces(ctx), 0.0)


def test_joint_compliance_hook_pulls_the_arm_to_rest():
    builder = DiagramBuilder()
    plant, _ = AddTwoLinkArm(1e-3)
    builder.AddSystem(plant)
    spring = AddJointCompliance(builder, plant, stiffness=[20.0, 10.0], damping=[2.0, 1.0], rest=[0.2, -0.1])
    fr = FrictionModel.coulomb_viscous(np.zeros(2), np.zeros(2))      # no friction: the spring acts alone
    AddJointFriction(builder, plant, fr, extra_torque_sources=[spring.get_joint_torques_output_port()])
    log = AddStateLogger(builder, plant, 0.05)
    diagram = builder.Build()
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    plant.SetPositions(plant.GetMyMutableContextFromRoot(ctx), [1.0, 0.8])
    sim.AdvanceTo(6.0)
    X = log.FindLog(ctx).data().T
    assert np.linalg.norm(X[-1, :2] - [0.2, -0.1]) < 0.05 < np.linalg.norm(X[0, :2] - [0.2, -0.1])
    np.testing.assert_allclose(spring_damper_torque([1.0, 0.0], [0.5, 0.0], [20.0, 10.0], [2.0, 1.0], 0.2),
                               [-20.0 * 0.8 - 1.0, 2.0])
    with pytest.raises(DataError, match="damping"):
        AddJointCompliance(DiagramBuilder(), plant, stiffness=[1.0, 2.0], damping=[1.0])


def test_joint_spring_damper_autodiff_gradient_is_minus_k_and_d():
    from pydrake.autodiffutils import ExtractGradient, InitializeAutoDiff

    from drake_est.systems.builders import JointSpringDamper
    ad = JointSpringDamper([10.0, 20.0], [1.0, 0.5], [0.1, -0.2]).ToAutoDiffXd()
    ctx = ad.CreateDefaultContext()
    ad.get_robot_state_input_port().FixValue(ctx, InitializeAutoDiff(np.array([0.3, -0.4, 0.5, 2.0])).ravel())
    grad = ExtractGradient(ad.get_joint_torques_output_port().Eval(ctx))
    np.testing.assert_array_equal(grad, [[-10.0, 0.0, -1.0, 0.0], [0.0, -20.0, 0.0, -0.5]])
