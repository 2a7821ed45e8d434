import numpy as np
import pytest

from drake_est.robots import RobotModel, add_irb140, irb140, irb140_metadata, jacobian, forward_kinematics

DEG = np.pi / 180
# Standard DH of the IRB 140 (shared/irb140_facts.md): theta offset, d, a, alpha
DH = [(0, 0.352, 0.070, -90 * DEG), (-90 * DEG, 0, 0.360, 0), (0, 0, 0, -90 * DEG),
      (0, 0.380, 0, 90 * DEG), (0, 0, 0, -90 * DEG), (180 * DEG, 0.065, 0, 0)]


def dh_fk(q):
    """Independent DH forward kinematics written out here (not the library's helper)."""
    T = np.eye(4)
    for (off, d, a, al), qi in zip(DH, q):
        th = qi + off
        ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(al), np.sin(al)
        T = T @ np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d],
                          [0, 0, 0, 1]])
    return T


CONFIGS = [np.zeros(6), np.array([0.4, -0.3, 0.6, 1.1, -0.8, 2.3]), np.array([-1.2, 0.5, -1.0, -2.0, 1.3, -0.7])]


@pytest.mark.parametrize("q", CONFIGS)
def test_flange_pose_matches_dh(q):
    X = forward_kinematics(q).GetAsMatrix4()
    T = dh_fk(q)
    np.testing.assert_allclose(X[:3, 3], T[:3, 3], atol=1e-9)
    # orientation: DH frame 6 and ABB tool0 differ by a constant rotation, fixed at q = 0
    R_off = dh_fk(np.zeros(6))[:3, :3].T @ forward_kinematics(np.zeros(6)).rotation().matrix()
    np.testing.assert_allclose(X[:3, :3], T[:3, :3] @ R_off, atol=1e-9)


def test_zero_configuration_flange_position():
    # upper arm vertical, forearm horizontal: flange at 0.07 + 0.38 + 0.065 forward, 0.352 + 0.36 up
    np.testing.assert_allclose(forward_kinematics(np.zeros(6)).translation(), [0.515, 0.0, 0.712], atol=1e-12)


def test_jacobian_matches_finite_differences():
    q = CONFIGS[1]
    J = jacobian(q)
    eps = 1e-6
    for i in range(6):
        dq = np.zeros(6)
        dq[i] = eps
        dp = (forward_kinematics(q + dq).translation() - forward_kinematics(q - dq).translation()) / (2 * eps)
        np.testing.assert_allclose(J[3:, i], dp, atol=1e-6)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_inverse_dynamics_consistent_with_forward_dynamics(seed):
    rng = np.random.default_rng(seed)
    robot = irb140()
    q, qd, qdd = rng.uniform(-1, 1, 6), rng.uniform(-2, 2, 6), rng.uniform(-5, 5, 6)
    tau = robot.inverse_dynamics(q, qd, qdd)
    # forward dynamics from Drake's own plant time derivatives
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import ConstantVectorSource

    builder, plant, _, _ = add_irb140(DiagramBuilder())
    src = builder.AddSystem(ConstantVectorSource(tau))
    builder.Connect(src.get_output_port(), plant.get_actuation_input_port())
    diagram = builder.Build()
    ctx = diagram.CreateDefaultContext()
    pctx = plant.GetMyMutableContextFromRoot(ctx)
    plant.SetPositions(pctx, q)
    plant.SetVelocities(pctx, qd)
    vdot = plant.EvalTimeDerivatives(pctx).CopyToVector()[6:]
    np.testing.assert_allclose(vdot, qdd, atol=1e-8)


def test_gravity_torques_hold_the_robot():
    robot = irb140()
    q = CONFIGS[2]
    np.testing.assert_allclose(robot.forward_dynamics(q, np.zeros(6), robot.gravity_torques(q)), np.zeros(6), atol=1e-9)


def test_metadata_coupling_is_lower_triangular_wrist():
    meta = irb140_metadata()
    N = meta.motor_from_arm
    assert np.allclose(N, np.tril(N))
    assert N[4, 3] != 0 and N[5, 3] != 0 and N[5, 4] != 0
    assert np.allclose(np.diag(N), meta.gear_ratios)
    np.testing.assert_allclose(meta.arm_from_motor @ N, np.eye(6), atol=1e-12)
    assert meta.position_limits.shape == (6, 2)


def test_payload_changes_gravity_torque():
    q = np.array([0.0, 0.3, -0.2, 0.0, 0.4, 0.0])
    base = irb140().gravity_torques(q)
    loaded = RobotModel.irb140(payload=(2.0, [0, 0, 0.05])).gravity_torques(q)
    assert abs(loaded[1] - base[1]) > 5.0  # 2 kg at ~0.6 m lever: > 10 N m at joint 2
