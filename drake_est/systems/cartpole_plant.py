"""The cart-pole of Eqs. (8.11)-(8.12) as a Drake ``MultibodyPlant`` (``models/cartpole.urdf``): the "true
system" of the model-based RL example (thesis Sec. 11.2).

The plant's actuator is a force on the cart; (8.12) takes the cart *acceleration* as input, so
:class:`drake_est.systems.controllers.CartAccelerationActuator` (a LeafSystem) computes the force that realizes p'' = u
from the plant's mass matrix, bias and gravity terms.  :class:`CartPoleTrueSystem` steps the resulting
Diagram (explicit Euler of the Diagram's time derivatives, input held over h = 0.01 s, the discretization of
the benchmark) in the thesis state order (theta, theta', p, v).

This module builds a Diagram from a plant and a LeafSystem, so it sits above both ``drake_est.systems``
and ``drake_est.control`` and is imported by neither (``drake_est.control.cartpole_drake`` forwards its
names here).
"""
from __future__ import annotations

import numpy as np

from drake_est.errors import DataError
from drake_est.robots import models_dir
from drake_est.systems.controllers import CartAccelerationActuator

# plant state (p, theta, v, omega) <-> thesis state (theta, omega, p, v)
PLANT_FROM_THESIS = np.array([2, 0, 3, 1])
THESIS_FROM_PLANT = np.array([1, 3, 0, 2])


def add_cartpole(builder):
    """Add the continuous cart-pole plant (with SceneGraph) and its acceleration actuator to ``builder``.

    Returns (plant, actuator); the actuator's ``cart_acceleration`` input [m/s^2] is the u of (8.12)."""
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import AddMultibodyPlantSceneGraph

    plant, _ = AddMultibodyPlantSceneGraph(builder, 0.0)
    Parser(plant).AddModels(str(models_dir() / "cartpole.urdf"))
    plant.Finalize()
    act = builder.AddSystem(CartAccelerationActuator(plant))
    builder.Connect(plant.get_state_output_port(), act.get_state_input_port())
    builder.Connect(act.get_cart_force_output_port(), plant.get_actuation_input_port())
    return plant, act


class CartPoleTrueSystem:
    """The Drake cart-pole Diagram with input u = cart acceleration, stepped with period ``h``.

    :meth:`step` (thesis state order) uses the Diagram's time derivatives (explicit Euler with ``substeps``
    sub-steps); :meth:`rollout` runs a controller ``policy(t, x) -> u`` for T steps."""

    def __init__(self, h=0.01, substeps=1):
        from pydrake.systems.framework import DiagramBuilder
        builder = DiagramBuilder()
        self.plant, self.actuator = add_cartpole(builder)
        builder.ExportInput(self.actuator.get_cart_acceleration_input_port(), "cart_acceleration")
        self.diagram = builder.Build()
        self.context = self.diagram.CreateDefaultContext()
        self._u = self.diagram.get_input_port(0)
        self.h = float(h)
        self.substeps = int(substeps)
        self.queries = 0

    def xdot(self, x, u):
        """Time derivative in thesis order for thesis state x (4,) and acceleration u."""
        self.context.SetContinuousState(np.asarray(x, float)[PLANT_FROM_THESIS])
        self._u.FixValue(self.context, np.atleast_1d(np.asarray(u, float)))
        return self.diagram.EvalTimeDerivatives(self.context).CopyToVector()[THESIS_FROM_PLANT]

    def step(self, x, u):
        x = np.asarray(x, float)
        dt = self.h / self.substeps
        for _ in range(self.substeps):
            x = x + dt * self.xdot(x, u)
        self.queries += 1
        return x

    def rollout(self, x0, T, policy):
        """Closed loop for T steps; returns X (T+1, 4), U (T, 1).  Raises DataError on a non-finite state."""
        X = np.empty((T + 1, 4))
        U = np.empty((T, 1))
        X[0] = x0
        for t in range(T):
            U[t] = policy(t, X[t])
            X[t + 1] = self.step(X[t], U[t])
            if not np.all(np.isfinite(X[t + 1])):
                raise DataError(f"cart-pole state became non-finite at step {t + 1}")
        return X, U
