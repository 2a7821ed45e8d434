"""Robot models: the ABB IRB 140 as a Drake ``MultibodyPlant`` (``models/irb140.urdf``)
with its metadata (``models/irb140.toml``: gear ratios, the wrist coupling matrix of
thesis Eq. (9.10)-(9.11), nominal friction), and kinematics/dynamics helpers:

* :func:`add_irb140` -- the plant welded to the world in a ``DiagramBuilder``;
* :class:`RobotModel` -- forward kinematics F_k(q) in SE(3) (``RigidTransform``),
  the manipulator Jacobian J(q), inverse dynamics tau = M(q) qdd + C(q, qd) qd + G(q),
  mass matrix and gravity torques, single-sample and batched, for the IRB 140 or any URDF;
* :func:`forward_kinematics`, :func:`jacobian`, :func:`inverse_dynamics` -- module-level
  shortcuts on a cached IRB 140 model.
"""
from __future__ import annotations

import functools
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, MultibodyPlant
from pydrake.multibody.tree import JacobianWrtVariable, MultibodyForces, SpatialInertia, UnitInertia
from pydrake.systems.framework import DiagramBuilder

from drake_est.errors import DataError


def models_dir() -> Path:
    """The repository's ``models/`` folder."""
    return Path(__file__).resolve().parents[1] / "models"


@dataclass
class RobotMetadata:
    """What URDF cannot carry (see ``models/irb140.toml`` for sources/assumptions)."""

    name: str
    joint_names: list
    gear_ratios: np.ndarray
    rotor_inertias: np.ndarray
    motor_from_arm: np.ndarray  # q_motor = motor_from_arm @ q_arm (lower triangular, Eq. (9.10))
    coulomb: np.ndarray
    viscous: np.ndarray
    position_limits: np.ndarray = field(default=None)  # (n, 2) rad
    velocity_limits: np.ndarray = field(default=None)  # (n,) rad/s
    flange_frame: str = "tool0"
    urdf: Path | None = None

    @property
    def arm_from_motor(self) -> np.ndarray:
        """G of Eq. (9.11): q_arm = G q_motor (solved, not inverted explicitly, on use)."""
        return np.linalg.solve(self.motor_from_arm, np.eye(len(self.gear_ratios)))

    def motor_positions(self, q_arm) -> np.ndarray:
        """Motor angles wrapped to [0, 2 pi): p_motor = mod(G^-1 q_arm, 2 pi) (Sec. 9.6)."""
        q_arm = np.atleast_2d(q_arm)
        return np.mod(q_arm @ self.motor_from_arm.T, 2 * np.pi)

    def limits_dict(self) -> dict:
        return {j + 1: tuple(self.position_limits[j]) for j in range(len(self.joint_names))}


@functools.lru_cache(maxsize=None)
def irb140_metadata() -> RobotMetadata:
    """Metadata of the IRB 140 from ``models/irb140.toml`` and the URDF's limits."""
    path = models_dir() / "irb140.toml"
    with open(path, "rb") as f:
        d = tomllib.load(f)
    model = irb140()
    return RobotMetadata(
        name=d["name"], joint_names=list(d["joint_names"]), gear_ratios=np.array(d["gear_ratios"], float),
        rotor_inertias=np.array(d["rotor_inertias"], float), motor_from_arm=np.array(d["motor_from_arm"], float), coulomb=np.array(d["coulomb"], float),
        viscous=np.array(d["viscous"], float), position_limits=model.position_limits.copy(),
        velocity_limits=model.velocity_limits.copy(), flange_frame=d["flange_frame"],
        urdf=models_dir() / d["urdf"])


def _add_payload(plant: MultibodyPlant, model, flange_frame: str, mass: float, com) -> None:
    """Weld a point-like payload body of ``mass`` kg at ``com`` (m, in the flange frame)."""
    inertia = SpatialInertia(mass, np.zeros(3), UnitInertia.SolidSphere(0.02))
    body = plant.AddRigidBody("payload", model, inertia)
    plant.WeldFrames(plant.GetFrameByName(flange_frame, model), body.body_frame(), RigidTransform(np.asarray(com, float)))


#: numeric URDF attributes checked before Drake parses a file: {element: {attribute: number of values}}
_URDF_NUMBERS = {"mass": {"value": 1}, "inertia": {k: 1 for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")},
                 "origin": {"xyz": 3, "rpy": 3}, "axis": {"xyz": 3},
                 "limit": {"lower": 1, "upper": 1, "velocity": 1, "effort": 1},
                 "dynamics": {"damping": 1, "friction": 1},
                 "cylinder": {"radius": 1, "length": 1}, "capsule": {"radius": 1, "length": 1},
                 "sphere": {"radius": 1}, "box": {"size": 3}, "mesh": {"scale": 3}}
_URDF_POSITIVE = {"cylinder", "capsule", "sphere", "box", "mesh"}   # shape sizes: Drake aborts on <= 0
URDF_MAX_ABS = 1e9   # no robot has a length, mass, inertia or limit beyond this in SI units


def validate_urdf(path) -> None:
    """Check a URDF's numbers before Drake reads it, with one ``DataError`` line naming the link/joint.

    Drake aborts the whole process (not an exception) on some inconsistent values (a lower position
    limit above the upper one, a negative velocity limit) and accepts non-physical ones silently (negative
    mass, an inertia that violates the triangle inequality); both are refused here.  Files whose root is
    not ``<robot>`` (SDF) are left to Drake's parser."""
    import xml.etree.ElementTree as ET

    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as err:
        raise DataError(f"robot model {path} is not valid XML ({err})") from None
    except (UnicodeDecodeError, ValueError) as err:
        raise DataError(f"robot model {path} is not a readable XML file ({type(err).__name__})") from None
    if root.tag != "robot":
        return
    for owner in list(root.iter("link")) + list(root.iter("joint")):
        if owner.get("name") is None and owner.find("*") is None:
            continue          # <joint name=...> references inside <transmission> etc. carry no numbers
        who = f"{owner.tag} '{owner.get('name', '?')}'"
        _check_single(path, who, owner, ("inertial",) if owner.tag == "link" else
                      ("parent", "child", "axis", "limit", "origin", "dynamics"))
        for inertial in owner.findall("inertial"):
            _check_single(path, who, inertial, ("mass", "inertia", "origin"))
        vals = {}
        for el in owner.iter():
            spec = _URDF_NUMBERS.get(el.tag, {})
            for attr, count in spec.items():
                raw = el.get(attr)
                if raw is None:
                    continue
                try:
                    v = np.array([float(x) for x in raw.split()], dtype=float)
                except ValueError:
                    raise DataError(f"robot model {path}: {who}: <{el.tag} {attr}=\"{raw[:40]}\"> is not a number") \
                        from None
                if v.size != count:
                    raise DataError(f"robot model {path}: {who}: <{el.tag} {attr}=\"{raw[:40]}\"> needs {count} "
                                    f"number(s), has {v.size}")
                if not np.all(np.isfinite(v)) or np.any(np.abs(v) > URDF_MAX_ABS):
                    raise DataError(f"robot model {path}: {who}: <{el.tag} {attr}=\"{raw[:40]}\"> must be finite "
                                    f"and within +-{URDF_MAX_ABS:.0e}")
                if el.tag in _URDF_POSITIVE and not np.all(v > 0):
                    raise DataError(f"robot model {path}: {who}: <{el.tag} {attr}=\"{raw[:40]}\"> must be > 0")
                vals[(el.tag, attr)] = v
        _check_urdf_physics(path, who, vals)


def _check_single(path, who, el, tags):
    """A second <mass>, <limit>, ... would be ignored by Drake without a word: refuse it."""
    for tag in tags:
        n = len(el.findall(tag))
        if n > 1:
            raise DataError(f"robot model {path}: {who}: {n} <{tag}> elements in <{el.tag}>; one is allowed")


def _check_urdf_physics(path, who, vals):
    get = lambda tag, attr, default=None: (float(vals[(tag, attr)][0]) if (tag, attr) in vals else default)  # noqa: E731
    m = get("mass", "value")
    if m is not None and m < 0:
        raise DataError(f"robot model {path}: {who}: mass {m:g} kg is negative")
    if any(("inertia", k) in vals for k in ("ixx", "iyy", "izz")):
        I = np.array([[get("inertia", "ixx", 0.0), get("inertia", "ixy", 0.0), get("inertia", "ixz", 0.0)],
                      [get("inertia", "ixy", 0.0), get("inertia", "iyy", 0.0), get("inertia", "iyz", 0.0)],
                      [get("inertia", "ixz", 0.0), get("inertia", "iyz", 0.0), get("inertia", "izz", 0.0)]])
        ev = np.linalg.eigvalsh(I)
        tol = 1e-9 * max(float(np.sum(np.abs(ev))), 1e-300)
        if ev[0] < -tol or ev[0] + ev[1] < ev[2] - tol:
            raise DataError(f"robot model {path}: {who}: the rotational inertia is not physical (principal moments "
                            f"{', '.join(f'{e:.3g}' for e in ev)} kg m^2: negative or violating the triangle "
                            "inequality)")
    lo, hi = get("limit", "lower"), get("limit", "upper")
    if lo is not None and hi is not None and lo > hi:
        raise DataError(f"robot model {path}: {who}: position limit lower {lo:g} is above upper {hi:g}")
    for attr in ("velocity", "effort"):
        v = get("limit", attr)
        if v is not None and v < 0:
            raise DataError(f"robot model {path}: {who}: <limit {attr}> {v:g} is negative")
    for attr in ("damping", "friction"):
        v = get("dynamics", attr)
        if v is not None and v < 0:
            raise DataError(f"robot model {path}: {who}: <dynamics {attr}> {v:g} is negative")
    if ("axis", "xyz") in vals and not np.linalg.norm(vals[("axis", "xyz")]) > 0:
        raise DataError(f"robot model {path}: {who}: <axis xyz> is the zero vector")


def add_robot(builder: DiagramBuilder, urdf, time_step: float = 0.0, base_link: str | None = None,
              payload: tuple | None = None, flange_frame: str | None = None, rotor: tuple | None = None):
    """Parse ``urdf`` into a MultibodyPlant in ``builder``, weld its base to the world and finalize.

    ``payload=(mass_kg, com_xyz_in_flange_m)`` welds an extra mass to ``flange_frame``
    (used to simulate an unmodeled payload). ``rotor=(gear_ratios, rotor_inertias)`` sets the
    actuators' reflected rotor inertia g^2 J_r (added to the mass matrix by Drake). Returns ``(plant, scene_graph, model_instance)``."""
    urdf = Path(urdf)
    if not urdf.exists():
        raise DataError(f"robot model not found: {urdf}")
    if not urdf.is_file():
        raise DataError(f"robot model {urdf} is not a regular file")
    validate_urdf(urdf)
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=time_step)
    parser = Parser(plant)
    parser.SetAutoRenaming(True)
    try:
        model = _build_model(plant, parser, urdf, base_link, payload, flange_frame, rotor)
    except DataError:
        raise
    except (Exception, SystemExit) as err:  # noqa: BLE001 - Drake: RuntimeError with a long text (parse, loops,
        # Finalize); a failed C++ assertion ("Failure at ...") reaches Python as SystemExit
        first = (str(err).strip().splitlines() or [type(err).__name__])[0]
        raise DataError(f"cannot load robot model {urdf}: {first[:200]}") from None
    return plant, scene_graph, model


def _build_model(plant, parser, urdf, base_link, payload, flange_frame, rotor):
    models = parser.AddModels(str(urdf))
    if len(models) != 1:
        raise DataError(f"robot model {urdf} holds {len(models)} models; one robot is expected")
    (model,) = models
    if base_link is None:
        base_link = _root_link(plant, model)
    if base_link is not None:    # None: the model is already attached to the world by its own joint
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(base_link, model))
    if payload is not None:
        _add_payload(plant, model, flange_frame or "tool0", payload[0], payload[1])
    if rotor is not None:
        gear, inertia = rotor
        acts = [i for i in plant.GetJointActuatorIndices() if plant.get_joint_actuator(i).model_instance() == model]
        for k, idx in enumerate(acts):
            act = plant.get_mutable_joint_actuator(idx)
            act.set_default_gear_ratio(float(gear[k]))
            act.set_default_rotor_inertia(float(inertia[k]))
    plant.Finalize()
    return model


def _root_link(plant, model) -> str:
    bodies = plant.GetBodyIndices(model)
    children = {plant.get_joint(j).child_body().index() for j in plant.GetJointIndices(model)}
    roots = [plant.get_body(b).name() for b in bodies if b not in children]
    if not roots and any(plant.get_joint(j).parent_body().index() == plant.world_body().index()
                         for j in plant.GetJointIndices(model)):
        return None
    if len(roots) != 1:
        raise DataError(f"cannot find a unique root link in the URDF (candidates: {roots})")
    return roots[0]


def _irb140_rotor():
    with open(models_dir() / "irb140.toml", "rb") as f:
        d = tomllib.load(f)
    return np.array(d["gear_ratios"], float), np.array(d["rotor_inertias"], float)


def add_irb140(builder: DiagramBuilder | None = None, time_step: float = 0.0, payload: tuple | None = None):
    """The IRB 140 plant welded to the world in ``builder`` (a new one if None).

    Returns ``(builder, plant, scene_graph, model_instance)``. Six revolute joints, one actuator
    each (input port ``plant.get_actuation_input_port()`` in arm-side N m)."""
    builder = builder or DiagramBuilder()
    plant, sg, model = add_robot(builder, models_dir() / "irb140.urdf", time_step=time_step, base_link="base_link",
                                 payload=payload, flange_frame="tool0", rotor=_irb140_rotor())
    return builder, plant, sg, model


class RobotModel:
    """Kinematics and rigid-body dynamics of a fixed-base robot from Drake.

    Example::

        robot = RobotModel.irb140()
        X_WF = robot.forward_kinematics(q)        # RigidTransform of the flange (tool0)
        J = robot.jacobian(q)                     # 6 x n, [angular; translational], world frame
        tau = robot.inverse_dynamics(q, qd, qdd)  # M qdd + C qd + G
    """

    def __init__(self, urdf, base_link: str | None = None, flange_frame: str | None = None,
                 payload: tuple | None = None, rotor: tuple | None = None):
        builder = DiagramBuilder()
        self.plant, _, self.model = add_robot(builder, urdf, 0.0, base_link, payload, flange_frame, rotor)
        self.diagram = builder.Build()
        self._dctx = self.diagram.CreateDefaultContext()
        self.context = self.plant.GetMyMutableContextFromRoot(self._dctx)
        self.n = self.plant.num_positions()
        if self.plant.num_velocities() != self.n:
            raise DataError("only robots with as many velocities as positions (revolute/prismatic joints) are supported")
        if flange_frame is None:
            names = [self.plant.get_frame(i).name() for i in self.plant.GetFrameIndices(self.model)]
            flange_frame = "tool0" if "tool0" in names else self.plant.get_body(self.plant.GetBodyIndices(self.model)[-1]).name()
        self.flange = self.plant.GetFrameByName(flange_frame, self.model)
        self.urdf = Path(urdf)
        self._forces = MultibodyForces(self.plant)
        self.position_limits = np.column_stack([self.plant.GetPositionLowerLimits(),
                                                self.plant.GetPositionUpperLimits()])
        self.velocity_limits = self.plant.GetVelocityUpperLimits().copy()
        self.joint_names = [self.plant.get_joint(j).name() for j in self.plant.GetJointIndices(self.model)
                            if self.plant.get_joint(j).num_positions() == 1]

    @classmethod
    def irb140(cls, payload: tuple | None = None) -> "RobotModel":
        return cls(models_dir() / "irb140.urdf", base_link="base_link", flange_frame="tool0", payload=payload,
                   rotor=_irb140_rotor())

    def _check(self, q, name="q"):
        q = np.asarray(q, dtype=float).ravel()
        if q.shape[0] != self.n:
            raise DataError(f"{name} has {q.shape[0]} entries, the robot has {self.n} joints")
        return q

    def _set(self, q, qd=None):
        self.plant.SetPositions(self.context, self._check(q))
        self.plant.SetVelocities(self.context, np.zeros(self.n) if qd is None else self._check(qd, "qd"))

    def forward_kinematics(self, q, frame=None) -> RigidTransform:
        """Pose of the flange (or ``frame``) in the world, F_k(q) in SE(3)."""
        self._set(q)
        f = self.flange if frame is None else (self.plant.GetFrameByName(frame, self.model) if isinstance(frame, str) else frame)
        return f.CalcPoseInWorld(self.context)

    def jacobian(self, q, frame=None, offset=None) -> np.ndarray:
        """Spatial-velocity Jacobian (6 x n) of the flange origin (+ ``offset`` in the flange
        frame) in the world frame, rows [angular (3); translational (3)]."""
        self._set(q)
        f = self.flange if frame is None else self.plant.GetFrameByName(frame, self.model)
        p = np.zeros(3) if offset is None else np.asarray(offset, float)
        return self.plant.CalcJacobianSpatialVelocity(self.context, JacobianWrtVariable.kV, f, p,
                                                      self.plant.world_frame(), self.plant.world_frame())

    def inverse_dynamics(self, q, qd, qdd) -> np.ndarray:
        """tau = M(q) qdd + C(q, qd) qd + G(q) (gravity and URDF damping included)."""
        self._set(q, qd)
        self.plant.CalcForceElementsContribution(self.context, self._forces)
        return self.plant.CalcInverseDynamics(self.context, self._check(qdd, "qdd"), self._forces)

    def mass_matrix(self, q) -> np.ndarray:
        self._set(q)
        return self.plant.CalcMassMatrix(self.context)

    def gravity_torques(self, q) -> np.ndarray:
        """G(q): the torque that holds the robot still at q (= -tau_g of Drake)."""
        self._set(q)
        return -self.plant.CalcGravityGeneralizedForces(self.context)

    def forward_dynamics(self, q, qd, tau) -> np.ndarray:
        """qdd = M^-1 (tau - C qd - G), by a Cholesky solve."""
        import scipy.linalg
        M = self.mass_matrix(q)
        bias = self.inverse_dynamics(q, qd, np.zeros(self.n))
        return scipy.linalg.cho_solve(scipy.linalg.cho_factor(M), np.asarray(tau, float) - bias)

    def inverse_dynamics_batch(self, Q, QD, QDD) -> np.ndarray:
        """Row-wise :meth:`inverse_dynamics` for arrays (N, n)."""
        Q, QD, QDD = (np.atleast_2d(np.asarray(a, float)) for a in (Q, QD, QDD))
        out = np.empty_like(Q)
        for i in range(Q.shape[0]):
            out[i] = self.inverse_dynamics(Q[i], QD[i], QDD[i])
        return out

    def forward_kinematics_batch(self, Q) -> np.ndarray:
        """Flange poses as (N, 4, 4) homogeneous matrices."""
        Q = np.atleast_2d(np.asarray(Q, float))
        return np.stack([self.forward_kinematics(q).GetAsMatrix4() for q in Q])


def load_urdf_model(path) -> "RobotModel":
    """A :class:`RobotModel` of a user-supplied URDF; any parse/model error becomes one ``DataError`` line
    naming the file (a damaged model file is user input)."""
    path = Path(str(path))
    if path.suffix.lower() not in (".urdf", ".sdf", ".xml"):
        raise DataError(f"--robot must be 'irb140', 'generic' or an existing .urdf file, got '{path}'")
    if not path.is_file():
        raise DataError(f"robot model not found: {path}")
    try:
        return RobotModel(path)
    except DataError:
        raise
    except Exception as err:  # noqa: BLE001 - Drake's parser raises RuntimeError/ValueError with long texts
        first = (str(err).strip().splitlines() or [type(err).__name__])[0]
        raise DataError(f"cannot load robot model {path}: {first[:200]}") from None


def robot_position_limits(robot) -> tuple[dict, set]:
    """Position limits of the robot a command names, used to refuse positions in wrong units (degrees).

    ``robot``: ``"irb140"`` (its URDF limits), ``None``/``"generic"``/``"none"``/``"auto"`` (no model: no
    limits) or a URDF path (the finite limits of its one-degree-of-freedom joints; joint ``j`` is the
    plant's position ``j - 1``).  Returns ``(limits, prismatic)``: ``{joint: (lo, hi)}`` [rad or m] and
    the set of prismatic joints (positions in m, never judged as degrees)."""
    name = None if robot is None else str(robot)
    if name is None or name.lower() in ("generic", "none", "auto", ""):
        return {}, set()
    if name.lower() == "irb140":
        return irb140_metadata().limits_dict(), set()
    model = load_urdf_model(name)
    limits, prismatic = {}, set()
    plant = model.plant
    for ji in plant.GetJointIndices(model.model):
        joint = plant.get_joint(ji)
        if joint.num_positions() != 1:
            continue
        j = joint.position_start() + 1
        if "prismatic" in joint.type_name().lower():
            prismatic.add(j)
        lo, hi = float(joint.position_lower_limits()[0]), float(joint.position_upper_limits()[0])
        if np.isfinite(lo) and np.isfinite(hi) and hi > lo:
            limits[j] = (lo, hi)
    return limits, prismatic


@functools.lru_cache(maxsize=None)
def irb140(payload: tuple | None = None) -> RobotModel:
    """A cached :class:`RobotModel` of the IRB 140 (not thread-safe: one context)."""
    return RobotModel.irb140(payload=payload)


def forward_kinematics(q) -> RigidTransform:
    """IRB 140 flange (tool0) pose in the world at joint angles ``q`` [rad]."""
    return irb140().forward_kinematics(q)


def jacobian(q) -> np.ndarray:
    """IRB 140 flange spatial-velocity Jacobian (6 x 6, [angular; translational]) in the world."""
    return irb140().jacobian(q)


def inverse_dynamics(q, qd, qdd) -> np.ndarray:
    """IRB 140 inverse dynamics tau = M(q) qdd + C(q, qd) qd + G(q) [N m]."""
    return irb140().inverse_dynamics(q, qd, qdd)


def dh_transform(theta, d, a, alpha) -> np.ndarray:
    """Standard Denavit-Hartenberg link transform (4 x 4)."""
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d], [0, 0, 0, 1]])


def rpy_to_rotation(rpy):
    """RotationMatrix from roll-pitch-yaw [rad]."""
    return RollPitchYaw(np.asarray(rpy, float)).ToRotationMatrix()
