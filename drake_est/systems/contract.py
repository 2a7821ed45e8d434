"""The contract every drake_est ``LeafSystem`` meets (checked by ``tests/test_system_contract.py``).

Each module in :mod:`drake_est.systems` defines ``contract_cases() -> list[ContractCase]`` with at least one
case per LeafSystem class it defines.  The shared test then checks, for every case:

1. port names are lower_snake_case and each appears in the class docstring with a unit in brackets;
2. with the inputs fixed to ``inputs`` and the system simulated to ``t_final``, each output named in
   ``expected`` equals the plain algorithm's value (``expected(system)`` returns ``{port_name: array}``,
   computed with the numpy function/class the system wraps) to ``rtol``/``atol``;
3. two Contexts of one system simulated interleaved (step by step, alternately) give the same outputs as
   two separate runs: the system keeps no hidden state outside the Context.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np


@dataclass
class ContractCase:
    """One instance of a LeafSystem with fixed inputs and the outputs the plain algorithm gives.

    make:      () -> a fresh LeafSystem (called several times: cases must be deterministic).
    inputs:    {input_port_name: constant value} for every input port that must be connected
               (vector ports: array; abstract ports: the Python value).
    t_final:   simulated time [s] before outputs are compared (covers several periodic updates).
    expected:  (system) -> {output_port_name: array}: the plain algorithm's result for the same inputs
               at t_final; None when the case only checks names and hidden state.
    """
    make: Callable[[], object]
    inputs: dict = field(default_factory=dict)
    t_final: float = 0.05
    expected: Callable[[object], dict] | None = None
    rtol: float = 1e-9
    atol: float = 1e-9
    label: str = ""

    def expected_outputs(self, system) -> dict:
        if self.expected is None:
            return {}
        return {k: np.asarray(v, float) for k, v in self.expected(system).items()}
