"""Diagnosis fixes of issue 16 found on the independent testbench (drake_est.diagnose.testbench):

* a coarse torque ADC: the quantization guard bounds what fitting the rounding error can do per sample,
  (step / 2)^2, instead of asking every finding to move the prediction by a whole step (it hid an
  asymmetric Coulomb that removed 60 % of the residual, and small ripples);
* the Stribeck law is refined continuously in (vs, delta) after its grid search (a large hump fitted with a
  vs 24 % off left a speed-shaped misfit that was named as an energy drift and a position friction);
* the speed bound of the data selection (9.9) is also at least ten times the velocity noise;
* backfitting: an abrupt change found before a position-dependent friction was in the model is searched
  again on its partial residual once it is (the change time was 5 s off and three false names followed).
"""
from __future__ import annotations

import numpy as np
import pytest

from drake_est.diagnose import diagnose
from drake_est.diagnose.core import _above_quantization
from drake_est.diagnose.nominal import select_rows
from drake_est.diagnose.testbench import generate

from conftest import bench_module


def _names(rep):
    d = rep.to_dict()
    out = set()
    for f in d["findings"]:
        out |= set(f.get("ambiguous_between", [f["effect"]]))
    return out, d


def test_quantized_asymmetric_coulomb_is_named():
    # testbench case 68: 250 Hz, 300 s, torque ADC step 0.19 N m; the asymmetry removes ~60 % of the residual
    log, _ = generate({"asymmetric_coulomb": 1.0}, seed=1068, duration=120.0, sample_rate=100.0,
                      noise="quantized", noise_std=0.0955)
    names, d = _names(diagnose(log, robot="generic", seed=0, simulate=False))
    assert "asymmetric_coulomb" in names
    assert names <= {"asymmetric_coulomb", "position_dependent_load"}


@pytest.mark.parametrize("seed", [3, 4])
def test_quantized_null_log_stays_clean(seed):
    log, _ = generate({}, seed=seed, duration=120.0, sample_rate=100.0, noise="quantized", noise_std=0.08)
    names, d = _names(diagnose(log, robot="generic", seed=0, simulate=False))
    assert names == set(), d["findings"]


def test_large_stribeck_hump_alone_is_named_with_its_shape():
    # testbench case 32: ks = 2.7 N m (100 x the noise), vs = 0.1 rad/s, delta = 2, with a 0.7 Hz disturbance
    log, truth = generate({"stribeck": 1.0, "_vs": 0.1, "time_periodic_disturbance": 1.0, "_f_hz": 0.7},
                          seed=1032, duration=120.0, sample_rate=250.0, noise="quantized", noise_std=0.027)
    names, d = _names(diagnose(log, robot="generic", seed=0, simulate=False))
    assert names == {"stribeck", "time_periodic_disturbance"}, d["findings"]
    p = next(f for f in d["findings"] if f["effect"] == "stribeck")["parameters"]
    # the slowest speed level (0.049 rad/s) is below the selection's speed bound: the shape is seen from 0.08
    # rad/s up, so vs and delta are less sharp than the names
    assert abs(p["vs"] - truth["stribeck"]["vs"]) < 0.15 * truth["stribeck"]["vs"]
    assert abs(p["delta"] - truth["stribeck"]["delta"]) < 0.5


def test_selection_speed_bound_follows_velocity_noise():
    t = np.arange(5000) * 0.01
    v = np.where((t // 5) % 2 == 0, 1.0, -1.0) * np.where(t < 25, 1.0, 0.03)
    a = np.zeros_like(v)
    mask, _, thr = select_rows(v, a, t)
    assert thr["v_min"] == pytest.approx(0.05, rel=1e-6)     # 5 % of the top speed
    assert mask[t >= 25].mean() < 0.05                         # the 0.03 level is below it
    noisy = v + np.random.default_rng(0).normal(0, 0.01, v.size)
    _, _, thr2 = select_rows(noisy, a, t)
    assert thr2["v_min"] > 0.09                               # ten times the velocity noise


def test_backfitting_moves_the_change_time():
    # testbench case 94: a change at 44.5 s with a position-dependent friction; found first at 39.5 s
    log, truth = generate({"abrupt_change": 1.0, "position_dependent_friction": 1.0}, seed=1094, duration=120.0,
                          sample_rate=100.0, noise="student_t", noise_std=0.056)
    names, d = _names(diagnose(log, robot="generic", seed=0, simulate=False))
    assert names == {"abrupt_change", "position_dependent_friction"}
    f = next(f for f in d["findings"] if f["effect"] == "abrupt_change")
    assert abs(f["parameters"]["t_change_s"] - truth["abrupt_change"]["t_change"]) < 0.5
    assert "backfitted_from_t_change_s" in f["evidence"]


def test_quantization_bound_rejects_fitting_the_rounding_error():
    """An 'extension' that predicts exactly the rounding error (|e| <= step/2) is not evidence; one that
    predicts a real 4-step effect is."""
    from types import SimpleNamespace
    rng = np.random.default_rng(0)
    n = 4000
    step = 0.2
    true = rng.uniform(-3, 3, n)
    y = step * np.round(true / step)
    val = np.zeros(n, bool)
    val[1::2] = True
    jd = SimpleNamespace(y=y, val=val, tau=y, train=~val)
    prep = SimpleNamespace(joints={1: jd}, meta={})
    fit0 = SimpleNamespace(pred={1: true}, rss_val={1: float(((y - true)[val] ** 2).sum())})
    fit_q = SimpleNamespace(pred={1: y.copy()}, rss_val={1: 0.0})           # fits the rounding exactly
    ext = SimpleNamespace(cols={1: None}, n_params=3)
    assert not _above_quantization(prep, fit0, fit_q, ext)
    effect = 4 * step * np.sin(np.arange(n) / 50.0)
    y2 = step * np.round((true + effect) / step)
    jd.y = jd.tau = y2
    prep.meta = {}
    fit0b = SimpleNamespace(pred={1: true}, rss_val={1: float(((y2 - true)[val] ** 2).sum())})
    fit1b = SimpleNamespace(pred={1: true + effect}, rss_val={1: float(((y2 - true - effect)[val] ** 2).sum())})
    assert _above_quantization(prep, fit0b, fit1b, ext)


# --- the closed-loop generator (drake_est.diagnose.testbench_loop): residuals locked to the motion -------------

def _loop_case(k):
    return bench_module("bench_diagnose_testbench").loop_log(k)


def test_motion_lines_are_the_multisine_frequencies():
    from types import SimpleNamespace
    from drake_est.diagnose.detectors import motion_lines_hz
    t = np.arange(0, 200, 0.01)
    v = 1.0 * np.sin(2 * np.pi * 0.05 * t) + 0.6 * np.sin(2 * np.pi * 0.16 * t) + 0.05 * np.sin(2 * np.pi * 0.4 * t)
    q = np.cumsum(v) * 0.01
    lines = motion_lines_hz(SimpleNamespace(t=t, v=v, q=q))
    assert np.min(np.abs(lines - 0.05)) < 0.006 and np.min(np.abs(lines - 0.16)) < 0.006
    assert np.min(np.abs(lines - 0.4)) > 0.006            # 5 % of the strongest: not a line of the motion


def test_misfit_at_a_multisine_line_is_not_a_disturbance():
    # loop case 30: a spring load and a Lorentzian Stribeck under a multisine; the misfit of the Stribeck law
    # repeats at the multisine's 0.175 Hz and was named time_periodic_disturbance (then a 2 s "thermal" drift)
    log, truth = _loop_case(30)
    names, d = _names(diagnose(log, robot="generic", seed=0, simulate=False))
    assert names == {"position_dependent_load", "stribeck"}, d["findings"]


def test_disturbance_with_a_harmonic_is_one_finding():
    # loop case 67: a 0.5 Hz force with a second harmonic; the harmonic was left over and named a ripple
    log, truth = _loop_case(67)
    names, d = _names(diagnose(log, robot="generic", seed=0, simulate=False))
    assert names == {"time_periodic_disturbance"}, d["findings"]
    f = d["findings"][0]
    assert abs(f["parameters"]["frequency_hz"] - 0.5) < 0.01
    assert any(abs(h["frequency_hz"] - 1.0) < 0.02 for h in f["parameters"].get("harmonics", []))


def test_robust_scale_is_floored_at_the_rounding_noise():
    from drake_est.diagnose.nominal import robust_scale
    rng = np.random.default_rng(0)
    e = rng.normal(0, 1.0, 5000)
    assert robust_scale(e) == pytest.approx(1.0, rel=0.05)
    assert robust_scale(e, step=0.1) == robust_scale(e)          # the MAD is above the floor: unchanged
    # a coarse ADC whose input barely moves: 91 % of the residuals on one level, the rest one step off
    step = 0.2
    e = step * np.where(rng.random(5000) < 0.91, 0.0, rng.choice([-1.0, 1.0], 5000))
    assert robust_scale(e) < step / 10
    assert robust_scale(e, step) == pytest.approx(step / np.sqrt(12.0))
    assert not np.any(np.abs(e) > 6.0 * robust_scale(e, step))  # one step is no outlier


def test_quantized_closed_loop_log_keeps_its_one_step_samples():
    """Closed-loop spec 746 (50 Hz, torque ADC step 0.178 N m, compliance planted): the nominal residual is 0 on
    91 % of the selected samples and one step off on the rest; the 6-MAD screen took all 247 of those for outliers,
    the inertia backfit went to J = 0.0007 (true 0.56) and a Stribeck law was named.  With the scale floored at the
    rounding noise nothing is screened and nothing is named."""
    log, truth = _loop_case(746)
    names, d = _names(diagnose(log, robot="generic", seed=0, simulate=False))
    assert names == set(), d["findings"]
    assert d["data"]["excluded"]["1"]["outliers"] == 0
    assert d["nominal"]["parameters"]["1"]["J"] == pytest.approx(truth["J"], rel=0.10)


def test_a_flexible_winner_is_ambiguous_with_a_rival_the_quantization_guard_held_back():
    """Closed-loop spec 1113 of the benchmark (loop_cases(1114)[1113]: a third-size asymmetric Coulomb level of
    0.16 N m, torque ADC step 0.19 N m, 1000 Hz).  The asymmetry moves the prediction by less than half a step, so
    the quantization guard holds it back (it removes 35 % of the RMSE with one parameter); a position load with
    18 parameters moved it by more somewhere and was named alone.  Judged from the asymmetry's fit by the same
    guard, the load is not ahead beyond the rounding error: the finding is ambiguous with the asymmetry."""
    from drake_est.diagnose.testbench_loop import generate as generate_loop
    log, _ = generate_loop({"asymmetric_coulomb": 1.0 / 3.0}, seed=4113, duration=120.0, sample_rate=1000.0,
                           noise="quantized", noise_std=0.09532132962178498, check_visible=False)
    names, d = _names(diagnose(log, robot="generic", seed=0, simulate=False))
    assert "asymmetric_coulomb" in names
    for f in d["findings"]:
        if f["effect"] != "asymmetric_coulomb":
            assert "asymmetric_coulomb" in f.get("ambiguous_between", []), f["effect"]
            assert f["competition"].get("separated_below_quantization_step")


def test_selection_noise_scan_alternative_keeps_the_slow_samples_of_a_smooth_10_hz_motion():
    """benchmarks/bench_selection_noise_scan.py's second-difference estimate (tried in the twenty-second round, not
    kept): on a smooth, noise-free motion at 10 Hz the library's first-difference bound leaves out the slow samples
    that the alternative keeps; on white velocity noise at 1 kHz both bounds are ten times the noise."""
    from conftest import bench_module
    S = bench_module("bench_selection_noise_scan")
    t = np.arange(1200) * 0.1
    v = np.sin(2 * np.pi * 0.1 * t)
    a = 2 * np.pi * 0.1 * np.cos(2 * np.pi * 0.1 * t)
    lib = select_rows(v, a, t)[0]
    alt = S.alternative_selection(v, a, t, "second-differences")
    assert alt.sum() > lib.sum() + 200 and not (lib & ~alt).any()
    one = S.alternative_selection(v, a, t, "second-differences-one-speed")
    assert not (one & ~alt).any()
    t = np.arange(20000) * 1e-3
    noisy = 0.12 * np.sin(2 * np.pi * 0.2 * t) + np.random.default_rng(2).normal(0, 0.01, t.size)
    zero = np.zeros_like(t)
    lib = select_rows(noisy, zero, t)[0]
    assert select_rows(noisy, zero, t)[2]["v_min"] == pytest.approx(0.1, rel=0.05)      # ten times the noise
    alt = S.alternative_selection(noisy, zero, t, "second-differences")
    assert abs(int(alt.sum()) - int(lib.sum())) < 0.02 * lib.sum()
