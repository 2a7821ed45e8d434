"""A pytest plugin that moves the last digits of the diagnosis' input, as another CPU would.

The same code and package versions give last digits that differ between CPUs (vectorized math libraries round
differently); a closed loop and an encoder carry them into a generated log, and a decision taken near a test's
level can then flip.  A test that follows one log across such a level passes on one machine and fails on another.
This plugin finds those tests on one machine:

    ULPS=3 PYTHONPATH=benchmarks pytest -p last_digits_plugin tests/test_diagnose_set_aside.py
    TAU_ULPS=2 PYTHONPATH=benchmarks pytest -p last_digits_plugin tests/test_diagnose.py

- ``ULPS=k``: every ``testbench_loop.generate`` call that does not set ``reference_ulps`` gets k (the position
  reference scaled by 1 + k 2^-52; a test that checks the default itself fails by design);
- ``TAU_ULPS=k``: every log that ``nominal.prepare`` receives has its torque scaled by 1 + k 2^-52 first (reaches the
  open-loop, synth, multi-log and real-data tests too).

Not loaded by the default test run (it lives outside ``tests/``)."""
from __future__ import annotations

import copy
import functools
import os

import numpy as np

import drake_est.diagnose.core as _core
import drake_est.diagnose.nominal as _nominal
import drake_est.diagnose.testbench_loop as _loop


def _ulps(name: str) -> int:
    raw = os.environ.get(name, "0")
    try:
        k = int(raw)
    except ValueError:
        raise SystemExit(f"{name}: expected an integer number of ulps, got {raw!r}") from None
    if not 0 <= k <= 1024:
        raise SystemExit(f"{name}: expected 0..1024 ulps, got {k}")
    return k


def scaled_torque(log, k: int):
    """A shallow copy of ``log`` whose torque is scaled by (1 + k 2^-52) (``log`` itself unchanged)."""
    if not k or log.tau is None:
        return log
    out = copy.copy(log)
    out.tau = np.asarray(log.tau, float) * (1.0 + k * 2.0 ** -52)
    return out


def install(reference_ulps: int, tau_ulps: int) -> None:
    """Wrap the generator and ``prepare`` (idempotent for k = 0: nothing is wrapped)."""
    if reference_ulps:
        gen = _loop.generate

        @functools.wraps(gen)
        def generate(*a, **kw):
            kw.setdefault("reference_ulps", reference_ulps)
            return gen(*a, **kw)

        _loop.generate = generate
    if tau_ulps:
        prep = _nominal.prepare

        @functools.wraps(prep)
        def prepare(log, *a, **kw):
            return prep(scaled_torque(log, tau_ulps), *a, **kw)

        _nominal.prepare = prepare
        _core.prepare = prepare


def pytest_configure(config):
    import pytest
    try:
        ref, tau = _ulps("ULPS"), _ulps("TAU_ULPS")
    except SystemExit as e:
        raise pytest.UsageError(str(e)) from None
    install(ref, tau)
    if ref or tau:
        print(f"last_digits_plugin: reference moved by {ref} ulps, torque by {tau} ulps")
