"""benchmarks/last_digits_plugin.py: the development plugin that moves the diagnosis' input by a few ulps (another
CPU's last digits) acts on the generator's reference and on the prepared torque, and leaves the caller's log alone."""
import numpy as np
import pytest

from conftest import bench_module


def _plugin():
    return bench_module("last_digits_plugin")


def test_install_moves_the_reference_and_the_prepared_torque(monkeypatch):
    import drake_est.diagnose.core as core
    import drake_est.diagnose.nominal as nominal
    import drake_est.diagnose.testbench_loop as loop
    from drake_est.diagnose.testbench import generate as open_loop

    for m, name in ((loop, "generate"), (nominal, "prepare"), (core, "prepare")):
        monkeypatch.setattr(m, name, getattr(m, name))    # restored after the test
    gen = loop.generate
    plugin = _plugin()
    plugin.install(0, 0)
    assert loop.generate is gen                           # k = 0 wraps nothing
    plugin.install(2, 3)
    kw = dict(effects={}, seed=3, duration=5.0, sample_rate=100, check_visible=False)
    moved, _ = loop.generate(**kw)
    assert np.array_equal(moved.tau, gen(**kw, reference_ulps=2)[0].tau)
    assert not np.array_equal(moved.tau, gen(**kw)[0].tau)
    assert np.array_equal(loop.generate(**kw, reference_ulps=0)[0].tau, gen(**kw)[0].tau)   # an explicit value wins
    log, _ = open_loop({"stribeck": 1.0}, seed=1, duration=30.0, sample_rate=100)
    tau = log.tau.copy()
    jd = core.prepare(log).joints[1]
    rel = np.abs(jd.tau / tau[:, 0] - 1.0)[tau[:, 0] != 0]
    assert 0 < rel.max() <= 4 * 2.0 ** -52
    assert np.array_equal(log.tau, tau)                   # the caller's log is not touched


def test_bad_environment_values_are_one_line_errors(monkeypatch):
    plugin = _plugin()
    for bad, words in (("x", "integer"), ("-1", "0..1024"), ("5000", "0..1024")):
        monkeypatch.setenv("TAU_ULPS", bad)
        with pytest.raises(SystemExit) as e:
            plugin._ulps("TAU_ULPS")
        assert "TAU_ULPS" in str(e.value) and words in str(e.value) and "\n" not in str(e.value)
