"""Build and run a Diagram: IRB 140 MultibodyPlant + FrictionModel + tracking controller.

Simulates joint 1 of the IRB 140 moving back and forth under Drake's InverseDynamicsController while the
FrictionModel (Coulomb + viscous, thesis Eq. (9.2), IRB 140 nominal values from models/irb140.toml) acts on
the joints, logs the motor torque, and plots torque vs velocity: the Coulomb + viscous shape appears in the
torque the controller must supply.

    python diagrams/irb140_with_friction.py [--duration 20] [--out irb140_friction.png]
"""
import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from pydrake.systems.analysis import Simulator  # noqa: E402
from pydrake.systems.controllers import InverseDynamicsController  # noqa: E402
from pydrake.systems.framework import DiagramBuilder  # noqa: E402
from pydrake.systems.primitives import TrajectorySource, VectorLogSink  # noqa: E402
from pydrake.trajectories import PiecewisePolynomial  # noqa: E402

from drake_est.robots import add_irb140, irb140_metadata  # noqa: E402
from drake_est.systems.friction import FrictionModel, add_friction  # noqa: E402


def build(duration: float):
    meta = irb140_metadata()
    builder, plant, _, _ = add_irb140(DiagramBuilder())
    _, ctrl_plant, _, _ = add_irb140(DiagramBuilder())  # the controller's (nominal, frictionless) model
    n = plant.num_positions()
    ctrl = builder.AddSystem(InverseDynamicsController(ctrl_plant, np.full(n, 400.0), np.full(n, 200.0),
                                                       np.full(n, 40.0), True))
    # joint 1: a smooth back-and-forth motion; the others hold still
    ts = np.linspace(0, duration, 400)
    q = np.zeros((n, ts.size))
    qd = np.zeros((n, ts.size))
    w = 2 * np.pi / 10.0
    q[0] = 1.5 * np.sin(w * ts)
    qd[0] = 1.5 * w * np.cos(w * ts)
    q[4] = 0.6
    traj = PiecewisePolynomial.CubicHermite(ts, q, qd)
    src = builder.AddSystem(TrajectorySource(traj, output_derivative_order=1))
    acc = builder.AddSystem(TrajectorySource(traj.derivative(2)))
    builder.Connect(src.get_output_port(), ctrl.get_input_port_desired_state())
    builder.Connect(acc.get_output_port(), ctrl.get_input_port_desired_acceleration())
    builder.Connect(plant.get_state_output_port(), ctrl.get_input_port_estimated_state())
    friction = FrictionModel.coulomb_viscous(meta.coulomb, meta.viscous, sign_eps=1e-2)
    add_friction(builder, plant, friction, actuation_source=ctrl.get_output_port_control())
    log_x = builder.AddSystem(VectorLogSink(2 * n, 0.01))
    log_u = builder.AddSystem(VectorLogSink(n, 0.01))
    builder.Connect(plant.get_state_output_port(), log_x.get_input_port())
    builder.Connect(ctrl.get_output_port_control(), log_u.get_input_port())
    diagram = builder.Build()
    return diagram, plant, log_x, log_u, traj


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--out", default="irb140_friction.png")
    args = ap.parse_args()
    diagram, plant, log_x, log_u, traj = build(args.duration)
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    plant.SetPositions(plant.GetMyMutableContextFromRoot(ctx), traj.value(0).ravel())
    sim.get_mutable_integrator().set_maximum_step_size(0.005)
    sim.AdvanceTo(args.duration)
    t = log_x.FindLog(ctx).sample_times()
    keep = t > 1.0  # skip the start-up transient (the plant starts at rest, the reference does not)
    X = log_x.FindLog(ctx).data().T[keep]
    U = log_u.FindLog(ctx).data().T[keep]
    t = t[keep]
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(X[:, 6], U[:, 0], ".", ms=2)
    ax.set_xlabel("joint 1 velocity [rad/s]")
    ax.set_ylabel("joint 1 motor torque [N m]")
    ax.set_title("IRB 140 with FrictionModel: torque the controller supplies")
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"simulated {args.duration:.0f} s; max tracking error {np.abs(X[:, 0] - [traj.value(ti)[0, 0] for ti in t]).max():.2e} rad; wrote {args.out}")


if __name__ == "__main__":
    main()
