"""Drake system wrapper: the periodic components found by the LPV spectral method as a torque source.

:class:`PeriodicComponentsSystem` is a stateless ``LeafSystem`` around
:class:`drake_est.spectral.detect.PeriodicComponents` (or any fitted
:class:`~drake_est.spectral.lpv.LPVSpectrum`): it evaluates
``sum_w Re(k_w^T phi_bar(v) exp(-i w x))`` for one joint, e.g. to add identified ripple to a
simulated friction model or to feed it forward in a controller.

Ports
-----
* input ``position`` (1) -- the sampling variable the spectrum was fitted on, e.g. joint angle [rad];
* input ``schedule`` (1) -- the scheduling variable, e.g. joint velocity [rad/s] (ignored by models
  without a schedule basis, but always declared so diagrams are uniform);
* output ``periodic_signal`` (1) -- the model's periodic part in the units of the fitted signal
  (e.g. [N m] for a torque residual).
"""
from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem


class PeriodicComponentsSystem(LeafSystem):
    """Stateless Drake system evaluating fitted periodic components (see module doc)."""

    def __init__(self, components):
        super().__init__()
        model = getattr(components, "model", components)
        self._freqs = np.asarray(model.freqs, dtype=float).copy()
        self._coef = np.asarray(model.coef).copy()
        self._basis = model.basis
        self.DeclareVectorInputPort("position", BasicVector(1))
        self.DeclareVectorInputPort("schedule", BasicVector(1))
        self.DeclareVectorOutputPort("periodic_signal", BasicVector(1), self._calc,
                                     prerequisites_of_calc={self.all_input_ports_ticket()})

    def _calc(self, context, output):
        x = float(self.get_input_port(0).Eval(context)[0])
        if self._basis.n_basis > 1:
            v = float(self.get_input_port(1).Eval(context)[0])
            phi = self._basis(np.array([v]))[0]
        else:
            phi = np.ones(1)
        k = self._coef @ phi                       # complex amplitude per frequency at v
        w = 2 * np.pi * self._freqs * x
        output.SetAtIndex(0, float(np.sum(k.real * np.cos(w) + k.imag * np.sin(w))))
