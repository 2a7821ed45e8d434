"""Seam-tracking LeafSystems (thesis Ch. 14) and the closed-loop Diagram builder.

Thin wrappers: every number comes from :mod:`drake_est.seam.filter` / :mod:`drake_est.seam.simulate`.

* :class:`CompliantArm` -- the IRB 140 ``MultibodyPlant`` kinematics with joint compliance: the arm deflects
  quasi-statically by K^-1 J^T f under the process force (FSW is slow, Sec. 14.1) and carries joint offsets
  (kinematic errors) the filter's model does not know;
* :class:`SeamSensors` -- joint encoders (motor side), force sensor and 0-2 laser stripes ahead of the tool;
* :class:`SeamTrackingEstimator` -- the seam-tracking particle filter (generic ``ParticleFilter`` with the
  SE(3) seam model);
* :class:`SeamTrackingController` -- corrects the commanded joints from the estimate.

* :class:`SeamMeshcatOverlay` -- live Meshcat drawing of the seam, the laser stripes, the true and estimated
  tool and the particle cloud at a modest publish rate (:mod:`drake_est.seam.viz`).

:func:`MakeSeamTrackingDiagram` wires them with trajectory sources for the nominal joints and the force; given
a ``meshcat`` it adds the robot (``MeshcatVisualizer`` of a geometry-only IRB 140 posed by the deflected arm)
and the overlay, both publishing every ``meshcat_period`` of simulated time.
"""
from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem

from drake_est.errors import DataError
from drake_est.seam.filter import filter_step, make_seam_filter
from drake_est.seam.simulate import (measure_all, reference_pose, tracking_correction, true_tool_pose)


class CompliantArm(LeafSystem):
    """The compliant IRB 140: q_arm = q_cmd + K^-1 J(q_cmd)^T f, tool pose F_k(q_arm + offsets) X_FT.

    Input ports: ``commanded_joints`` (6) [rad]; ``process_force`` (3) force on the tool [N].
    Output ports: ``arm_joints`` (6) deflected joint angles [rad]; ``tool_pose`` (16) true tool pose, 4x4
    row-major, translation [m]."""

    def __init__(self, scenario):
        super().__init__()
        self._scn = scenario
        self._q = self.DeclareVectorInputPort("commanded_joints", 6)
        self._f = self.DeclareVectorInputPort("process_force", 3)
        self._arm = self.DeclareVectorOutputPort("arm_joints", 6, self._calc_arm)
        self._pose = self.DeclareVectorOutputPort("tool_pose", 16, self._calc_pose)

    def get_commanded_joints_input_port(self):
        return self._q

    def get_process_force_input_port(self):
        return self._f

    def get_tool_pose_output_port(self):
        return self._pose

    def get_arm_joints_output_port(self):
        return self._arm

    def _calc(self, context):
        return true_tool_pose(self._scn, self._q.Eval(context), self._f.Eval(context))

    def _calc_arm(self, context, output):
        output.SetFromVector(self._calc(context)[1])

    def _calc_pose(self, context, output):
        output.SetFromVector(self._calc(context)[0].reshape(-1))


class SeamSensors(LeafSystem):
    """Encoders, force sensor and laser stripes of step k = round(t / period), noise from (seed, k).

    Input ports: ``commanded_joints`` (6) motor-side joint angles [rad]; ``process_force`` (3) [N];
    ``tool_pose`` (16) true tool pose, 4x4 row-major [m].
    Output port: ``measurement`` (9 + 4 S): measured joints [rad], measured force [N], per stripe
    [valid (1/0) [-], seam point in the laser plane (2) [m], surface angle [rad]]."""

    def __init__(self, scenario, model, period: float, seed: int = 0):
        super().__init__()
        if not period > 0:
            raise DataError(f"period must be > 0, got {period}")
        self._scn, self._model, self._period, self._seed = scenario, model, float(period), int(seed)
        self._q = self.DeclareVectorInputPort("commanded_joints", 6)
        self._f = self.DeclareVectorInputPort("process_force", 3)
        self._pose = self.DeclareVectorInputPort("tool_pose", 16)
        self._y = self.DeclareVectorOutputPort("measurement", model.ny, self._calc)

    def get_commanded_joints_input_port(self):
        return self._q

    def get_process_force_input_port(self):
        return self._f

    def get_tool_pose_input_port(self):
        return self._pose

    def get_measurement_output_port(self):
        return self._y

    def _calc(self, context, output):
        k = int(np.floor(context.get_time() / self._period + 1e-6))
        X = np.asarray(self._pose.Eval(context)).reshape(4, 4)
        output.SetFromVector(measure_all(self._scn, self._model, X, self._q.Eval(context), self._f.Eval(context),
                                         self._seed, k))


class SeamTrackingEstimator(LeafSystem):
    """The seam-tracking particle filter (Sec. 14.1) at a fixed period: each update corrects with the
    measurement, stores the weighted mean deviation xi_k|k and predicts (the generic ``ParticleFilter``).

    Input ports: ``measurement`` (9 + 4 S) [rad, N, m, rad] (see :class:`SeamSensors`); ``control`` (9)
    commanded joints [rad] and measured force [N].
    Output ports: ``estimate`` (6) tool-pose deviation xi = [dp [m], dtheta [rad]] from F_k(q_cmd) X_FT of the
    last update (no direct feedthrough); ``particles`` (6 N) row-major particle cloud [m, rad];
    ``diagnostics`` (3) [ESS [-], degenerate steps [-], steps [-]].
    State: one ``BasicVector``: particles, log-weights, k, xi (6), ESS, number of degenerate steps."""

    def __init__(self, pf, period: float):
        super().__init__()
        if not period > 0:
            raise DataError(f"period must be > 0, got {period}")
        self._pf = pf
        self._N, self._ny = pf.N, int(pf.ny)
        x, logw = pf.initial_belief()
        init = np.concatenate([x.reshape(-1), logw, [0.0], np.zeros(6), [float(pf.N), 0.0]])
        self._state = self.DeclareDiscreteState(BasicVector(init))
        self._measurement = self.DeclareVectorInputPort("measurement", self._ny)
        self._control = self.DeclareVectorInputPort("control", 9)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self._estimate = self.DeclareVectorOutputPort("estimate", 6, self._calc_estimate,
                                                      prerequisites_of_calc={self.xd_ticket()})
        self._particles = self.DeclareVectorOutputPort("particles", 6 * self._N, self._calc_particles,
                                                       prerequisites_of_calc={self.xd_ticket()})
        self._diag = self.DeclareVectorOutputPort("diagnostics", 3, self._calc_diag,
                                                  prerequisites_of_calc={self.xd_ticket()})

    def get_measurement_input_port(self):
        return self._measurement

    def get_control_input_port(self):
        return self._control

    def get_estimate_output_port(self):
        return self._estimate

    def get_particles_output_port(self):
        return self._particles

    def _read(self, context):
        v = context.get_discrete_state(self._state).get_value()
        N = self._N
        return v[:6 * N].reshape(N, 6), v[6 * N:7 * N], int(round(v[7 * N])), v[7 * N + 1:]

    def _update(self, context, discrete_state):
        x, logw, k, rest = self._read(context)
        x, logw, xi, ess, deg = filter_step(self._pf, x, logw, self._measurement.Eval(context),
                                            self._control.Eval(context), k)
        discrete_state.get_mutable_vector(self._state).SetFromVector(
            np.concatenate([x.reshape(-1), logw, [k + 1.0], xi, [ess, rest[7] + deg]]))

    def _calc_estimate(self, context, output):
        output.SetFromVector(self._read(context)[3][:6])

    def _calc_particles(self, context, output):
        output.SetFromVector(self._read(context)[0].reshape(-1))

    def _calc_diag(self, context, output):
        _, _, k, rest = self._read(context)
        output.SetFromVector([rest[6], rest[7], float(k)])


class SeamTrackingController(LeafSystem):
    """Tracking controller: commanded joints q_cmd = q_ref + c, with c updated every period by
    c += gain J^+ e, e the twist from the estimated tool pose F_k(q_cmd) X_FT Exp(xi) to F_k(q_ref) X_FT.

    Input ports: ``reference_joints`` (6) [rad]; ``estimate`` (6) deviation xi [m, rad].
    Output port: ``commanded_joints`` (6) [rad].  State: the correction c (6) [rad]."""

    def __init__(self, scenario, period: float, gain: float = 0.02, enabled: bool = True):
        super().__init__()
        if not period > 0:
            raise DataError(f"period must be > 0, got {period}")
        self._scn, self._gain, self._enabled, self._period = scenario, float(gain), bool(enabled), float(period)
        self._c = self.DeclareDiscreteState(6)
        self._qref = self.DeclareVectorInputPort("reference_joints", 6)
        self._est = self.DeclareVectorInputPort("estimate", 6)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self._cmd = self.DeclareVectorOutputPort("commanded_joints", 6, self._calc_cmd)

    def get_reference_joints_input_port(self):
        return self._qref

    def get_estimate_input_port(self):
        return self._est

    def get_commanded_joints_output_port(self):
        return self._cmd

    def _calc_cmd(self, context, output):
        output.SetFromVector(self._qref.Eval(context) + context.get_discrete_state(self._c).get_value())

    def _update(self, context, discrete_state):
        c = context.get_discrete_state(self._c).get_value()
        if self._enabled:
            k = int(np.floor(context.get_time() / self._period + 1e-6))
            q_cmd = self._qref.Eval(context) + c
            X_ref = reference_pose(self._scn, min(k, self._scn.T - 1))
            c = c + tracking_correction(self._scn.robot, self._scn.X_FT, q_cmd, self._est.Eval(context), X_ref,
                                        self._gain)
        discrete_state.get_mutable_vector(self._c).SetFromVector(c)


class SeamMeshcatOverlay(LeafSystem):
    """Live Meshcat view of seam tracking: at initialization draws the seam, the laser fans and the tool and
    estimate markers (and points the camera at the seam); every ``period`` of simulated time (a publish event,
    no state) moves the laser stripes with the true tool, the estimate marker and the particles' frame, and
    replaces the particle cloud.  Scene paths: :mod:`drake_est.seam.viz`.

    Input ports: ``tool_pose`` (16) true tool pose, 4x4 row-major, translation [m]; ``commanded_joints`` (6)
    [rad]; ``estimate`` (6) deviation xi = [dp [m], dtheta [rad]] from F_k(q_cmd) X_FT; ``particles`` (6 N)
    row-major particle deviations [m, rad]."""

    def __init__(self, meshcat, tool_pose, X_FT, seam_points, seam_normals, sensor_distances, n_particles: int,
                 period: float = 0.05):
        super().__init__()
        if not period > 0:
            raise DataError(f"meshcat period must be > 0, got {period}")
        from drake_est.seam import viz
        self._viz, self._meshcat, self._tool_pose = viz, meshcat, tool_pose
        self._X_FT = np.asarray(X_FT, float)
        self._knots = np.ascontiguousarray(seam_points, float)
        self._normals = np.ascontiguousarray(seam_normals, float)
        self._dists = tuple(float(d) for d in sensor_distances)
        self._N = int(n_particles)
        self._pose = self.DeclareVectorInputPort("tool_pose", 16)
        self._q = self.DeclareVectorInputPort("commanded_joints", 6)
        self._est = self.DeclareVectorInputPort("estimate", 6)
        self._particles = self.DeclareVectorInputPort("particles", 6 * self._N)
        self.DeclareInitializationPublishEvent(self._draw_static)
        self.DeclarePeriodicPublishEvent(float(period), 0.0, self._publish)

    def get_tool_pose_input_port(self):
        return self._pose

    def get_commanded_joints_input_port(self):
        return self._q

    def get_estimate_input_port(self):
        return self._est

    def get_particles_input_port(self):
        return self._particles

    def _draw_static(self, context):
        X = np.asarray(self._pose.Eval(context)).reshape(4, 4)
        depths = [self._viz.stripe_depth(X, d, self._knots, self._normals) for d in self._dists]
        self._viz.draw_static(self._meshcat, self._knots, self._dists, depths, X_FT=self._X_FT)
        self._viz.look_at_seam(self._meshcat, self._knots)

    def _publish(self, context):
        v = self._viz
        X_true = np.asarray(self._pose.Eval(context)).reshape(4, 4)
        X_nom = np.asarray(self._tool_pose(self._q.Eval(context)), float)
        X_est = v.estimate_pose(X_nom, self._est.Eval(context))
        v.set_frame(self._meshcat, v.frame_poses(X_true, X_nom, X_est, self._dists, self._knots, self._normals))
        v.set_particles(self._meshcat, np.asarray(self._particles.Eval(context)).reshape(self._N, 6))


def AddSeamMeshcat(builder, scenario, model, arm, controller, estimator, meshcat, period: float = 0.05):
    """Live Meshcat for the seam-tracking Diagram: the IRB 140 drawn at the deflected joints plus the true
    kinematic offsets (a geometry-only ``MultibodyPlant`` posed by ``MultibodyPositionToGeometryPose``, so no
    dynamics are simulated) through a ``MeshcatVisualizer``, and a :class:`SeamMeshcatOverlay`; both publish
    every ``period`` [s] of simulated time.  Returns (visualizer, overlay)."""
    from pydrake.geometry import MeshcatVisualizer, MeshcatVisualizerParams, SceneGraph
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant
    from pydrake.systems.primitives import Adder, ConstantVectorSource
    from pydrake.systems.rendering import MultibodyPositionToGeometryPose

    if not period > 0:
        raise DataError(f"meshcat period must be > 0, got {period}")
    sg = builder.AddSystem(SceneGraph())
    plant = MultibodyPlant(0.0)
    plant.RegisterAsSourceForSceneGraph(sg)
    (inst,) = Parser(plant).AddModels(str(scenario.robot.urdf))
    root = plant.get_body(plant.GetBodyIndices(inst)[0])
    plant.WeldFrames(plant.world_frame(), root.body_frame())
    plant.Finalize()
    if plant.num_positions() != 6:
        raise DataError(f"the robot model for Meshcat has {plant.num_positions()} positions, expected 6")
    to_pose = builder.AddSystem(MultibodyPositionToGeometryPose(plant))   # keeps the plant alive
    offsets = builder.AddSystem(ConstantVectorSource(np.asarray(scenario.kin_offsets, float)))
    add = builder.AddSystem(Adder(2, 6))
    builder.Connect(arm.get_arm_joints_output_port(), add.get_input_port(0))
    builder.Connect(offsets.get_output_port(), add.get_input_port(1))
    builder.Connect(add.get_output_port(), to_pose.get_input_port())
    builder.Connect(to_pose.get_output_port(), sg.get_source_pose_port(plant.get_source_id()))
    vis = MeshcatVisualizer.AddToBuilder(builder, sg, meshcat, MeshcatVisualizerParams(publish_period=period))
    overlay = builder.AddSystem(SeamMeshcatOverlay(meshcat, model.tool_pose, scenario.X_FT, scenario.seam.points,
                                                   scenario.seam.normals, model.config.sensor_distances,
                                                   estimator.get_particles_output_port().size() // 6, period))
    builder.Connect(arm.get_tool_pose_output_port(), overlay.get_tool_pose_input_port())
    builder.Connect(controller.get_commanded_joints_output_port(), overlay.get_commanded_joints_input_port())
    builder.Connect(estimator.get_estimate_output_port(), overlay.get_estimate_input_port())
    builder.Connect(estimator.get_particles_output_port(), overlay.get_particles_input_port())
    return vis, overlay


# ------------------------------------------------------------------------------------------- builder
def MakeSeamTrackingDiagram(scenario, filter_config=None, closed_loop: bool = True, seed: int = 0,
                            gain: float = 0.02, particle_period: float | None = None, meshcat=None,
                            meshcat_period: float = 0.05):
    """The closed-loop seam-tracking Diagram: nominal-joint and force sources -> controller -> compliant arm
    -> sensors -> estimator -> controller; with ``meshcat`` also the live view (:func:`AddSeamMeshcat`,
    publishing every ``meshcat_period`` [s]).  Returns (diagram, handles dict with the systems and loggers)."""
    from pydrake.systems.primitives import Multiplexer, TrajectorySource, VectorLogSink
    from pydrake.trajectories import PiecewisePolynomial
    from drake_est.seam.filter import SeamFilterConfig
    from drake_est.seam.simulate import compliance_model

    dt = scenario.config.dt
    cfg = filter_config or SeamFilterConfig(compliance=compliance_model(scenario))
    pf, model = make_seam_filter(scenario.robot, scenario.X_FT, scenario.compressed, cfg, seed=seed)
    b = DiagramBuilder()
    t = np.arange(scenario.T) * dt
    qsrc = b.AddSystem(TrajectorySource(PiecewisePolynomial.FirstOrderHold(t, scenario.q_ref.T)))
    fsrc = b.AddSystem(TrajectorySource(PiecewisePolynomial.FirstOrderHold(t, scenario.force.T)))
    ctrl = b.AddSystem(SeamTrackingController(scenario, dt, gain, enabled=closed_loop))
    arm = b.AddSystem(CompliantArm(scenario))
    sens = b.AddSystem(SeamSensors(scenario, model, dt, seed))
    est = b.AddSystem(SeamTrackingEstimator(pf, dt))
    umux = b.AddSystem(Multiplexer([6, 3]))
    fsel = b.AddSystem(_Slice(model.ny, 6, 9))
    b.Connect(qsrc.get_output_port(), ctrl.get_reference_joints_input_port())
    b.Connect(est.get_estimate_output_port(), ctrl.get_estimate_input_port())
    b.Connect(ctrl.get_commanded_joints_output_port(), arm.get_commanded_joints_input_port())
    b.Connect(fsrc.get_output_port(), arm.get_process_force_input_port())
    b.Connect(ctrl.get_commanded_joints_output_port(), sens.get_commanded_joints_input_port())
    b.Connect(fsrc.get_output_port(), sens.get_process_force_input_port())
    b.Connect(arm.get_tool_pose_output_port(), sens.get_tool_pose_input_port())
    b.Connect(sens.get_measurement_output_port(), est.get_measurement_input_port())
    b.Connect(ctrl.get_commanded_joints_output_port(), umux.get_input_port(0))
    b.Connect(sens.get_measurement_output_port(), fsel.get_input_port())
    b.Connect(fsel.get_output_port(), umux.get_input_port(1))
    b.Connect(umux.get_output_port(), est.get_control_input_port())
    log_pose = b.AddSystem(VectorLogSink(16, dt))
    log_cmd = b.AddSystem(VectorLogSink(6, dt))
    log_est = b.AddSystem(VectorLogSink(6, dt))
    b.Connect(arm.get_tool_pose_output_port(), log_pose.get_input_port())
    b.Connect(ctrl.get_commanded_joints_output_port(), log_cmd.get_input_port())
    b.Connect(est.get_estimate_output_port(), log_est.get_input_port())
    log_parts = None
    if particle_period:
        log_parts = b.AddSystem(VectorLogSink(6 * pf.N, particle_period))
        b.Connect(est.get_particles_output_port(), log_parts.get_input_port())
    vis = overlay = None
    if meshcat is not None:
        vis, overlay = AddSeamMeshcat(b, scenario, model, arm, ctrl, est, meshcat, meshcat_period)
    diagram = b.Build()
    return diagram, {"controller": ctrl, "arm": arm, "sensors": sens, "estimator": est, "pf": pf, "model": model,
                     "log_pose": log_pose, "log_cmd": log_cmd, "log_est": log_est, "log_particles": log_parts,
                     "meshcat_visualizer": vis, "meshcat_overlay": overlay}


class _Slice(LeafSystem):
    """Entries [a, b) of a vector (the measured force out of the measurement vector).

    Input port: ``input`` (n) [any]; output port: ``output`` (b - a) [same units]."""

    def __init__(self, n: int, a: int, b: int):
        super().__init__()
        self._a, self._b = int(a), int(b)
        self._in = self.DeclareVectorInputPort("input", int(n))
        self.DeclareVectorOutputPort("output", self._b - self._a,
                                     lambda c, o: o.SetFromVector(self._in.Eval(c)[self._a:self._b]))


def contract_cases():
    from drake_est.seam.filter import SeamFilterConfig
    from drake_est.systems.contract import ContractCase

    scn = _contract_scenario()
    q0 = scn.q_ref[0]
    f0 = scn.force[-1]
    cfg = SeamFilterConfig(n_particles=50)
    pf, model = make_seam_filter(scn.robot, scn.X_FT, scn.compressed, cfg, seed=3)
    Xt = true_tool_pose(scn, q0, f0)[0]
    y = measure_all(scn, model, Xt, q0, f0, 0, 0)
    u = np.concatenate([q0, y[6:9]])

    def est_expected(s):
        x, logw = pf.initial_belief()
        for k in range(5):
            x, logw, xi, ess, _ = filter_step(pf, x, logw, y, u, k)
        return {"estimate": xi}

    return [
        ContractCase(make=lambda: CompliantArm(scn), inputs={"commanded_joints": q0, "process_force": f0},
                     expected=lambda s: {"arm_joints": true_tool_pose(scn, q0, f0)[1],
                                         "tool_pose": true_tool_pose(scn, q0, f0)[0].reshape(-1)}),
        ContractCase(make=lambda: SeamSensors(scn, model, 0.01, seed=0),
                     inputs={"commanded_joints": q0, "process_force": f0, "tool_pose": Xt.reshape(-1)},
                     t_final=0.0, expected=lambda s: {"measurement": y}),
        ContractCase(make=lambda: SeamTrackingEstimator(pf, 0.01), inputs={"measurement": y, "control": u},
                     t_final=0.045, expected=est_expected, rtol=1e-7, atol=1e-9),
        ContractCase(make=lambda: SeamTrackingController(scn, 0.01), inputs={"reference_joints": q0,
                                                                           "estimate": np.zeros(6)},
                     t_final=0.03),
        ContractCase(make=lambda: SeamMeshcatOverlay(_contract_meshcat(), model.tool_pose, scn.X_FT, scn.seam.points,
                                                     scn.seam.normals, cfg.sensor_distances, pf.N, 0.01),
                     inputs={"tool_pose": Xt.reshape(-1), "commanded_joints": q0, "estimate": np.zeros(6),
                             "particles": np.zeros(6 * pf.N)}, t_final=0.03),
        ContractCase(make=lambda: _Slice(5, 1, 3), inputs={"input": np.arange(5.0)},
                     expected=lambda s: {"output": np.array([1.0, 2.0])}),
    ]


_SCN = {}


def _contract_scenario():
    """A short, fast scenario for contract checks (cached)."""
    if "s" not in _SCN:
        from drake_est.seam.seam import thesis_seam
        from drake_est.seam.simulate import ScenarioConfig, make_scenario
        seam = thesis_seam("xy", n_points=41)
        _SCN["s"] = make_scenario(seam, ScenarioConfig(speed=2.0, dt=1e-2), seed=0)
    return _SCN["s"]


def _contract_meshcat():
    """One Meshcat server for the contract checks (cached)."""
    if "meshcat" not in _SCN:
        from pydrake.geometry import Meshcat
        _SCN["meshcat"] = Meshcat()
    return _SCN["meshcat"]
