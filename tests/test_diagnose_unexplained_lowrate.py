"""The "unexplained" verdict at low sample rates (issue 16 item 3): the reversal-impulse test of
drake_est.diagnose.unexplained (momentum balance around velocity reversals, any sample rate).

Out-of-vocabulary effects of the independent testbench (a delay between torque and position samples,
backlash) must end in ``unexplained`` at 10 Hz, where the derivative-filter tests are off; null logs must
stay clean.  The false-alarm rate over many null logs is the ``slow`` test at the end."""
from __future__ import annotations

import functools
import json
import os

import numpy as np
import pytest

from drake_est.diagnose import diagnose
from drake_est.diagnose.testbench import generate
from drake_est.diagnose.unexplained import reversal_impulse, reversal_times

os.environ.setdefault("DRAKE_EST_NO_PROGRESS", "1")


def _run(effects, seed, rate=10.0, noise="gaussian", noise_std=0.05, duration=120.0, speeds=6):
    log, truth = generate(effects, seed=seed, duration=duration, sample_rate=rate, noise=noise,
                          noise_std=noise_std, speeds=speeds)
    rep = diagnose(log, robot="generic", seed=0, simulate=False)
    res = rep.result
    res.final_fit._model = res.final_model
    return rep, res, truth


@functools.lru_cache(maxsize=None)
def _oov(effect, seed, noise):
    return _run({effect: 1.0}, seed, noise=noise, noise_std=0.04)


def _reversal_entries(rep):
    return [u for u in rep.to_dict()["unexplained"] if u["variable"] == "velocity_reversals"]


def test_reversal_times_from_positions_at_10_hz():
    """The reversal instant is the stationary point of the measured position, found between samples."""
    h = 0.1
    t = np.arange(0.0, 60.0, h)
    w = 2 * np.pi / 7.3
    q = np.sin(w * t + 0.4) + 0.2 * np.sin(3 * w * t + 1.0)
    v = w * np.cos(w * t + 0.4) + 0.6 * w * np.cos(3 * w * t + 1.0)
    first, t0 = reversal_times(t, q, v)
    # true zero crossings of v (dense grid)
    td = np.arange(0.0, 60.0, 1e-5)
    vd = w * np.cos(w * td + 0.4) + 0.6 * w * np.cos(3 * w * td + 1.0)
    true = td[np.flatnonzero(np.sign(vd[1:]) != np.sign(vd[:-1]))]
    assert first.size == t0.size and t0.size >= len(true) - 2
    err = np.array([np.min(np.abs(true - x)) for x in t0])
    assert np.max(err) < 0.01 * 7.3          # well inside a sample (0.1 s) on a 7.3 s period
    assert np.all(t[first] >= t0) and np.all(t[first - 1] < t0)


@pytest.mark.parametrize("rate, seed, tol", [(100.0, 2, 0.15), (10.0, 3, 0.6)])
def test_impulse_measures_the_delay(rate, seed, tol):
    """Nearly noise-free testbench logs: the missing impulse per reversal is the Coulomb step 2 k_c lasting
    about the planted delay (read back within 15 % at 100 Hz; at 10 Hz a one-sample delay reads back about half
    of it, its reversals are only resolved to a sample); without a delay it is below 5 % of a sample."""
    _, res, truth = _run({"delay": 1.0}, seed, rate=rate, noise_std=1e-4)
    r = reversal_impulse(res.prep, res.final_fit, 1)
    assert r is not None and r["impulse"] < 0 and r["p"] < 1e-8
    d = truth["delay"]["seconds"]
    assert abs(abs(r["impulse"]) / (2 * r["kc"]) - d) < tol * d
    _, res0, _ = _run({}, seed, rate=rate, noise_std=1e-4)
    r0 = reversal_impulse(res0.prep, res0.final_fit, 1)
    assert abs(r0["impulse"]) / (2 * r0["kc"]) < 0.05 / rate


@pytest.mark.parametrize("effect, seed, noise", [("delay", 1104, "quantized"), ("backlash", 1103, "student_t"),
                                                 ("backlash", 1145, "student_t")])
def test_out_of_vocabulary_at_10_hz_is_unexplained(effect, seed, noise):
    """Delay and backlash at 10 Hz: no vocabulary name, an ``unexplained`` entry at the velocity reversals
    that says where it lies (window, torque missing) and how much of the variance it holds."""
    rep, _, _ = _oov(effect, seed, noise)
    d = rep.to_dict()
    assert d["findings"] == []
    (u,) = _reversal_entries(rep)
    assert u["p_value"] < 1e-6 and u["impulse_per_reversal"] < 0 and "missing" in u["where"]
    assert 0.03 <= u["share_of_residual_variance"] <= 1.0
    assert u["window_s"] > 0 and u["reversals"] >= 12
    assert len(u["profile_time_s"]) == len(u["profile_mean_residual"]) > 4


@pytest.mark.parametrize("seed, noise", [(0, "gaussian"), (1, "student_t"), (2, "quantized")])
def test_null_logs_at_10_hz_stay_clean(seed, noise):
    rep, res, _ = _run({}, 300 + seed, noise=noise, noise_std=0.02 + 0.015 * seed)
    assert rep.to_dict()["unexplained"] == []
    r = reversal_impulse(res.prep, res.final_fit, 1)
    assert r is not None and r["p"] > 1e-4         # tested, and not significant


def test_one_speed_is_untestable():
    """All reversals of one size: a constant impulse deficit cannot be told from an inertia error."""
    _, res, _ = _run({"delay": 1.0}, 5, speeds=1)
    assert reversal_impulse(res.prep, res.final_fit, 1) is None


def test_robot_models_are_not_tested():
    """IRB140 models compute the rigid-body torque only at the selected rows: the test does not apply."""
    from types import SimpleNamespace
    prep = SimpleNamespace(robot=object(), joints={1: None})
    assert reversal_impulse(prep, SimpleNamespace(), 1) is None


def test_report_files_show_it(tmp_path):
    rep, _, _ = _oov("backlash", 1103, "student_t")
    rep.write(tmp_path)
    d = json.loads((tmp_path / "report.json").read_text())
    assert any(u["variable"] == "velocity_reversals" for u in d["unexplained"])
    assert (tmp_path / "unexplained.png").stat().st_size > 1000
    assert "velocity_reversals" in (tmp_path / "report.md").read_text()


@pytest.mark.slow
@pytest.mark.xfail(strict=False, reason="known, measured 2026-11-23: 1 of these 84 null logs is flagged (50 Hz, "
                   "generator seed 5103: impulse +0.004 N m s, p = 6e-5, the same for a reversal-instant tolerance "
                   "of 0.1-0.5 samples); an O(h^2) discretization residue at the window ends is not bounded yet")
def test_false_alarm_rate_on_many_null_logs():
    """60 null testbench logs at 10 Hz (Gaussian, Student-t, quantized) and 24 at 50-250 Hz: the reversal test
    (p < 1e-3 / tests) flags none; its p-values are not concentrated near 0 (at most 3 of 84 below 0.01
    where 0.84 are expected)."""
    flagged, ps = 0, []
    specs = [(10.0, s) for s in range(60)] + [(r, 100 + s) for r in (50.0, 100.0, 250.0) for s in range(8)]
    for rate, s in specs:
        rng = np.random.default_rng(s)
        rep, res, _ = _run({}, 5000 + s, rate=rate, noise=["gaussian", "student_t", "quantized"][s % 3],
                           noise_std=float(rng.uniform(0.02, 0.1)))
        flagged += bool(_reversal_entries(rep))
        r = reversal_impulse(res.prep, res.final_fit, 1)
        if r is not None:
            ps.append(r["p"])
    assert flagged == 0
    assert len(ps) >= 70 and sum(p < 0.01 for p in ps) <= 3


@pytest.mark.long
def test_stribeck_entry_says_the_selection_left_the_slow_samples_out():
    """Closed-loop spec 4980 (10 Hz: a position load and a Lorentzian Stribeck law, every moving sample below 2 vs).
    The selection's speed bound is ten times the velocity's sample-to-sample change (46 % of the top speed), so the
    Stribeck law is untestable although the log moves slowly: the next-experiment entry says so, with the bound and
    how many slow samples it left out, and the rate at which the same motion would be selected down to 5 % of the top
    speed (93 Hz); logged at that rate, Stribeck is named.  A 250 Hz log's bound is 5 % of its top speed and its
    entries carry no note."""
    from conftest import bench_module
    B = bench_module("bench_diagnose_testbench")
    log, _ = B.loop_log(4980)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    e = next(x for x in d["next_experiment"] if x["reason"].startswith("stribeck untestable"))
    assert "sample-to-sample change of the velocity at 10 Hz" in e["reason"]
    assert 0.3 < e["selection_speed_bound_share_of_top_speed"] < 0.7
    assert e["slow_samples_left_out"] > 100
    assert e["selection_speed_bound"] == pytest.approx(d["data"]["selection"]["1"]["v_min"])
    # the same motion logged at the rate the entry asks for: the bound is 5 % of the top speed and Stribeck is named
    fs = e["sample_rate_hz_needed"]
    assert 60 <= fs <= 150 and f"logged at {fs:.0f} Hz or faster" in e["experiment"]
    spec = dict(B.loop_cases(4981)[4980], sample_rate=fs)
    log2, truth2 = B.loop_log(spec)
    d2 = diagnose(log2, robot="generic", seed=0, simulate=False).to_dict()
    assert not any("selection_speed_bound" in x for x in d2["next_experiment"])      # bound at 5 % of the top speed
    assert "stribeck" in {f["effect"] for f in d2["findings"]}
    log, _ = B.loop_log(4543)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert not any("selection_speed_bound" in x for x in d["next_experiment"])


def test_next_experiment_rate_benchmark_json_agrees_with_its_rows_the_kept_rows_and_the_docs():
    """benchmarks/bench_next_experiment_rate.py's kept JSON: its summary is what its rows give, it covers every kept
    row where a planted Stribeck law was missed in the kept JSONs it read (a kept row changed since would show here; a
    block added later is not among them), and the docs quote it."""
    from pathlib import Path

    from conftest import bench_module
    root = Path(__file__).resolve().parents[1]
    R = bench_module("bench_next_experiment_rate")
    s = json.loads((root / "benchmarks" / "results" / "next_experiment_rate.json").read_text())
    assert R.summarize(s["rows"]) == s["summary"]
    misses = {(f, k) for f, k, kind in R.logs_to_check(jsons=s["kept_jsons"]) if kind == "miss"}
    # rows whose kept row stopped being a Stribeck miss after the script ran stay as measured, listed (with a note)
    gone = {(f, k) for f, k in s.get("no_longer_missed", [])}
    assert not gone & misses
    assert all(f"note_{k}" in s for _, k in gone)
    assert {(r["family"], r["k"]) for r in s["rows"] if r["kind"] == "miss"} - gone == misses
    m = s["summary"]["miss"]
    assert m["at_that_rate_wrong_names"] == 0 == s["summary"]["null"]["at_that_rate_wrong_names"]
    doc = (root / "docs" / "readme" / "diagnose_testbench.md").read_text()
    assert (f"at that rate {m['at_that_rate_stribeck_named']} of the {m['asking_for_a_faster_log']} name the Stribeck "
            "law") in " ".join(doc.split())


@pytest.mark.parametrize("rate, off", [(10.0, {"jerk_excluded_samples", "time_shift_torque_vs_position",
                                               "snap_excluded_samples", "jerk_snap_matched_filter"}),
                                       (50.0, {"snap_excluded_samples", "jerk_snap_matched_filter"}),
                                       (60.0, None), (100.0, None)])
def test_next_experiment_names_the_residual_tests_a_long_derivative_window_turns_off(rate, off):
    """Below 60 Hz the 7-sample derivative window spans more than 0.1 s (0.2 s below 35 Hz) and some tests of the
    final residual (those that see a delay, backlash or an elastic gear) do not run: the report says which, that they
    run from 60 Hz, and asks for 100 Hz (the tests that ran are those the readings list)."""
    rep, res, _ = _run({}, seed=5, rate=rate)
    d = rep.to_dict()
    e = [x for x in d["next_experiment"] if x.get("tests_off")]
    ran = {r["variable"] for r in res.structure_readings}
    if off is None:
        assert e == []
        assert {"jerk_excluded_samples", "time_shift_torque_vs_position"} <= ran
        return
    assert len(e) == 1 and set(e[0]["tests_off"]) == off and not off & ran
    assert e[0]["sample_rate_hz_needed"] == 60.0 and e[0]["sample_rate_hz_suggested"] == 100.0
    assert "logged at 100 Hz or faster" in e[0]["experiment"]


@pytest.mark.parametrize("name, at_rate", [("next_experiment_rate_residual_tests.json", None),
                                           ("next_experiment_rate_residual_tests_100hz.json", 100.0)])
def test_residual_tests_rate_benchmark_jsons_agree_with_their_rows_the_kept_rows_and_the_docs(name, at_rate):
    """bench_next_experiment_rate.py --entry residual-tests (at the rate asked for, and at 100 Hz): the summary is
    what the rows give, the rows cover the kept out-of-vocabulary logs below 60 Hz that did not end as `unexplained`
    and the kept null logs below 60 Hz (of the kept JSONs it read), no log gains a wrong name, and the docs quote the counts."""
    from pathlib import Path

    from conftest import bench_module
    root = Path(__file__).resolve().parents[1]
    R = bench_module("bench_next_experiment_rate")
    s = json.loads((root / "benchmarks" / "results" / name).read_text())
    assert R.summarize(s["rows"]) == s["summary"] and s.get("at_rate") == at_rate
    want = {(f, k, kind) for f, k, kind in R.logs_to_check(entry="residual-tests", jsons=s["kept_jsons"])}
    assert {(r["family"], r["k"], r["kind"]) for r in s["rows"]} == want
    o, n = s["summary"]["oov"], s["summary"]["null"]
    assert o["at_that_rate_wrong_names"] == 0 == n["at_that_rate_wrong_names"]
    doc = " ".join((root / "docs" / "readme" / "diagnose_testbench.md").read_text().split())
    assert f"{o['at_that_rate_unexplained']} of the {o['asking_for_a_faster_log']}" in doc
