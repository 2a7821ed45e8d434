"""FrictionModel LeafSystem: ports, numbers, energy state, and use inside a MultibodyPlant diagram."""
import numpy as np
import pytest
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import RevoluteJoint, SpatialInertia, UnitInertia
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from drake_est.errors import DrakeEstError
from drake_est.identification.friction import EnergyDynamics, JointFriction, build_model
from drake_est.systems.friction import FrictionModel, add_friction


def test_ports_and_coulomb_viscous_numbers():
    fm = FrictionModel.coulomb_viscous(kc=[5.0, 2.0], kv=[2.0, 0.5])
    assert fm.get_input_port(0).get_name() == "joint_positions"
    assert fm.get_input_port(1).get_name() == "joint_velocities"
    assert fm.get_output_port(0).get_name() == "friction_torques"
    ctx = fm.CreateDefaultContext()
    fm.get_input_port(0).FixValue(ctx, [0.1, 0.2])
    fm.get_input_port(1).FixValue(ctx, [0.5, -1.0])
    F = fm.get_output_port(0).Eval(ctx)
    np.testing.assert_allclose(F, [5.0 + 2.0 * 0.5, -2.0 - 0.5], rtol=1e-12)


def test_direction_dependent_coulomb():
    fm = FrictionModel.coulomb_viscous(kc=[3.0], kv=[1.0], kc_minus=[4.0])
    np.testing.assert_allclose(fm.friction([0.0], [0.2]), [3.0 + 0.2])
    np.testing.assert_allclose(fm.friction([0.0], [-0.2]), [-4.0 - 0.2])
    np.testing.assert_allclose(fm.friction([0.0], [0.0]), [0.0])


def test_identified_model_matches_predict_and_roundtrips_json(tmp_path):
    rng = np.random.default_rng(0)
    q = rng.uniform(-2, 2, 3000)
    v = rng.choice([-1, 1], 3000) * rng.uniform(0.1, 1.0, 3000)
    y = 4 * np.sign(v) + 1.5 * v + 0.8 * np.sign(v) * np.exp(-((q - 0.5) / 0.3) ** 2) + 0.05 * rng.standard_normal(3000)
    m = build_model("position", q, v, n_position=16, lam=1e-3).fit(q, v, y)
    fm = FrictionModel([m])
    for k in range(5):
        np.testing.assert_allclose(fm.friction([q[k]], [v[k]]), m.predict(q[k:k + 1], v[k:k + 1]), rtol=1e-12)
    import json
    path = tmp_path / "params.json"
    path.write_text(json.dumps({"model": m.to_dict()}))
    fm2 = FrictionModel.from_json(path)
    np.testing.assert_allclose(fm2.friction([0.4], [-0.3]), fm.friction([0.4], [-0.3]), rtol=1e-12)


def test_energy_state_follows_friction_power():
    m = JointFriction.coulomb_viscous(kc=10.0, kv=2.0)
    m.energy = EnergyDynamics(gain=-0.2, time_constant=5.0, h=0.1)
    fm = FrictionModel([m])
    ctx = fm.CreateDefaultContext()
    fm.get_input_port(0).FixValue(ctx, [0.0])
    fm.get_input_port(1).FixValue(ctx, [1.0])
    sim = Simulator(fm, ctx)
    sim.AdvanceTo(30.0)
    E = ctx.get_discrete_state(0).CopyToVector()[0]
    # stationary point of E = k_e |F v| with F = 10 + 2 + E:  E = -0.2 (12 + E)  ->  E = -2.4 / 1.2
    assert E == pytest.approx(-2.0, rel=0.02)
    F = fm.get_output_port(0).Eval(ctx)[0]
    assert F == pytest.approx(12.0 + E, rel=1e-9)


def _disk_plant(builder, inertia=0.5):
    plant = MultibodyPlant(0.0)
    builder.AddSystem(plant)
    body = plant.AddRigidBody("disk", SpatialInertia(1.0, np.zeros(3), UnitInertia(inertia, inertia, inertia)))
    joint = plant.AddJoint(RevoluteJoint("spin", plant.world_frame(), body.body_frame(), [0, 0, 1]))
    plant.AddJointActuator("motor", joint)
    plant.mutable_gravity_field().set_gravity_vector([0, 0, 0])
    plant.Finalize()
    return plant


def test_friction_decelerates_a_disk_like_the_ode():
    """I dw/dt = -(kv w + kc) while w > 0: w(t) = (w0 + kc/kv) exp(-kv t / I) - kc/kv."""
    I, kc, kv, w0 = 0.5, 0.4, 0.3, 3.0
    builder = DiagramBuilder()
    plant = _disk_plant(builder, I)
    fm = FrictionModel.coulomb_viscous([kc], [kv])
    add_friction(builder, plant, fm)
    diagram = builder.Build()
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    plant.SetVelocities(plant.GetMyMutableContextFromRoot(ctx), [w0])
    sim.get_mutable_integrator().set_target_accuracy(1e-8)
    T = 1.0
    sim.AdvanceTo(T)
    w = plant.GetVelocities(plant.GetMyContextFromRoot(ctx))[0]
    expect = (w0 + kc / kv) * np.exp(-kv * T / I) - kc / kv
    assert w == pytest.approx(expect, rel=1e-4)


def test_irb140_diagram_with_identified_friction():
    robots = pytest.importorskip("drake_est.robots")
    builder, plant, _, _ = robots.add_irb140(DiagramBuilder(), time_step=1e-3)
    meta = robots.irb140_metadata()
    fm = FrictionModel.coulomb_viscous(meta.coulomb, meta.viscous, sign_eps=1e-2)
    add_friction(builder, plant, fm)
    diagram = builder.Build()
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    pc = plant.GetMyMutableContextFromRoot(ctx)
    v0 = np.zeros(6)
    v0[0] = 1.0
    plant.SetVelocities(pc, v0)
    sim.AdvanceTo(0.3)
    v = plant.GetVelocities(plant.GetMyContextFromRoot(ctx))
    # joint 1 (vertical axis) is braked by its friction: 0 < v1 < 1
    assert 0.0 <= v[0] < 0.95
    F = fm.get_output_port(0).Eval(fm.GetMyContextFromRoot(ctx))
    assert F.shape == (6,)


def test_bad_inputs():
    with pytest.raises(DrakeEstError):
        FrictionModel.coulomb_viscous([1.0, 2.0], [1.0])
    m = build_model("nominal", np.zeros(5), np.ones(5))
    with pytest.raises(DrakeEstError, match="not fitted"):
        FrictionModel([m])


def test_add_friction_is_the_builder_set():
    """add_friction wraps builders.AddJointFriction: Gain without a source, Adder(source, -F) with one."""
    from pydrake.systems.primitives import Adder, ConstantVectorSource, Gain
    builder = DiagramBuilder()
    plant = _disk_plant(builder)
    out = add_friction(builder, plant, FrictionModel.coulomb_viscous([0.4], [0.3]))
    assert isinstance(out, Gain)
    builder = DiagramBuilder()
    plant = _disk_plant(builder)
    src = builder.AddSystem(ConstantVectorSource([1.5]))
    fm = FrictionModel.coulomb_viscous([0.4], [0.3])
    out = add_friction(builder, plant, fm, actuation_source=src.get_output_port())
    assert isinstance(out, Adder)
    diagram = builder.Build()
    ctx = diagram.CreateDefaultContext()
    plant.SetVelocities(plant.GetMyMutableContextFromRoot(ctx), [2.0])
    u = out.get_output_port().Eval(out.GetMyContextFromRoot(ctx))
    assert u[0] == pytest.approx(1.5 - (0.4 + 0.3 * 2.0), rel=1e-12)
    with pytest.raises(DrakeEstError, match="positions"):
        add_friction(DiagramBuilder(), plant, FrictionModel.coulomb_viscous([1.0, 1.0], [1.0, 1.0]))


def _ad_gradient(system, q, v):
    from pydrake.autodiffutils import ExtractGradient, ExtractValue, InitializeAutoDiff
    ad = system.ToAutoDiffXd()
    ctx = ad.CreateDefaultContext()
    x = InitializeAutoDiff(np.concatenate([q, v])).ravel()
    ad.get_input_port(0).FixValue(ctx, x[:q.size])
    ad.get_input_port(1).FixValue(ctx, x[q.size:])
    F = ad.get_output_port(0).Eval(ctx)
    return ExtractValue(F).ravel(), ExtractGradient(F)


def _fd_gradient(fm, q, v, h=1e-6):
    n = q.size
    cols = []
    for i in range(2 * n):
        e = np.zeros(2 * n)
        e[i] = h
        cols.append((fm.friction(q + e[:n], v + e[n:]) - fm.friction(q - e[:n], v - e[n:])) / (2 * h))
    return np.column_stack(cols)


def test_autodiff_gradient_equals_finite_difference():
    """FrictionModel.ToAutoDiffXd(): dF/d(q, v) of Coulomb + viscous (9.2), direction-dependent (9.3),
    gravity-in-position and a position expansion equals central differences of the float model."""
    from drake_est.identification.friction.terms import BFETerm, Coulomb, Gravity, Viscous
    rng = np.random.default_rng(3)
    Q, DQ = rng.uniform(-1, 1, (400, 3)), rng.uniform(-1, 1, (400, 3))
    m0 = JointFriction.coulomb_viscous(2.0, 0.8, index=0, kc_minus=1.5)
    m1 = JointFriction([Coulomb(), Viscous(), Gravity()], index=1, lam=0.0)
    m1.fit(Q, DQ, 1.0 * np.sign(DQ[:, 1]) + 0.5 * DQ[:, 1] + 0.3 * np.sin(Q[:, 1]))
    m2 = JointFriction([Coulomb(), Viscous(), BFETerm.from_data(["q"], Q, DQ, 2, 5)], index=2, lam=1e-3)
    m2.fit(Q, DQ, np.sign(DQ[:, 2]) + 0.2 * np.cos(3 * Q[:, 2]))
    fm = FrictionModel([m0, m1, m2], sign_eps=0.05)
    q, v = np.array([0.3, -0.4, 0.2]), np.array([0.02, -0.03, 0.1])
    F, G = _ad_gradient(fm, q, v)
    np.testing.assert_allclose(F, fm.friction(q, v), rtol=1e-12, atol=1e-12)
    fd = _fd_gradient(fm, q, v)
    np.testing.assert_allclose(G, fd, rtol=1e-6, atol=1e-6)
    assert G[0, 3] > 10.0 and G[1, 1] != 0.0 and G[2, 2] != 0.0   # tanh slope, gravity, expansion
    # joint 1 goes the other way: the kc- branch of (9.3)
    v2 = np.array([-0.02, -0.03, 0.1])
    np.testing.assert_allclose(_ad_gradient(fm, q, v2)[1], _fd_gradient(fm, q, v2), rtol=1e-6, atol=1e-6)


def test_autodiff_energy_model_and_plant_diagram():
    """An energy model keeps its discrete state under AutoDiffXd; a plant + friction diagram converts."""
    from pydrake.autodiffutils import AutoDiffXd
    m = JointFriction.coulomb_viscous(2.0, 0.8, index=0)
    m.energy = EnergyDynamics(gain=0.05, time_constant=0.5, h=0.01, E0=0.3)
    fm = FrictionModel([m], sign_eps=0.1)
    q, v = np.array([0.1]), np.array([0.05])
    F, G = _ad_gradient(fm, q, v)
    np.testing.assert_allclose(F, fm.friction(q, v, E=[0.3]), rtol=1e-12)
    E = np.array([0.3])
    fd = (fm.friction(q, v + 1e-6, E) - fm.friction(q, v - 1e-6, E)) / 2e-6
    assert G[0, 1] == pytest.approx(fd[0], rel=1e-6)
    # the ZOH energy update E <- a E + k_e (1 - a) |F v| runs on AutoDiffXd and matches the float one
    E_next = []
    for s, x in ((fm, [0.1, 0.5]), (fm.ToAutoDiffXd(), [AutoDiffXd(0.1), AutoDiffXd(0.5, [1.0])])):
        c = s.CreateDefaultContext()
        s.get_input_port(0).FixValue(c, np.array(x[:1], dtype=type(x[0])))
        s.get_input_port(1).FixValue(c, np.array(x[1:], dtype=type(x[0])))
        E_next.append(s.EvalUniquePeriodicDiscreteUpdate(c).get_vector(0).CopyToVector()[0])
    assert E_next[1].value() == pytest.approx(E_next[0], rel=1e-12) and E_next[0] != pytest.approx(0.3)
    assert E_next[1].derivatives()[0] > 0.0        # more speed, more friction power, more energy
    builder = DiagramBuilder()
    plant = _disk_plant(builder)
    add_friction(builder, plant, FrictionModel.coulomb_viscous([0.4], [0.3], sign_eps=0.05))
    ad = builder.Build().ToAutoDiffXd()
    ctx = ad.CreateDefaultContext()
    ctx.SetContinuousState([AutoDiffXd(0.0, [1.0, 0.0]), AutoDiffXd(0.2, [0.0, 1.0])])
    xdot = ad.EvalTimeDerivatives(ctx).CopyToVector()
    # d(wdot)/dw = -(kv + kc / eps * (1 - tanh^2(w / eps))) / I, I = 0.5
    expect = -(0.3 + 0.4 / 0.05 * (1 - np.tanh(0.2 / 0.05) ** 2)) / 0.5
    assert xdot[1].derivatives()[1] == pytest.approx(expect, rel=1e-9)


def _truth_reference(tr, q, v, t, E):
    """The synthetic truth written out by hand (Eqs. (9.1)-(9.3), (9.12), (9.13), (9.22), ripple)."""
    F = np.zeros(len(tr.kc))
    for j in range(len(tr.kc)):
        s = np.tanh(v[j] / tr.v_eps)
        kc, kv = (tr.kc_neg[j] if v[j] < 0 else tr.kc[j]), tr.kv[j]
        if j in tr.change and t >= tr.change[j][0]:
            kc = tr.change[j][1] * (tr.kc_neg[j] / tr.kc[j] if v[j] < 0 else 1.0)
            kv = tr.change[j][2]
        c, w, a = tr.bumps.get(j, ([], [], []))
        level = kc + sum(ak * np.exp(-0.5 * ((q[j] - ck) / wk) ** 2) for ck, wk, ak in zip(c, w, a)) + E[j]
        F[j] = kv * v[j] + s * level
        if j in tr.ripple:
            g, h, a0, vh, ph = tr.ripple[j]
            F[j] += a0 / (1 + abs(v[j]) / vh) * np.sin(h * np.mod(g * q[j], 2 * np.pi) + ph)
        for i, kci, kvi in tr.coupling.get(j, []):
            F[j] += kvi * v[i] + kci * np.tanh(v[i] / tr.v_eps)
    return F


def test_friction_truth_is_evaluated_through_the_package_terms():
    """FrictionTruth.torque (all effects at once) equals the hand-written truth; its per-joint
    JointFriction holds the package's terms, and the two new term types round-trip through to_dict."""
    from drake_est.identification.friction.terms import SpeedAttenuatedRipple, TimeSwitched, term_from_dict
    from drake_est.identification.friction.truth import FrictionTruth
    tr = FrictionTruth(kc=np.array([2.0, 1.0, 0.5]), kv=np.array([0.8, 0.3, 0.2]), kc_neg=np.array([1.5, 1.4, 0.6]),
                       bumps={0: (np.array([0.2, -0.3]), np.array([0.3, 0.2]), np.array([0.5, -0.4]))},
                       ripple={1: (50.0, 2, 0.4, 0.5, 0.3)}, energy={0: (-0.1, 5.0)},
                       coupling={2: [(1, 0.2, 0.1)]}, change={0: (1.0, 2.6, 1.1), 1: (0.5, 0.7, 0.2)})
    rng = np.random.default_rng(11)
    for _ in range(30):
        q, v = rng.uniform(-1, 1, 3), rng.uniform(-0.2, 0.2, 3)
        t, E = rng.uniform(0, 2), np.array([rng.uniform(-0.3, 0.0), 0.0, 0.0])
        np.testing.assert_allclose(tr.torque(q, v, t, E), _truth_reference(tr, q, v, t, E), rtol=1e-12, atol=1e-12)
    kinds = [t.kind for t in tr.joint_model(1).terms]
    assert kinds == ["time_switched"] * 4 + ["speed_attenuated_ripple"]
    tr.active = np.array([True, False, True])
    assert tr.joint_model(1) is None and tr.torque(np.zeros(3), np.ones(3), 0.0)[1] == 0.0
    Q, V = rng.uniform(-1, 1, (5, 2)), rng.uniform(-1, 1, (5, 2))
    for term in (SpeedAttenuatedRipple(50.0, 3, 0.4, 0.2), TimeSwitched(JointFriction.coulomb_viscous(1, 1).terms[0], 0.3)):
        back = term_from_dict(term.to_dict())
        kw = {"t": np.linspace(0, 1, 5)} if term.needs_time else {}
        np.testing.assert_array_equal(back.columns(Q, V, 1, **kw), term.columns(Q, V, 1, **kw))
        assert back.names() == term.names()
    with pytest.raises(DrakeEstError, match="v_half"):
        SpeedAttenuatedRipple(50.0, 1, 0.0)
