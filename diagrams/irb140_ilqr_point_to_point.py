"""Build and run a Diagram: IRB 140 MultibodyPlant driven by the IlqrController (point-to-point under torque limits).

The controller plans once (at initialization, from the measured state) a 1 s point-to-point motion with
control-limited iLQR on the explicit-Euler discretization (dt = 0.01 s) of a separate nominal IRB 140 plant,
with Jacobians by AutoDiffXd (``drake_est.control.problems.irb140_point_to_point``; torque limits
``IRB140_TORQUE_LIMITS``, J1-J3 assumed, J4-J6 public), then outputs u = u_ff(t) + K(t)(x - x_nom(t)) clipped
to the limits through a 1 kHz zero-order hold to the continuous plant (built by ``AddIrb140Plant``).

    python diagrams/irb140_ilqr_point_to_point.py [--duration 3] [--out irb140_ilqr.png]

The simulation stops at the end of the plan (min(duration, horizon)); beyond it the plan holds its last step,
which does not hold the arm against gravity (use ``replan_period`` for that).  Writes ``<out stem>.json`` with
the tracking error |q - q_nom| (max and RMS over the plan), the error to the goal at the end of the plan, and
the largest torque / limit ratio.
"""
import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from pydrake.systems.analysis import Simulator  # noqa: E402
from pydrake.systems.framework import DiagramBuilder  # noqa: E402
from pydrake.systems.primitives import VectorLogSink, ZeroOrderHold  # noqa: E402

from drake_est.control.problems import irb140_point_to_point  # noqa: E402
from drake_est.jsonutil import dump_json  # noqa: E402
from drake_est.systems.builders import AddIrb140Plant, PlantConfig  # noqa: E402
from drake_est.systems.controllers import IlqrController  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=3.0, help="simulated time [s]")
    ap.add_argument("--out", default="irb140_ilqr.png")
    ap.add_argument("--horizon", type=int, default=100, help="plan steps of 0.01 s")
    a = ap.parse_args(argv)
    p = irb140_point_to_point(T=a.horizon)
    builder = DiagramBuilder()
    plant = AddIrb140Plant(builder, PlantConfig(time_step=0.0))
    ctrl = builder.AddSystem(IlqrController(p.model, p.cost, a.horizon, p.dt, p.lower, p.upper, U_init=p.U0))
    zoh = builder.AddSystem(ZeroOrderHold(1e-3, 6))
    builder.Connect(plant.get_state_output_port(), ctrl.get_state_input_port())
    builder.Connect(ctrl.get_control_output_port(), zoh.get_input_port())
    builder.Connect(zoh.get_output_port(), plant.get_actuation_input_port())
    log_x = builder.AddSystem(VectorLogSink(12, 0.01))
    log_n = builder.AddSystem(VectorLogSink(12, 0.01))
    log_u = builder.AddSystem(VectorLogSink(6, 0.01))
    builder.Connect(plant.get_state_output_port(), log_x.get_input_port())
    builder.Connect(ctrl.get_nominal_state_output_port(), log_n.get_input_port())
    builder.Connect(zoh.get_output_port(), log_u.get_input_port())
    diagram = builder.Build()
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    plant.SetPositionsAndVelocities(plant.GetMyMutableContextFromRoot(ctx), p.x0)
    t0 = time.perf_counter()
    sim.Initialize()                         # the controller plans here
    t_plan = time.perf_counter() - t0
    t_end = min(a.duration, a.horizon * p.dt)
    sim.AdvanceTo(t_end)
    wall = time.perf_counter() - t0
    t = log_x.FindLog(ctx).sample_times()
    x = log_x.FindLog(ctx).data().T
    xn = log_n.FindLog(ctx).data().T
    u = log_u.FindLog(ctx).data().T
    in_plan = t <= a.horizon * p.dt + 1e-9
    err = np.abs(x[:, :6] - xn[:, :6])
    res = {"tracking_error_max_rad": float(err[in_plan].max()),
           "tracking_error_rms_rad": float(np.sqrt(np.mean(err[in_plan] ** 2))),
           "goal_error_at_end_rad": float(np.abs(x[-1, :6] - p.q_goal).max()),
           "planned_goal_error_rad": float(np.abs(xn[-1, :6] - p.q_goal).max()),
           "max_torque_fraction_of_limit": float((np.abs(u) / p.upper).max()),
           "torque_limits": p.upper.tolist(), "plan_seconds": t_plan, "wall_seconds": wall,
           "simulated_s": t_end, "horizon_s": a.horizon * p.dt}
    fig, axs = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    for j in range(6):
        axs[0].plot(t, x[:, j], f"C{j}-", lw=1, label=f"q{j + 1}")
        axs[0].plot(t, xn[:, j], f"C{j}--", lw=0.8)
        axs[1].plot(t, u[:, j] / p.upper[j], f"C{j}-", lw=1, label=f"tau{j + 1}")
    axs[0].set_ylabel("q [rad] (dashed: plan)")
    axs[1].set_ylabel("tau / limit [-]")
    axs[1].set_xlabel("time [s]")
    axs[0].legend(fontsize=7, ncol=6)
    axs[0].set_title(f"IRB 140 point-to-point with IlqrController: max tracking error "
                     f"{res['tracking_error_max_rad']:.2e} rad", fontsize=10)
    fig.tight_layout()
    out = Path(a.out)
    fig.savefig(out, dpi=110)
    dump_json(res, out.with_suffix(".json"))
    print(res)


if __name__ == "__main__":
    main()
