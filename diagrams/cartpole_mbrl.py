"""Build and run a Diagram: the controller learned by model-based RL (Algorithm 7, LTV models) on the Drake cart-pole.

Learns a controller for the pendulum-on-a-cart task of thesis Sec. 11.2 (dampen the pendulum released near
upright, |u| <= 10 m/s^2) with :func:`drake_est.control.mbrl.mbrl` (LTV model by (7.5), KL-constrained iLQR) on
:class:`drake_est.systems.cartpole_plant.CartPoleTrueSystem`, then runs the learned time-varying feedback
controller (mean action, as an ``IlqrController.from_plan``) in a Diagram with the continuous cart-pole
``MultibodyPlant`` (``models/cartpole.urdf``) through a 0.01 s zero-order hold.

    python diagrams/cartpole_mbrl.py [--duration 4] [--iterations 12] [--model ltv] [--out cartpole_mbrl.png]

``--model`` picks the model of Algorithm 7: ``ltv`` (default), ``lti``, ``ltv-nn`` (successive network prior)
or ``ltv-nn-pretrained`` (network pretrained on random-input experiments, trained here first).

Writes ``<out stem>.json`` with the learned cost per iteration, the cost of the true-model DDP, the cost of the
simulated closed loop and its deviation from the learned nominal trajectory.
"""
import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from pydrake.systems.analysis import Simulator  # noqa: E402
from pydrake.systems.framework import DiagramBuilder  # noqa: E402
from pydrake.systems.primitives import MatrixGain, VectorLogSink, ZeroOrderHold  # noqa: E402

from drake_est.control.cartpole import benchmark_problem  # noqa: E402
from drake_est.systems.cartpole_plant import (PLANT_FROM_THESIS, THESIS_FROM_PLANT,  # noqa: E402
                                              CartPoleTrueSystem, add_cartpole)
from drake_est.control.ilqr import ilqr  # noqa: E402
from drake_est.control.mbrl import mbrl  # noqa: E402
from drake_est.jsonutil import dump_json  # noqa: E402
from drake_est.systems.controllers import IlqrController  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=4.0, help="simulated time [s] (the task lasts 4 s)")
    ap.add_argument("--iterations", type=int, default=12, help="learning iterations (experiments)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--model", default="ltv", choices=["ltv", "lti", "ltv-nn", "ltv-nn-pretrained"],
                    help="model of Algorithm 7 (default ltv)")
    ap.add_argument("--out", default="cartpole_mbrl.png")
    a = ap.parse_args(argv)
    model, cost, x0, U0, lo, hi = benchmark_problem()
    T, h = 400, 0.01
    learned = mbrl(CartPoleTrueSystem(), model, cost, x0, T, model=a.model, iterations=a.iterations, seed=a.seed,
                   lower=lo, upper=hi, show_progress=True)
    ctrl_l = learned.controller
    J_ddp = ilqr(model, cost, x0, U0, lo, hi).J

    builder = DiagramBuilder()
    plant, act = add_cartpole(builder)
    P = np.eye(4)[THESIS_FROM_PLANT]                    # thesis-order state = P @ plant state
    to_thesis = builder.AddSystem(MatrixGain(P))
    ctrl = builder.AddSystem(IlqrController.from_plan(ctrl_l.x_nom, ctrl_l.u_nom, ctrl_l.K, h, lo, hi))
    zoh = builder.AddSystem(ZeroOrderHold(h, 1))
    builder.Connect(plant.get_state_output_port(), to_thesis.get_input_port())
    builder.Connect(to_thesis.get_output_port(), ctrl.get_state_input_port())
    builder.Connect(ctrl.get_control_output_port(), zoh.get_input_port())
    builder.Connect(zoh.get_output_port(), act.get_cart_acceleration_input_port())
    log_x = builder.AddSystem(VectorLogSink(4, h))
    log_u = builder.AddSystem(VectorLogSink(1, h))
    builder.Connect(to_thesis.get_output_port(), log_x.get_input_port())
    builder.Connect(zoh.get_output_port(), log_u.get_input_port())
    diagram = builder.Build()
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    plant.SetPositionsAndVelocities(plant.GetMyMutableContextFromRoot(ctx), x0[PLANT_FROM_THESIS])
    t_end = min(a.duration, T * h)
    sim.AdvanceTo(t_end)
    t = log_x.FindLog(ctx).sample_times()
    x = log_x.FindLog(ctx).data().T
    u = log_u.FindLog(ctx).data().T
    k = min(len(t), T)
    dev = np.abs(x[:k] - ctrl_l.x_nom[:k])
    res = {"learned_cost_per_iteration": [float(c) for c in learned.costs],
           "true_model_ddp_cost": float(J_ddp),
           "learned_over_ddp": float(min(learned.costs) / J_ddp),
           "closed_loop_theta_deviation_max_rad": float(dev[:, 0].max()),
           "max_abs_u": float(np.abs(u).max()), "simulated_s": float(t_end), "iterations": a.iterations,
           "model": a.model}
    fig, axs = plt.subplots(3, 1, figsize=(7, 7))
    axs[0].plot(np.arange(1, a.iterations + 1), learned.costs, "o-", label=f"{a.model.upper()} model-based RL")
    axs[0].axhline(J_ddp, color="k", ls="--", label="DDP, true model")
    axs[0].set_yscale("log")
    axs[0].set_xlabel("learning iteration")
    axs[0].set_ylabel("cost [-]")
    axs[0].legend(fontsize=8)
    axs[1].plot(t, x[:, 0], label="theta, Drake cart-pole")
    axs[1].plot(np.arange(T + 1) * h, ctrl_l.x_nom[:, 0], "--", label="theta, learned nominal")
    axs[1].set_ylabel("theta [rad]")
    axs[1].legend(fontsize=8)
    axs[2].plot(t, u[:, 0])
    axs[2].set_ylabel("u [m/s^2]")
    axs[2].set_xlabel("time [s]")
    fig.suptitle(f"Learned controller (Algorithm 7, {a.model}) on the Drake cart-pole", fontsize=10)
    fig.tight_layout()
    out = Path(a.out)
    fig.savefig(out, dpi=110)
    dump_json(res, out.with_suffix(".json"))
    print(res)


if __name__ == "__main__":
    main()
