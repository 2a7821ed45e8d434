"""A time-periodic disturbance at a line of the motion (thirty-third round): the scan's peak there is a candidate held
against a free function of the state (competition.survives_state_law), and a law of the state that adds nothing to
such a set-aside sinusoid is ambiguous with it (competition.law_confounded_with_time, core._time_confound)."""
import numpy as np
import pytest

from drake_est.diagnose import core, competition as comp, detectors as det
from drake_est.diagnose import diagnose
from drake_est.diagnose.core import Model, prepare
from drake_est.diagnose.testbench_loop import generate


def _nominal(log):
    prep = prepare(log, robot="generic", seed=0)
    model = Model(prep)
    return prep, model, model.fit()


def test_all_blocks_at_once_can_predict_worse_than_the_model_the_forward_choice_does_not():
    # loop spec 5775 (an asymmetric level beside a Lorentzian Stribeck law at 250 Hz, with the level and Stribeck in
    # the model): every block of the state's free function at once raised the held-out RMSE, and a candidate at a line
    # then looked significant given it
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import bench_diagnose_testbench as b
    log, _ = b.loop_log(5775, reference_ulps=3)
    prep = prepare(log, robot="generic", seed=0)
    alt = core._search(prep, core.MAX_FINDINGS, core.ALPHA, core.MIN_GAIN, {("position_dependent_load", 1)})
    m = Model(prep, [st.ext for st in alt[3][:2]])
    assert [e.effect for e in m.exts] == ["asymmetric_coulomb", "stribeck"]
    solve = core._model_solver(m, 1)
    allN = np.hstack(list(comp.state_blocks(prep, 1).values()))
    zero = np.zeros((allN.shape[0], 0))
    assert comp._partial_test(prep, m, 1, zero, allN, core.ALPHA, core.MIN_GAIN, solve)["rmse_reduction"] < -0.2
    N = comp.state_nuisance(prep, m, 1, solve=solve)
    assert comp._partial_test(prep, m, 1, zero, N, core.ALPHA, core.MIN_GAIN, solve)["rmse_reduction"] > 0.1


@pytest.mark.parametrize("f_hz,seed", [(0.04, 0), (0.04, 2), (0.04, 3), (0.06, 2)])
def test_slow_disturbance_is_named_not_a_position_law(f_hz, seed):
    # 5 to 7 periods in a 120 s closed-loop log: point-to-point moves put their dense spectral lines there, the scan
    # that skips them never offered the disturbance, and a position law (not planted) was named (0.04 Hz seeds 2
    # and 3, 0.06 Hz seed 2 with the code before this round); 0.06 Hz seed 2 also needs the finding's own candidate
    # to be the better of the two time-periodic ones when it is checked again (finding_to_set_aside)
    log, truth = generate({"time_periodic_disturbance": 1.0, "_f_hz": f_hz}, seed=seed)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    names = [f["effect"] for f in d["findings"]]
    assert names == ["time_periodic_disturbance"], names
    ev = d["findings"][0]["evidence"]
    assert abs(ev["frequency_hz"] - f_hz) < 0.05 * f_hz
    if truth["trajectory"] == "p2p":
        assert "at_motion_line_hz" in ev


def test_peak_off_the_motion_lines_gives_no_second_candidate():
    log, _ = generate({"time_periodic_disturbance": 1.0, "_f_hz": 2.0}, seed=1)
    prep, model, fit = _nominal(log)
    jd = prep.joints[1]
    r = core._residual(prep, fit, 1)
    assert det.time_periodic(jd, r) is not None
    assert det.time_periodic_at_motion_line(jd, r) is None


def test_a_position_friction_at_a_motion_line_is_not_a_disturbance():
    # a position friction under point-to-point moves: the residual peaks at a line of the motion (0.05 Hz) and a
    # sinusoid there alone lowers the held-out RMSE by a third, but a free function of the state explains it
    log, _ = generate({"position_dependent_friction": 1.0}, seed=2)
    prep, model, fit = _nominal(log)
    jd = prep.joints[1]
    e = det.time_periodic_at_motion_line(jd, core._residual(prep, fit, 1))
    assert e is not None and abs(e.evidence["at_motion_line_hz"] - e.evidence["frequency_hz"]) < 2.0 / np.ptp(jd.t)
    alone = comp._partial_test(prep, model, 1, np.zeros((jd.rows.size, 0)), e.cols[1], core.ALPHA, core.MIN_GAIN)
    assert alone["significant"] and alone["rmse_reduction"] > 0.2
    # the state's free function chosen block by block on the held-out data (here the position friction's kernels and
    # the inertia's misfits), fitted with the search's solver
    t = comp.survives_state_law(prep, model, fit, e, core.ALPHA, core.MIN_GAIN, solve=core._model_solver(model, 1))
    assert not t["significant"] and t["nuisance_columns"] >= 12
    # the round's evaluation of the candidate applies that test: not significant, marked as the state's
    sigma = {1: float(np.sqrt(fit.rss_val[1] / prep.joints[1].val.sum()))}
    _, tst, _, _ = core._evaluate(prep, model, fit, sigma, e, core.ALPHA, core.MIN_GAIN, {})
    assert tst["explained_by_state_law"] and not tst["significant"]
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert [f["effect"] for f in d["findings"]][:1] == ["position_dependent_friction"]
    assert "time_periodic_disturbance" not in [f["effect"] for f in d["findings"]]


def test_survives_state_law_applies_to_candidates_at_a_line_only():
    log, _ = generate({"time_periodic_disturbance": 1.0, "_f_hz": 2.0}, seed=1)
    prep, model, fit = _nominal(log)
    e = det.time_periodic(prep.joints[1], core._residual(prep, fit, 1))
    assert comp.survives_state_law(prep, model, fit, e, core.ALPHA, core.MIN_GAIN)["skipped"]


def test_time_confound_marks_the_law_ambiguous_with_the_disturbance():
    c = {"p_value": 0.4, "rmse_reduction": 0.001, "score": -3.0, "frequency_hz": 0.06, "at_motion_line_hz": 0.0583,
         "time_periodic_given_state": {"p_value": 0.9, "rmse_reduction": 0.0, "score": -4.0}}
    out = core._time_confound({"runner_up": "position_dependent_load", "ambiguous": True,
                               "ambiguous_with": ["position_dependent_load"]}, {"confounded_with_time": c})
    assert out["ambiguous_with"] == ["position_dependent_load", "time_periodic_disturbance"]
    assert out["confounded_with_time"] and "0.06 Hz" in out["reason"]
    assert core._time_confound({"ambiguous": False}, {}) == {"ambiguous": False}


def test_next_experiment_for_a_law_confounded_with_time():
    # the experiment that separates a law of the state from a slow disturbance: the same moves repeated half a period
    # apart, over at least 10 periods
    from types import SimpleNamespace
    from drake_est.diagnose.unexplained import next_experiments
    log, _ = generate({"time_periodic_disturbance": 1.0, "_f_hz": 0.05}, seed=2)
    prep, model, fit = _nominal(log)
    ext = det.Extension("position_dependent_friction", 1, {1: np.zeros((prep.joints[1].rows.size, 1))}, ["w0"], {}, {})
    comp_ = core._time_confound({"runner_up": None, "ambiguous": False}, {"confounded_with_time": {
        "p_value": 0.3, "rmse_reduction": 0.0, "score": -2.0, "frequency_hz": 0.05, "at_motion_line_hz": 0.05,
        "time_periodic_given_state": {"p_value": 0.8, "rmse_reduction": 0.0, "score": -3.0}}})
    out = next_experiments(prep, [SimpleNamespace(ext=ext, competition=comp_)], 120.0)
    e = next(x for x in out if x.get("reason", "").startswith("ambiguous between position_dependent_friction"))
    assert e["repeat_offset_s"] == pytest.approx(10.0) and e["duration_s"] == pytest.approx(200.0)
    assert "half a period" in e["experiment"] and "joint 1" in e["experiment"]


def test_report_shows_the_test_given_the_state(tmp_path):
    log, _ = generate({"time_periodic_disturbance": 1.0, "_f_hz": 0.04}, seed=3)
    rep = diagnose(log, robot="generic", seed=0, simulate=False)
    f = rep.to_dict()["findings"][0]
    g = f["evidence"]["given_state_function"]
    assert g["p_value"] < 1e-6 and g["rmse_reduction"] > 0.5
    from drake_est.diagnose.report import markdown
    assert "At a line of the motion" in markdown(rep.to_dict())


def test_docs_quote_the_slow_disturbance_runs():
    # the docs' numbers come from the kept JSONs of benchmarks/bench_slow_disturbance.py, before and with the round
    import json
    import sys
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    sys.path.insert(0, str(root / "benchmarks"))
    import bench_slow_disturbance as bs
    doc = (root / "docs" / "readme" / "diagnose_testbench.md").read_text()
    for name in ("diagnose_slow_disturbance_before_round33.json", "diagnose_slow_disturbance_round33.json",
                 "diagnose_slow_disturbance_round34.json"):
        d = json.loads((root / "benchmarks" / "results" / name).read_text())
        assert f"`{name}`: {bs.counts_text(d)}" in doc


def _loop(k):
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import bench_diagnose_testbench as b
    return b.loop_log(k)


def test_a_misfit_that_follows_the_moves_does_not_hold_across_the_halves():
    # loop spec 1317 (backlash at 50 Hz, out of the vocabulary): a candidate at a line of the motion, significant on
    # the whole log, predicts the first half of the log from the second with a fifth of its gain
    log, truth = _loop(1317)
    assert truth["effects"] == ["backlash"]
    prep, model, fit = _nominal(log)
    e = det.time_periodic_at_motion_line(prep.joints[1], core._residual(prep, fit, 1))
    assert e is not None
    own = comp._partial_test(prep, model, 1, np.zeros((prep.joints[1].rows.size, 0)), e.cols[1], core.ALPHA,
                             core.MIN_GAIN, core._model_solver(model, 1))
    h = comp.holds_across_halves(prep, model, e, core.ALPHA, core.MIN_GAIN, own["rmse_reduction"],
                                 solve=core._model_solver(model, 1))
    assert own["significant"] and not h["significant"]
    assert min(h["half_gains"]) < comp.HALF_GAIN_SHARE * own["rmse_reduction"]
    assert core.motion_line_gate(prep) == frozenset()


def test_backlash_whose_moves_repeat_is_a_transient_after_reversals():
    # loop spec 6641 (backlash at 50 Hz): its moves repeat, so the candidate at a line keeps its phase across the
    # halves; the transients after each reversal explain it
    log, truth = _loop(6641)
    assert truth["effects"] == ["backlash"]
    prep, model, fit = _nominal(log)
    assert "reversal" in comp.state_blocks(prep, 1)
    assert core.motion_line_gate(prep) == frozenset()
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert d["findings"] == [] and d["unexplained"]


def test_a_disturbance_at_the_block_alternation_is_found_at_a_motion_line():
    # loop spec 1629 (a 0.5 Hz disturbance at 50 Hz, quantized torque): 0.5 Hz is a line of the motion there, the
    # scan skipped it and the log ended `unexplained`
    log, truth = _loop(1629)
    prep, _, _ = _nominal(log)
    assert core.motion_line_gate(prep) == frozenset({1})
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert [f["effect"] for f in d["findings"]] == ["time_periodic_disturbance"]
    assert abs(d["findings"][0]["evidence"]["frequency_hz"] - 0.5) < 0.01


def test_at_line_candidate_frequency_is_chosen_beside_the_models_columns():
    # 0.06 Hz, seed 3 (point-to-point moves, 120 s): found on the nominal residual alone the candidate sits at
    # 0.0602 Hz, since the nominal columns take part of a disturbance at the motion's lines; chosen beside them
    # (variable projection, core.at_line_refined) it is at 0.0600 Hz
    f_true = 0.06
    log, truth = generate({"time_periodic_disturbance": 1.0, "_f_hz": f_true}, seed=3)
    assert truth["trajectory"] == "p2p"
    prep, model, fit = _nominal(log)
    jd = prep.joints[1]
    r = core._residual(prep, fit, 1)
    raw = det.time_periodic_at_motion_line(jd, r)
    assert raw is not None
    new = core.at_line_refined(raw, jd, r, model.design_with_shared(1))
    f_raw, f_new = raw.evidence["frequency_hz"], new.evidence["frequency_hz"]
    assert abs(f_raw - f_true) > 1e-4
    assert abs(f_new - f_true) < 0.25 * abs(f_raw - f_true)
    assert new.evidence["refined_from_frequency_hz"] == pytest.approx(f_raw)
    assert "at_motion_line_hz" in new.evidence
    assert core.at_line_refined(None, jd, r, model.design_with_shared(1)) is None


@pytest.mark.parametrize("f_hz,seed", [(0.04, 6), (0.06, 3), (0.08, 3)])
def test_slow_disturbance_found_off_its_frequency_left_a_position_law(f_hz, seed):
    # thirty-third round: the disturbance was named, and then a position law (not planted) for the phase misfit of a
    # frequency chosen on the residual alone (0.0602 Hz for 0.06 Hz); the thirty-fourth round chooses it beside the
    # model's columns
    log, _ = generate({"time_periodic_disturbance": 1.0, "_f_hz": f_hz}, seed=seed)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert [f["effect"] for f in d["findings"]] == ["time_periodic_disturbance"]
    assert abs(d["findings"][0]["evidence"]["frequency_hz"] - f_hz) < 2e-3 * f_hz
