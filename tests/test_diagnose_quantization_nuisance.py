"""The rounding error of a quantized torque as a nuisance of the left-out-sample tests (fourteenth round).

A coarse torque ADC with little noise before it leaves a deterministic error, a sawtooth in the torque level with
period one ADC step.  The jerk, snap and time-shift tests regress its first harmonics in the model torque out
(``unexplained.quantization_nuisance``) instead of hiding every structure below one step (the ANOVA tests keep
that guard, and so do these tests where the derivative window is longer than 0.1 s)."""
from __future__ import annotations

import numpy as np

import drake_est.diagnose.unexplained as U
from drake_est.diagnose import diagnose

from conftest import bench_module


def _loop_spec(k, report=False):
    loop_log = bench_module("bench_diagnose_testbench").loop_log
    log, truth = loop_log(k)
    rep = diagnose(log, robot="generic", seed=0, simulate=False)
    return (rep.to_dict(), truth, rep) if report else (rep.to_dict(), truth)


def test_quantization_nuisance_carries_the_rounding_error_of_a_slowly_dithered_adc():
    rng = np.random.default_rng(3)
    step = 0.2
    tau = np.cumsum(rng.normal(0, 0.01, 20000)) + 1.3          # a torque level that wanders over many steps
    X = np.column_stack([np.ones(tau.size), U.quantization_nuisance(tau, step)])
    assert X.shape == (tau.size, 1 + 2 * U.QUANT_HARMONICS)

    def left(err):
        return np.var(err - X @ np.linalg.lstsq(X, err, rcond=None)[0]) / np.var(err)

    # no noise before the ADC: a sawtooth; its first three harmonics leave 1 - (6 / pi^2)(1 + 1/4 + 1/9) = 17 % of its
    # variance
    assert left(step * np.round(tau / step) - tau) < 0.2
    # a little noise before the ADC (0.15 step, the loop generator's) leaves part of the error deterministic
    assert left(step * np.round((tau + rng.normal(0, 0.15 * step, tau.size)) / step) - tau) < 0.85
    # a white error that does not follow the torque level is left alone
    assert left(rng.normal(0, step / 4, tau.size)) > 0.99
    assert U.quantization_nuisance(tau, 0.0) is None


def test_a_quantized_sensor_delay_is_reported_without_the_guard_and_hidden_with_it(monkeypatch, tmp_path):
    """Loop spec 373 (250 Hz, quantized torque, a delay between torque and position samples): the time-shift and
    jerk tests see it at a fraction of an ADC step, once the rounding error is a nuisance; with the one-step guard
    on every test (as before) it ended as "none".  Each entry says so, and carries the profile its plot shows (the
    mean residual over bins of the jerk, or of the odd model-torque difference at the best shift)."""
    d, truth, rep = _loop_spec(373, report=True)
    assert truth["effects"] == ["sensor_delay"]
    assert d["findings"] == []
    got = {u["variable"]: u for u in d["unexplained"]}
    assert {"time_shift_torque_vs_position", "jerk_excluded_samples"} <= set(got)
    for u in got.values():
        if u["variable"] in U.QUANTIZATION_NUISANCE_TESTS:
            assert u["adc_step"] > 0 and "rounding error of the quantized torque" in u["test"], u
    for name, key in (("jerk_excluded_samples", "profile_jerk"), ("time_shift_torque_vs_position",
                                                                  "profile_torque_difference")):
        x, m = got[name][key], got[name]["profile_mean_residual"]
        assert len(x) == len(m) >= 10 and np.all(np.diff(x) > 0)
    # a delay: the residual follows the odd difference, with opposite signs at its two ends
    m = got["time_shift_torque_vs_position"]["profile_mean_residual"]
    assert m[0] * m[-1] < 0
    out = rep.write(tmp_path)
    assert (out / "unexplained.png").stat().st_size > 10_000
    monkeypatch.setattr(U, "QUANTIZATION_NUISANCE_TESTS", ())
    d1, _ = _loop_spec(373)
    assert d1["findings"] == [] and d1["unexplained"] == [], d1["unexplained"]


def test_quantized_null_logs_stay_clean():
    """Loop spec 238 (250 Hz, quantized, nothing planted): clean with the rounding error as a nuisance and no guard;
    loop spec 700 (50 Hz, quantized, nothing planted) keeps the guard (derivative window 0.12 s) and is clean, though
    its time-shift test holds 4.4 % of structure that is there with the noise-free torque command too."""
    for k in (238, 700):
        d, truth = _loop_spec(k)
        assert truth["effects"] == []
        assert d["findings"] == [] and d["unexplained"] == [], (k, d["unexplained"])
