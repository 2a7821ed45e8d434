"""``NeuralDynamics``: a learned discrete-time dynamics model (thesis Ch. 8) as a Drake ``LeafSystem``.

The system is a thin wrapper around :class:`drake_est.identification.nn.NeuralDynamicsModel`: its discrete
state x is updated every ``time_step`` seconds as x+ = model.predict(x, u).  :func:`linearize_trajectory`
gives (A_t, B_t) of the model along a trajectory, for iLQR or as an LTV prior (Sec. 7.5).
"""
from __future__ import annotations

import numpy as np
from pydrake.systems.framework import LeafSystem_
from pydrake.systems.scalar_conversion import TemplateSystem

from drake_est.errors import DataError
from drake_est.identification.nn import NeuralDynamicsModel


@TemplateSystem.define("NeuralDynamics_")
def NeuralDynamics_(T):
    class Impl(LeafSystem_[T]):
        """Discrete-time x+ = model(x, u) of a fitted :class:`NeuralDynamicsModel`.

        Ports
        -----
        * input ``control`` (m,) [model units]   (absent when the model has no inputs)
        * output ``state`` (n,) [model units]: the discrete state x_k, held between updates

        Parameters
        ----------
        model : a fitted NeuralDynamicsModel (its weights are copied: later changes to ``model`` do not
            affect the system).
        time_step : update period [s] (the sample time of the data the model was trained on).
        initial_state : x_0 (default zeros).

        Scalar types: float and AutoDiffXd (``ToAutoDiffXd()``), so Drake's ``Linearize`` /
        ``FirstOrderTaylorApproximation`` and AutoDiff-based optimizers can differentiate it; the float
        system calls ``model.predict``, the AutoDiffXd one evaluates the same network on AutoDiffXd arrays.
        """

        def _construct(self, model, time_step, initial_state=None, converter=None):
            LeafSystem_[T].__init__(self, converter)
            if not isinstance(model, NeuralDynamicsModel) or model.params_ is None:
                raise DataError("model: a fitted NeuralDynamicsModel is required")
            if not (np.isfinite(time_step) and time_step > 0):
                raise DataError(f"time_step must be > 0 [s], got {time_step}")
            self._model = NeuralDynamicsModel.from_dict(model.to_dict())
            n, m = self._model.n_states, self._model.n_inputs
            x0 = np.zeros(n) if initial_state is None else np.asarray(initial_state, float).reshape(-1)
            if x0.shape != (n,) or not np.all(np.isfinite(x0)):
                raise DataError(f"initial_state must be {n} finite numbers")
            self._n, self._m = n, m
            self._x0 = x0
            self._time_step = float(time_step)
            self._x = self.DeclareDiscreteState(x0)
            self._control = self.DeclareVectorInputPort("control", m) if m else None
            self._state = self.DeclareStateOutputPort("state", self._x)
            self.DeclarePeriodicDiscreteUpdateEvent(self._time_step, 0.0, self._update)

        def _construct_copy(self, other, converter=None):
            Impl._construct(self, other._model, other._time_step, other._x0, converter=converter)

        def _update(self, context, discrete_state):
            x = context.get_discrete_state(self._x).CopyToVector()
            u = self._control.Eval(context) if self._control is not None else np.zeros(0)
            if T == float:
                xn = self._model.predict(x, u if self._m else None)
            else:
                xn = _predict_generic(self._model, np.concatenate([x, u]))
            discrete_state.get_mutable_vector(self._x).SetFromVector(xn)

        def model(self) -> NeuralDynamicsModel:
            return self._model

        def time_step(self) -> float:
            return self._time_step

        def get_control_input_port(self):
            if self._control is None:
                raise DataError("this NeuralDynamics model has no inputs")
            return self._control

        def get_state_output_port(self):
            return self._state

    return Impl


def _predict_generic(model, z):
    """x+ = net(z) + N z for any scalar type (object arrays of AutoDiffXd included)."""
    l = z
    for W, b in model.params_[:-1]:
        l = np.tanh(W @ l + b)
    W, b = model.params_[-1]
    return W @ l + b + model.nominal_matrix @ z


NeuralDynamics = NeuralDynamics_[None]


def linearize_trajectory(system_or_model, x, u=None):
    """(A_t, B_t) of a NeuralDynamics system or NeuralDynamicsModel along a state/input trajectory:
    arrays (T, n, n), (T, n, m) — the Jacobian [A B] (8.6) at each (x_t, u_t), usable by iLQR and, as
    ``np.concatenate([A, B], 2).transpose(0, 2, 1)``, as the LTV prior mean (Sec. 7.5)."""
    model = system_or_model.model() if hasattr(system_or_model, "model") else system_or_model
    X = np.atleast_2d(np.asarray(x, float))
    U = None if u is None else np.asarray(u, float).reshape(X.shape[0], -1)
    return model.linearize(X, U)


def _contract_model():
    model = NeuralDynamicsModel(hidden=(5, 4), form="g", seed=3)
    rng = np.random.default_rng(1)
    sizes = [3, 5, 4, 2]
    params = [(0.5 * rng.standard_normal((sizes[i + 1], sizes[i])), 0.1 * rng.standard_normal(sizes[i + 1]))
              for i in range(3)]
    return model.set_params(params, 2, 1)


def contract_cases():
    from drake_est.systems.contract import ContractCase
    dt, u, x0 = 0.01, np.array([0.3]), np.array([0.2, -0.1])

    def expected(system):
        x = x0.copy()
        for _ in range(6):      # updates at t = 0, 0.01, ..., 0.05 (t_final 0.055 lies between updates)
            x = system.model().predict(x, u)
        return {"state": x}

    return [ContractCase(make=lambda: NeuralDynamics(_contract_model(), dt, x0), inputs={"control": u},
                         t_final=0.055, expected=expected, label="NeuralDynamics g + x")]
