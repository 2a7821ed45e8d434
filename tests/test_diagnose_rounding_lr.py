"""The sixty-sixth round's bound on a finding under a coarse torque ADC (core.gain_within_rounding with
core.rounding_lr_bound, quantization.interval_loglik_profiled): its held-out likelihood gain on the quantized readings,
each model at the noise level its held-out readings favour, must pass a likelihood-ratio test at the diagnosis' ALPHA."""
import numpy as np
import pytest
import scipy.stats

from drake_est.diagnose import core, diagnose
from drake_est.diagnose.quantization import interval_fit, interval_loglik, interval_loglik_profiled
from drake_est.diagnose.report import markdown

from conftest import closed_loop_case


def _quantized_line(n=4000, sigma=0.03, step=0.2, seed=1):
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1.0, 1.0, n)
    X = np.column_stack([np.ones(n), x])
    y = step * np.round((0.4 + 0.9 * x + rng.normal(0.0, sigma, n)) / step)
    return X, y - 0.5 * step, y + 0.5 * step


def test_the_profiled_likelihood_is_the_best_over_the_noise_level():
    X, lo, hi = _quantized_line()
    c, s = interval_fit(X, lo, hi)
    ll, s_best = interval_loglik_profiled(X, c, lo, hi)
    grid = np.exp(np.linspace(np.log(1e-3), np.log(1.0), 400))
    on_grid = [float(np.sum(interval_loglik(X, c, g, lo, hi))) for g in grid]
    assert ll >= max(on_grid) - 1e-6
    assert ll == pytest.approx(float(np.sum(interval_loglik(X, c, s_best, lo, hi))))
    # the level the readings favour is near the one the fit found on the same readings (and the truth, 0.03)
    assert s_best == pytest.approx(s, rel=0.05) and 0.02 < s_best < 0.04
    # a model that predicts worse cannot score better by the noise level it is given
    worse, _ = interval_loglik_profiled(X, c + np.array([0.05, 0.0]), lo, hi)
    assert worse < ll


def test_the_profiled_likelihood_refuses_bad_intervals():
    X, lo, hi = _quantized_line(n=50)
    with pytest.raises(ValueError, match="one row per interval"):
        interval_loglik_profiled(X, np.zeros(2), lo[:-1], hi)
    with pytest.raises(ValueError, match="hi > lo"):
        interval_loglik_profiled(X, np.zeros(2), hi, hi)


def test_the_bound_is_the_likelihood_ratio_test_at_alpha():
    for k in (1, 2, 4, 16):
        assert core.rounding_lr_bound(k) == pytest.approx(0.5 * scipy.stats.chi2.ppf(1 - core.ALPHA, k))
    assert core.rounding_lr_bound(1) == pytest.approx(7.57, abs=0.01)
    assert core.rounding_lr_bound(4) == pytest.approx(11.76, abs=0.01)
    assert core.rounding_lr_bound(4) > core.rounding_lr_bound(2) > core.rounding_lr_bound(1)
    assert core.rounding_lr_bound(2, alpha=1e-2) < core.rounding_lr_bound(2)


@pytest.mark.long
def test_a_stribeck_law_within_chance_on_the_readings_is_set_aside():
    # fresh loop spec 24500: a third-size abrupt change at 250 Hz over 300 s with a 0.165 N m torque ADC.  Before the
    # round a Stribeck law was named beside the change (ambiguous with an energy drift): 26 % lower least-squares
    # RMSE, 17.5 nats on the quantized readings at the common noise level, 5.7 at each model's own
    mod, spec, log, truth = closed_loop_case(24500)
    rep = diagnose(log, robot="generic", seed=0, simulate=False)
    d = rep.to_dict()
    j = mod.judge(spec, d)
    assert j["correct"] and not j["wrong"]
    assert [f["effect"] for f in d["findings"]] == ["abrupt_change"]
    rounding = [x for x in d["set_aside"] if x.get("within_rounding")]
    assert [(x["effect"], x["joint"]) for x in rounding] == [("stribeck", 1)]
    x = rounding[0]
    # the gain at the common level passes the forty-fifth round's 1 nat; the profiled one fails the bound
    assert x["heldout_loglik_gain"] >= core.MIN_ROUNDING_LOGLIK_GAIN
    assert x["rounding_lr_bound"] == pytest.approx(core.rounding_lr_bound(x["finding_columns"]), rel=1e-5)
    assert x["heldout_loglik_gain_profiled"] < x["rounding_lr_bound"]
    assert x["heldout_loglik_gain_profiled"] < x["heldout_loglik_gain"]
    assert "within chance" in x["reason"] and "likelihood-ratio test" in x["reason"]
    assert "likelihood-ratio test" in markdown(d)
    # the change that stays passes the bound by far
    gains = {e.effect: info for e, info in core.rounding_loglik_gains(rep.result.prep, rep.result.final_model)}
    assert gains["abrupt_change"]["heldout_loglik_gain_profiled"] > 10 * core.rounding_lr_bound(2)


def test_the_bound_is_a_parameter_of_the_check():
    # loop spec 4654 (a load at 10 Hz, quantized torque) keeps its load at the default ALPHA; at an alpha so small that
    # the bound exceeds its profiled gain the load is set aside "within chance"
    mod, spec, log, truth = closed_loop_case(4654)
    d = diagnose(log, robot="generic", seed=0, simulate=False).result
    (e, info), = list(core.rounding_loglik_gains(d.prep, d.final_model))
    prof, k = info["heldout_loglik_gain_profiled"], info["finding_columns"]
    assert prof >= core.rounding_lr_bound(k)
    assert core.gain_within_rounding(d.prep, d.final_model) is None
    alpha = float(scipy.stats.chi2.sf(2.0 * prof * 1.5, k))
    e2, why = core.gain_within_rounding(d.prep, d.final_model, alpha=alpha)
    assert e2.effect == "position_dependent_load" and "within chance" in why["reason"]
    assert why["rounding_lr_bound"] > prof


def test_the_docs_sample_numbers_are_its_json():
    # the round's probe outside its rerun (benchmarks/probe_rounding_lr_sample.py, run with the base code): the docs'
    # counts and smallest margin are read off its JSON
    from pathlib import Path

    from conftest import bench_module

    root = Path(__file__).resolve().parents[1]
    probe = bench_module("probe_rounding_lr_sample")
    s = probe.summary(probe.read([str(root / "benchmarks" / "results" / "diagnose_rounding_lr_round66_sample.json")]))
    assert s["logs"] == 400 and not s["decided_otherwise"]
    ratio, k, effect, planted, gain, cols = s["smallest"][0]
    doc = " ".join((root / "docs" / "readme" / "diagnose_testbench.md").read_text().split())
    assert f"({s['calls']} calls of the check)" in doc
    assert f"the smallest profiled gain was {ratio:.1f} times its bound" in doc
    assert planted and f"at {gain:.1f} nats on {cols} columns" in doc
