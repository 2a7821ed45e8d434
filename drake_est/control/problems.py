"""Fixed trajectory-optimization problems shared by the benchmark, the diagrams and the tests.

* :func:`drake_est.control.cartpole.benchmark_problem` — the issue's cart-pole (J* = 786.1796);
* :func:`irb140_point_to_point` — an IRB 140 point-to-point motion under joint torque limits, dynamics from
  Drake (AutoDiffXd of the ``MultibodyPlant``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_est.control.ilqr import QuadraticCost

# Joint torque limits [N m] used for the IRB 140 example.  J4-J6 are the public wrist limits
# (/work/shared/irb140_facts.md: 8.58, 8.58, 4.91 N m); J1-J3 have no public figure: J2 uses the static
# estimate of that file (~170 N m), J3 its estimate (42 N m), and J1 (vertical axis, no gravity load) is
# given J2's value.  These are assumptions of this example, not ABB data.
IRB140_TORQUE_LIMITS = np.array([170.0, 170.0, 42.0, 8.58, 8.58, 4.91])


@dataclass
class PointToPoint:
    """An IRB 140 point-to-point problem: model, cost, start x0, initial controls U0, bounds, goal, dt."""
    model: object
    cost: QuadraticCost
    x0: np.ndarray
    U0: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    q_goal: np.ndarray
    dt: float
    plant: object


def irb140_point_to_point(T=100, dt=0.01, q_start=None, q_goal=None, plant=None):
    """Move the IRB 140 from ``q_start`` to ``q_goal`` (rad) in T steps of dt under
    :data:`IRB140_TORQUE_LIMITS`; cost sum 100 |q - q_g|^2 + 1 |v|^2 + 1e-3 |tau|^2, terminal weight x10.
    Dynamics: explicit Euler of the continuous Drake plant, Jacobians by AutoDiffXd."""
    from drake_est.control.drake_model import DrakeModel
    if plant is None:
        from drake_est.systems.builders import MakeIrb140ControllerPlant
        plant = MakeIrb140ControllerPlant(0.0)
    q_start = np.array([0.0, 0.0, 0.0, 0.0, 0.3, 0.0]) if q_start is None else np.asarray(q_start, float)
    q_goal = np.array([0.8, 0.4, -0.3, 0.5, 0.6, -0.5]) if q_goal is None else np.asarray(q_goal, float)
    model = DrakeModel(plant, dt)
    n = 12
    Q = np.diag(np.r_[np.full(6, 100.0), np.full(6, 1.0)])
    R = 1e-3 * np.eye(6)
    x_ref = np.r_[q_goal, np.zeros(6)]
    cost = QuadraticCost(Q, R, Qf=10 * Q, x_ref=x_ref)
    x0 = np.r_[q_start, np.zeros(6)]
    ctx = plant.CreateDefaultContext()
    plant.SetPositions(ctx, q_start)
    g0 = -plant.CalcGravityGeneralizedForces(ctx)
    lim = IRB140_TORQUE_LIMITS
    U0 = np.tile(np.clip(g0, -lim, lim), (T, 1))
    assert x0.shape[0] == n
    return PointToPoint(model, cost, x0, U0, -lim, lim, q_goal, dt, plant)
