"""Diagram builders (in the style of the MIT manipulation course's ``station.py``).

Every ``Add...(builder, ...)`` function adds systems to a ``DiagramBuilder``, wires them and returns the
systems it added (or a small dataclass of them); ``Make...(config)`` builds a whole ``Diagram`` and returns
``(diagram, handles)``.  Numbers (gains, rates, time steps) come from small ``@dataclass`` configs, never
literals, so that each caller keeps its own values explicit:

* :func:`AddIrb140Plant` -- the IRB 140 ``MultibodyPlant`` (continuous or discrete, optional payload,
  a discrete plant with :func:`AddJointCompliance` as a joint-flexibility hook);
* :func:`AddRobotPlant` -- the same for any URDF (generic axes);
* :func:`AddTwoLinkArm` / :func:`MakeTwoLinkArmPlant` -- the planar two-link arm of the thesis' Sec. 7.8;
* :func:`AddTrajectorySource` -- desired state [q; v] and desired acceleration of a trajectory;
* :func:`AddTrackingController` -- inverse-dynamics tracking on a (nominal, frictionless) controller model;
* :func:`AddJointFriction` -- a friction system whose torque opposes the plant's motion, summed with an
  optional actuation source into the plant's actuation input;
* :func:`AddStateLogger` / :func:`AddVectorLogger` -- ``VectorLogSink``s at a fixed period;
* :func:`MakeIrb140Simulation` -- plant + trajectory + tracking controller + friction + loggers.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydrake.systems.framework import LeafSystem_
from pydrake.systems.scalar_conversion import TemplateSystem

from drake_est.errors import DataError


# ------------------------------------------------------------------------------------------- configs
@dataclass
class PlantConfig:
    """How the robot plant is built.

    time_step:  0 for a continuous plant, > 0 [s] for a discrete one.
    payload:    ``(mass [kg], com_in_flange [m])`` welded to the flange, or None.

    Joint compliance is a separate hook: :func:`AddJointCompliance` adds a :class:`JointSpringDamper` whose
    torque the caller passes to :func:`AddJointFriction` as an extra actuation source."""
    time_step: float = 0.0
    payload: tuple | None = None


@dataclass
class TrackingControllerConfig:
    """Gains of the inverse-dynamics tracking controller u = ID(q, v, qdd_d + kp e + kd de + ki int e).

    Scalars broadcast to all joints. ``from_bandwidth(wn)`` gives kp = wn^2, kd = 2 wn, ki = ki_ratio wn^2."""
    kp: float | np.ndarray = 400.0
    kd: float | np.ndarray = 40.0
    ki: float | np.ndarray = 200.0

    @classmethod
    def from_bandwidth(cls, wn: float, ki_ratio: float = 0.5) -> "TrackingControllerConfig":
        return cls(kp=wn ** 2, kd=2 * wn, ki=ki_ratio * wn ** 2)

    def gains(self, n: int):
        def vec(g, name):
            g = np.broadcast_to(np.asarray(g, float), (n,)).copy()
            if not np.all(np.isfinite(g)) or np.any(g < 0):
                raise DataError(f"tracking controller gain {name} must be finite and >= 0")
            return g
        return vec(self.kp, "kp"), vec(self.ki, "ki"), vec(self.kd, "kd")


@dataclass
class Irb140SimulationConfig:
    """An IRB 140 simulation: plant, tracking controller gains, logging period [s]."""
    plant: PlantConfig = field(default_factory=PlantConfig)
    controller: TrackingControllerConfig = field(default_factory=TrackingControllerConfig)
    log_period: float = 0.01


# ------------------------------------------------------------------------------------------- plants
def AddRobotPlant(builder, urdf, config: PlantConfig | None = None, base_link: str | None = None,
                  flange_frame: str | None = None, rotor: tuple | None = None):
    """Add a URDF robot plant welded to the world; returns ``plant`` (finalized)."""
    from drake_est.robots import add_robot
    config = config or PlantConfig()
    plant, _, _ = add_robot(builder, urdf, config.time_step, base_link=base_link, payload=config.payload,
                            flange_frame=flange_frame, rotor=rotor)
    return plant


def AddIrb140Plant(builder, config: PlantConfig | None = None):
    """Add the IRB 140 ``MultibodyPlant`` (with its SceneGraph; rotor inertias from ``models/irb140.toml``).

    ``config.time_step`` = 0 gives a continuous plant, > 0 a discrete one. Returns the finalized plant;
    its actuation input is the arm-side joint torque [N m]."""
    from drake_est.robots import add_irb140
    config = config or PlantConfig()
    _, plant, _, _ = add_irb140(builder, time_step=float(config.time_step), payload=config.payload)
    return plant


def MakeIrb140ControllerPlant(time_step: float = 0.0):
    """A separate, nominal (no payload, frictionless) IRB 140 plant for a model-based controller."""
    from pydrake.systems.framework import DiagramBuilder
    return AddIrb140Plant(DiagramBuilder(), PlantConfig(time_step=time_step))


def AddJointCompliance(builder, plant, stiffness, damping, rest=None):
    """Add a :class:`JointSpringDamper` fed by the plant's state (a hook for flexible joints); pass its
    ``get_joint_torques_output_port()`` to :func:`AddJointFriction` (``extra_torque_sources``)."""
    spring = builder.AddSystem(JointSpringDamper(stiffness, damping, rest))
    builder.Connect(plant.get_state_output_port(), spring.get_robot_state_input_port())
    return spring


def AddTwoLinkArm(plant_or_time_step=1e-3, link_masses=(2.0, 1.0), link_lengths=(0.5, 0.4),
                  actuators: bool = True):
    """A planar two-link arm moving in the horizontal plane (joint axes along gravity, so gravity does no
    work), built programmatically: thin rods, default lengths 0.5 m / 0.4 m, masses 2 / 1 kg (Sec. 7.8).

    Takes an unfinalized ``MultibodyPlant`` or a time step [s] (a new plant is made); ``actuators`` adds a
    joint torque actuator [N m] to each joint (the plant's actuation input). Returns ``(plant, (joint1,
    joint2))`` with the plant finalized; add it to a ``DiagramBuilder`` with ``builder.AddSystem(plant)``."""
    from pydrake.math import RigidTransform
    from pydrake.multibody.plant import MultibodyPlant
    from pydrake.multibody.tree import FixedOffsetFrame, RevoluteJoint, SpatialInertia, UnitInertia

    plant = (MultibodyPlant(float(plant_or_time_step)) if np.isscalar(plant_or_time_step)
             else plant_or_time_step)
    bodies = []
    for i, (mass, length) in enumerate(zip(link_masses, link_lengths)):
        # thin rod along +x of the body frame, joint at the body origin
        G = UnitInertia.ThinRod(length, [1, 0, 0]).ShiftFromCenterOfMass([-length / 2, 0, 0])
        bodies.append(plant.AddRigidBody(f"link{i + 1}", SpatialInertia(mass, [length / 2, 0, 0], G)))
    j1 = plant.AddJoint(RevoluteJoint("joint1", plant.world_frame(), bodies[0].body_frame(), [0, 0, 1]))
    elbow = plant.AddFrame(FixedOffsetFrame("elbow", bodies[0].body_frame(),
                                            RigidTransform([link_lengths[0], 0, 0])))
    j2 = plant.AddJoint(RevoluteJoint("joint2", elbow, bodies[1].body_frame(), [0, 0, 1]))
    if actuators:
        for j in (j1, j2):
            plant.AddJointActuator(f"{j.name()}_motor", j)
    plant.Finalize()
    return plant, (j1, j2)


def MakeTwoLinkArmPlant(time_step: float = 1e-3, actuators: bool = True):
    """:func:`AddTwoLinkArm` on a new plant with ``time_step`` [s]."""
    return AddTwoLinkArm(time_step, actuators=actuators)


# ------------------------------------------------------------------------------------------- sources
@dataclass
class TrajectorySourceHandles:
    state: object          # TrajectorySource of [q; v]
    acceleration: object   # TrajectorySource of qdd


def AddTrajectorySource(builder, trajectory, with_acceleration: bool = True) -> TrajectorySourceHandles:
    """Add sources of the desired state [q; v] (``trajectory`` and its derivative) and, optionally, of the
    desired acceleration (second derivative). ``trajectory``: a pydrake ``PiecewisePolynomial``."""
    from pydrake.systems.primitives import TrajectorySource
    src = builder.AddSystem(TrajectorySource(trajectory, output_derivative_order=1))
    acc = builder.AddSystem(TrajectorySource(trajectory.derivative(2))) if with_acceleration else None
    return TrajectorySourceHandles(state=src, acceleration=acc)


# ------------------------------------------------------------------------------------------- control
def AddTrackingController(builder, plant, config: TrackingControllerConfig | None = None,
                          controller_plant=None, trajectory: TrajectorySourceHandles | None = None):
    """Add Drake's ``InverseDynamicsController`` (with integral action) tracking a reference.

    ``controller_plant`` is the controller's model (default: ``plant`` itself; pass a nominal, frictionless
    plant such as :func:`MakeIrb140ControllerPlant` to simulate model error). The plant's state feeds the
    controller; if ``trajectory`` is given its state/acceleration sources feed the desired ports. The
    controller's output is *not* connected (use :func:`AddJointFriction` or ``_connect_actuation``).
    Returns the controller."""
    from pydrake.systems.controllers import InverseDynamicsController
    config = config or TrackingControllerConfig()
    ctrl_plant = controller_plant if controller_plant is not None else plant
    kp, ki, kd = config.gains(ctrl_plant.num_positions())
    ctrl = builder.AddSystem(InverseDynamicsController(ctrl_plant, kp, ki, kd, True))
    if trajectory is not None:
        builder.Connect(trajectory.state.get_output_port(), ctrl.get_input_port_desired_state())
        if trajectory.acceleration is not None:
            builder.Connect(trajectory.acceleration.get_output_port(),
                            ctrl.get_input_port_desired_acceleration())
    builder.Connect(plant.get_state_output_port(), ctrl.get_input_port_estimated_state())
    return ctrl


# ------------------------------------------------------------------------------------------- friction
@dataclass
class JointFrictionHandles:
    friction: object       # the friction system
    negate: object         # Gain(-1)
    actuation: object      # Adder feeding the plant's actuation (or the Gain when no other source)
    demux: object | None = None


def AddJointFriction(builder, plant, friction, actuation_source=None, extra_torque_sources=(),
                     connect_actuation: bool = True) -> JointFrictionHandles:
    """Add a friction system (``friction_torques`` [N m] output) and feed ``-F`` to the plant's actuation.

    Inputs of the friction system are wired from the plant's state: ``joint_positions`` / ``joint_velocities``
    ports through a Demultiplexer, or a single state port (``robot_state``/``state`` [q; v]) directly. With
    ``actuation_source`` (an output port, e.g. a controller's torque) the actuation is
    ``actuation_source - F (+ extra_torque_sources)``; ``connect_actuation=False`` leaves the actuation
    unconnected. Systems are added in the order friction, (Demultiplexer,) Gain, Adder.
    Returns :class:`JointFrictionHandles`."""
    from pydrake.systems.primitives import Adder, Demultiplexer, Gain

    n = plant.num_velocities()
    fr = builder.AddSystem(friction)
    demux = None
    names = [fr.get_input_port(i).get_name() for i in range(fr.num_input_ports())]
    if "joint_positions" in names and "joint_velocities" in names:
        nq = plant.num_positions()
        demux = builder.AddSystem(Demultiplexer([nq, n]))
        builder.Connect(plant.get_state_output_port(), demux.get_input_port(0))
        builder.Connect(demux.get_output_port(0), fr.GetInputPort("joint_positions"))
        builder.Connect(demux.get_output_port(1), fr.GetInputPort("joint_velocities"))
    elif len(names) == 1:
        builder.Connect(plant.get_state_output_port(), fr.get_input_port(0))
    else:
        raise DataError(f"friction system inputs {names}: expected joint_positions/joint_velocities "
                        "or one state port")
    out = fr.GetOutputPort("friction_torques") if fr.HasOutputPort("friction_torques") else fr.get_output_port(0)
    neg = builder.AddSystem(Gain(-1.0, n))
    builder.Connect(out, neg.get_input_port())
    sources = [p for p in (actuation_source, neg.get_output_port(), *extra_torque_sources) if p is not None]
    if not connect_actuation:
        return JointFrictionHandles(friction=fr, negate=neg, actuation=None, demux=demux)
    if len(sources) == 1:
        builder.Connect(neg.get_output_port(), plant.get_actuation_input_port())
        return JointFrictionHandles(friction=fr, negate=neg, actuation=neg, demux=demux)
    add = builder.AddSystem(Adder(len(sources), n))
    for i, p in enumerate(sources):
        builder.Connect(p, add.get_input_port(i))
    builder.Connect(add.get_output_port(), plant.get_actuation_input_port())
    return JointFrictionHandles(friction=fr, negate=neg, actuation=add, demux=demux)


# ------------------------------------------------------------------------------------------- logging
def AddVectorLogger(builder, output_port, period: float):
    """A ``VectorLogSink`` publishing ``output_port`` every ``period`` [s]."""
    from pydrake.systems.primitives import VectorLogSink
    if not period > 0:
        raise DataError(f"log period must be > 0 s, got {period}")
    sink = builder.AddSystem(VectorLogSink(output_port.size(), period))
    builder.Connect(output_port, sink.get_input_port())
    return sink


def AddStateLogger(builder, plant, period: float):
    """Log the plant's state [q; v] every ``period`` [s]."""
    return AddVectorLogger(builder, plant.get_state_output_port(), period)


# ------------------------------------------------------------------------------------------- whole diagrams
@dataclass
class Irb140SimulationHandles:
    plant: object
    controller: object
    trajectory: TrajectorySourceHandles
    friction: JointFrictionHandles | None
    state_log: object
    torque_log: object
    friction_log: object | None


def MakeIrb140Simulation(config: Irb140SimulationConfig, trajectory, friction=None, controller_plant=None):
    """The IRB 140 tracking ``trajectory`` (a ``PiecewisePolynomial`` of q) under inverse-dynamics control
    on a nominal, frictionless controller model while ``friction`` (a friction system, or None) acts on the
    joints; logs the state, the controller torque and the friction torque every ``config.log_period``.

    Returns ``(diagram, handles)`` (:class:`Irb140SimulationHandles`). The systems are added in the order
    plant, controller, sources, friction, Gain, Adder, loggers."""
    from pydrake.systems.framework import DiagramBuilder

    builder = DiagramBuilder()
    plant = AddIrb140Plant(builder, config.plant)
    if controller_plant is None:
        controller_plant = MakeIrb140ControllerPlant(config.plant.time_step)
    ctrl = AddTrackingController(builder, plant, config.controller, controller_plant=controller_plant)
    traj = AddTrajectorySource(builder, trajectory)
    builder.Connect(traj.state.get_output_port(), ctrl.get_input_port_desired_state())
    builder.Connect(traj.acceleration.get_output_port(), ctrl.get_input_port_desired_acceleration())
    fh = None
    if friction is not None:
        fh = AddJointFriction(builder, plant, friction, actuation_source=ctrl.get_output_port_control())
    else:
        builder.Connect(ctrl.get_output_port_control(), plant.get_actuation_input_port())
    log_x = AddStateLogger(builder, plant, config.log_period)
    log_u = AddVectorLogger(builder, ctrl.get_output_port_control(), config.log_period)
    log_f = None
    if fh is not None:
        out = (fh.friction.GetOutputPort("friction_torques") if fh.friction.HasOutputPort("friction_torques")
               else fh.friction.get_output_port(0))
        log_f = AddVectorLogger(builder, out, config.log_period)
    diagram = builder.Build()
    return diagram, Irb140SimulationHandles(plant=plant, controller=ctrl, trajectory=traj, friction=fh,
                                            state_log=log_x, torque_log=log_u, friction_log=log_f)


# ------------------------------------------------------------------------------------------- helper systems
def spring_damper_torque(q, v, stiffness, damping, rest=0.0):
    """tau = -k (q - q_rest) - d v, elementwise (a linear joint spring-damper)."""
    return -np.asarray(stiffness) * (np.asarray(q) - rest) - np.asarray(damping) * np.asarray(v)


@TemplateSystem.define("JointSpringDamper_")
def JointSpringDamper_(T):
    class Impl(LeafSystem_[T]):
        """Joint compliance torque tau = -k (q - q_rest) - d v (:func:`spring_damper_torque`).

        Ports: input ``robot_state`` [q rad; v rad/s]; output ``joint_torques`` [N m].
        Scalar types float and AutoDiffXd (``ToAutoDiffXd()``), so a Diagram holding it can be linearized
        or differentiated (iLQR)."""

        def _construct(self, stiffness, damping, rest=None, converter=None):
            LeafSystem_[T].__init__(self, converter)
            self.stiffness = np.asarray(stiffness, float).ravel()
            self.damping = np.asarray(damping, float).ravel()
            n = self.stiffness.size
            if self.damping.size != n:
                raise DataError(f"damping has {self.damping.size} entries, stiffness {n}")
            self.rest = np.zeros(n) if rest is None else np.asarray(rest, float).ravel()
            if self.rest.size != n:
                raise DataError(f"rest has {self.rest.size} entries, expected {n}")
            self._n = n
            self._state = self.DeclareVectorInputPort("robot_state", 2 * n)
            self._torques = self.DeclareVectorOutputPort("joint_torques", n, self._calc)

        def _construct_copy(self, other, converter=None):
            Impl._construct(self, other.stiffness, other.damping, other.rest, converter=converter)

        def get_robot_state_input_port(self):
            return self._state

        def get_joint_torques_output_port(self):
            return self._torques

        def _calc(self, context, output):
            x = self._state.Eval(context)
            # Drake's Build() may probe the port with NaN inputs: NaN in, NaN out, without a warning
            with np.errstate(invalid="ignore"):
                output.SetFromVector(spring_damper_torque(x[: self._n], x[self._n:], self.stiffness,
                                                          self.damping, self.rest))

    return Impl


JointSpringDamper = JointSpringDamper_[None]


def contract_cases():
    from drake_est.systems.contract import ContractCase
    k, d, r = np.array([10.0, 20.0]), np.array([1.0, 0.5]), np.array([0.1, -0.2])
    x = np.array([0.3, -0.4, 0.5, 2.0])
    return [ContractCase(make=lambda: JointSpringDamper(k, d, r), inputs={"robot_state": x},
                         expected=lambda s: {"joint_torques": spring_damper_torque(x[:2], x[2:], k, d, r)},
                         label="two joints")]
