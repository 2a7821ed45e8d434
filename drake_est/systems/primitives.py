"""Small signal systems (pydrake's ``systems.primitives`` namespace): thin wrappers around plain functions.

* :class:`PeriodicComponentsSystem` -- the periodic components found by the LPV spectral method (thesis
  Ch. 10, Eq. (10.4)) as a signal source, e.g. identified ripple added to a simulated friction model or fed
  forward in a controller. Every number comes from :meth:`drake_est.spectral.lpv.LPVSpectrum.predict`.
"""
from __future__ import annotations

import copy

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem


class PeriodicComponentsSystem(LeafSystem):
    """Stateless evaluation of fitted periodic components, y = sum_w Re(k_w(v)^T exp(-i 2 pi f_w x)) (10.4).

    Wraps a fitted :class:`~drake_est.spectral.lpv.LPVSpectrum` (or a
    :class:`~drake_est.spectral.detect.PeriodicComponents`, whose ``.model`` is used) and calls its
    ``predict`` (the base regressors, e.g. Coulomb/viscous, are not part of the output).

    Ports
    -----
    * input ``position`` (1) -- the sampling variable the spectrum was fitted on, e.g. joint angle [rad];
    * input ``schedule`` (1) -- the scheduling variable, e.g. joint velocity [rad/s] (ignored by models
      without a schedule basis, but always declared so that diagrams are uniform);
    * output ``periodic_signal`` (1) -- the periodic part in the units of the fitted signal [fitted units,
      e.g. N m for a torque residual].
    """

    def __init__(self, components):
        super().__init__()
        self._model = copy.deepcopy(getattr(components, "model", components))   # read-only after this
        self._position = self.DeclareVectorInputPort("position", BasicVector(1))
        self._schedule = self.DeclareVectorInputPort("schedule", BasicVector(1))
        self._signal = self.DeclareVectorOutputPort("periodic_signal", BasicVector(1), self._calc,
                                                    prerequisites_of_calc={self.all_input_ports_ticket()})

    def get_position_input_port(self):
        return self._position

    def get_schedule_input_port(self):
        return self._schedule

    def get_periodic_signal_output_port(self):
        return self._signal

    def _calc(self, context, output):
        x = np.array([float(self._position.Eval(context)[0])])
        v = None
        if self._model.basis.n_basis > 1:
            v = np.array([float(self._schedule.Eval(context)[0])])
        output.SetAtIndex(0, float(self._model.predict(x, v)[0]))


def _small_spectrum():
    from drake_est.spectral.lpv import LPVSpectrum
    rng = np.random.default_rng(0)
    x = rng.uniform(0, 6, 400)
    v = rng.uniform(-1, 1, 400)
    y = (1 + 0.5 * v) * np.cos(2 * np.pi * 1.5 * x) + 0.3 * np.sin(2 * np.pi * 3.0 * x) \
        + 0.01 * rng.standard_normal(400)
    return LPVSpectrum(np.array([1.5, 3.0]), n_basis=3, lam=1e-3).fit(x, y, v)


def contract_cases():
    from drake_est.systems.contract import ContractCase
    model = _small_spectrum()
    x, v = 0.37, 0.4
    return [ContractCase(make=lambda: PeriodicComponentsSystem(model), inputs={"position": [x], "schedule": [v]},
                         expected=lambda s: {"periodic_signal": model.predict(np.array([x]), np.array([v]))},
                         label="LPV spectrum, 2 frequencies, 3 basis functions")]
