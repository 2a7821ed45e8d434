"""A finding that a linear response to the acceleration explains (an elastic gear's resonance, out of the vocabulary)
is not named (sixty-first round: core.finding_explained_by_linear_response)."""
import numpy as np
import pytest

from drake_est.diagnose import core, diagnose
from drake_est.diagnose.core import ALPHA, MIN_GAIN, Model

from conftest import closed_loop_case


@pytest.fixture(scope="module")
def compliance():
    # loop spec 18456: an elastic gear (a lightly damped 6.4 Hz resonance, encoder on the motor) at 1000 Hz; before the
    # sixty-first round a position load took part of the torque the resonance adds
    _, _, log, truth = closed_loop_case(18456)
    assert truth["effects"] == ["compliance"]
    return diagnose(log, robot="generic", seed=0, simulate=False), truth


def test_the_resonance_is_not_named_a_load(compliance):
    rep, _ = compliance
    assert rep.effects == []
    d = rep.to_dict()
    assert "acceleration" in [u["variable"] for u in d["unexplained"]]
    aside = [s for s in d["set_aside"] if s.get("explained_by_linear_response")]
    assert [(s["effect"], s["joint"]) for s in aside] == [("position_dependent_load", 1)]
    why = aside[0]
    # one way: the load given the response gains nothing significant, the response given the load does
    t = why["finding_given_linear_response"]
    assert not (t["p_value"] < ALPHA and t["rmse_reduction"] >= MIN_GAIN)
    assert why["linear_response_given_finding"]["p_value"] < ALPHA
    assert why["linear_response_given_finding"]["rmse_reduction"] > 0.1
    assert why["heldout_rmse_reduction_alone"] > MIN_GAIN
    assert why["linear_response_taps"] == 30 and why["linear_response_span_s"] == core.LINEAR_RESPONSE_SPAN_S
    assert "a linear response of joint 1 to its acceleration" in why["reason"]


def test_the_response_columns_are_delayed_accelerations(compliance):
    rep, _ = compliance
    prep = rep.result.prep
    jd = prep.joints[1]
    N = core.linear_response_nuisance(prep, 1)
    a = np.asarray(jd.a, float)
    rows = np.arange(a.size)[jd.rows]
    assert N.shape == (rows.size, core.LINEAR_RESPONSE_TAPS)
    np.testing.assert_array_equal(N[:, 0], a[rows])
    # the last column lags the acceleration by the span (1 s at 1000 Hz: 1000 samples), the first value before it
    lag = int(round(core.LINEAR_RESPONSE_SPAN_S * 1000.0))
    late = rows >= lag
    np.testing.assert_array_equal(N[late, -1], a[rows[late] - lag])
    np.testing.assert_array_equal(N[~late, -1], a[0])
    # few samples: no more lags than samples in the span
    assert core.linear_response_nuisance(prep, 1, span=0.003).shape[1] == 4


def test_the_check_needs_an_acceleration_entry(compliance, monkeypatch):
    # or, since the seventy-eighth round (core.LINEAR_RESPONSE_ON_TIME_CORRELATION), a time_correlation entry
    rep, _ = compliance
    prep = rep.result.prep
    cands = core._candidates(prep, Model(prep), Model(prep).fit(), set())
    load = [e for e in cands if e.effect == "position_dependent_load"][0]
    model = Model(prep, [load])
    un = rep.to_dict()["unexplained"]
    got = core.finding_explained_by_linear_response(prep, model, un, ALPHA, MIN_GAIN)
    assert got is not None and got[0] is load
    no_acc = [u for u in un if u["variable"] != "acceleration"]
    assert "time_correlation" in [u["variable"] for u in no_acc]
    got = core.finding_explained_by_linear_response(prep, model, no_acc, ALPHA, MIN_GAIN)
    assert got is not None and got[0] is load
    assert core.finding_explained_by_linear_response(
        prep, model, [u for u in no_acc if u["variable"] != "time_correlation"], ALPHA, MIN_GAIN) is None
    monkeypatch.setattr(core, "LINEAR_RESPONSE_ON_TIME_CORRELATION", False)
    assert core.finding_explained_by_linear_response(prep, model, no_acc, ALPHA, MIN_GAIN) is None


def test_a_planted_disturbance_is_not_held_against_the_response():
    # loop spec 6953: a time-periodic disturbance at 100 Hz forces the axis at its own frequency, and a filter of the
    # acceleration replays the torque that moved it (the sixty-first round set it aside); the check holds only smooth
    # laws of the position and speed against the response
    _, _, log, truth = closed_loop_case(6953)
    rep = diagnose(log, robot="generic", seed=0, simulate=False)
    assert rep.effects == truth["effects"] == ["time_periodic_disturbance"]
    d = rep.to_dict()
    assert "acceleration" in [u["variable"] for u in d["unexplained"]]
    assert not [s for s in d["set_aside"] if s.get("explained_by_linear_response")]
    prep, model = rep.result.prep, rep.result.final_model
    e = model.exts[0]
    assert e.effect not in core.LINEAR_RESPONSE_EFFECTS
    assert core._explained_one_way(prep, model, e, core.linear_response_nuisance(prep, e.joint), ALPHA,
                                   MIN_GAIN) is not None
    assert core.finding_explained_by_linear_response(prep, model, d["unexplained"], ALPHA, MIN_GAIN) is None
