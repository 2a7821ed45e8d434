"""A friction law of the speed must show where the axis slides into a stop or a reversal
(competition.survives_both_speed_changes): a Stribeck excess that only the samples leaving a standstill or a reversal
show is a transient there, not a law of the sliding speed."""
import numpy as np
import pytest

from conftest import bench_module, nominal_candidates
from drake_est.diagnose import competition as comp
from drake_est.diagnose import core


def _slow_excess(jd, height, only=None):
    """A friction excess height * exp(-(qd / vs)^2) sign(qd) over the whole log, vs a third of the median selected
    speed; ``only="up"``: only where a * qd > 0 (speeding up), ``only="down"``: only where a * qd <= 0."""
    vs = np.median(np.abs(jd.v[jd.rows])) / 3.0
    g = height * np.exp(-(jd.v / vs) ** 2) * np.sign(jd.v)
    up = jd.a * jd.v > 0
    return g if only is None else g * (up if only == "up" else ~up)


def _stribeck_candidate(prep):
    model = core.Model(prep)
    fit = model.fit()
    cands = {e.effect: e for e in core._candidates(prep, model, fit, set())}
    return model, fit, cands["stribeck"]


def test_speeding_up_is_acceleration_along_the_velocity():
    prep, _, _ = nominal_candidates({}, seed=3)
    jd = prep.joints[1]
    up = comp.speeding_up(prep, 1)
    assert up.shape == (jd.rows.size,) and up.dtype == bool
    a, v = jd.a[jd.rows], jd.v[jd.rows]
    assert np.array_equal(up, a * v > 0)
    # a back-and-forth motion passes its speeds both ways: neither side is rare
    assert 0.2 < up.mean() < 0.8


def test_a_stribeck_law_holds_on_both_sides():
    """An excess that depends on the speed alone is seen speeding up and slowing down: the test keeps it."""
    prep, _, _ = nominal_candidates({}, seed=11)
    jd = prep.joints[1]
    jd.tau = jd.tau + _slow_excess(jd, 0.6)
    model, fit, ext = _stribeck_candidate(prep)
    t = comp.survives_both_speed_changes(prep, model, fit, ext, core.ALPHA, core.MIN_GAIN,
                                         solve=core._model_solver(model, 1))
    assert "skipped" not in t
    assert t["significant"]
    assert t["slowing_down"]["significant"] and t["speeding_up"]["significant"]
    assert t["slowing_down"]["scale"] == pytest.approx(1.3, abs=0.4)


def test_an_excess_only_on_leaving_standstill_is_set_aside():
    """The same excess only while the axis speeds up (a transient out of a reversal): the plain held-out test of the
    Stribeck candidate is significant, but its law on the samples slowing down adds nothing given the law on those
    speeding up, and the candidate is not a law of the speed."""
    prep, _, _ = nominal_candidates({}, seed=11)
    jd = prep.joints[1]
    jd.tau = jd.tau + _slow_excess(jd, 0.6, only="up")
    model, fit, ext = _stribeck_candidate(prep)
    solve = core._model_solver(model, 1)
    plain = comp._partial_test(prep, model, 1, np.zeros((jd.rows.size, 0)), ext.cols[1], core.ALPHA, core.MIN_GAIN,
                               solve)
    assert plain["significant"]
    t = comp.survives_both_speed_changes(prep, model, fit, ext, core.ALPHA, core.MIN_GAIN, solve=solve)
    assert not t["significant"]
    # the slowing-down rows take the curve with a negative scale only (the bias the excess leaves in the nominal
    # Coulomb and viscous fit), the speeding-up rows with a positive one
    assert t["slowing_down"]["scale"] < 0 and not t["slowing_down"]["significant"]
    assert t["speeding_up"]["p_value"] < core.ALPHA and t["speeding_up"]["scale"] > 0


def test_an_excess_only_while_sliding_into_a_stop_is_kept():
    """The reverse is not asked: the same excess only while the axis slows down stands (planted laws in closed loop
    often show there and not where the axis speeds up, loop specs 7378, 1438, 2563)."""
    prep, _, _ = nominal_candidates({}, seed=11)
    jd = prep.joints[1]
    jd.tau = jd.tau + _slow_excess(jd, 0.6, only="down")
    model, fit, ext = _stribeck_candidate(prep)
    t = comp.survives_both_speed_changes(prep, model, fit, ext, core.ALPHA, core.MIN_GAIN,
                                         solve=core._model_solver(model, 1))
    assert t["significant"]
    assert t["slowing_down"]["scale"] > 0
    assert not t["speeding_up"]["significant"]


def test_the_test_applies_to_speed_laws_with_both_sides_only():
    prep, _, cands = nominal_candidates({"asymmetric_coulomb": 1.0}, seed=5)
    model = core.Model(prep)
    t = comp.survives_both_speed_changes(prep, model, model.fit(), cands["asymmetric_coulomb"], core.ALPHA,
                                         core.MIN_GAIN)
    assert t["significant"] and "skipped" in t
    # a side with too few rows: every row counted as speeding up
    prep, _, _ = nominal_candidates({}, seed=11)
    jd = prep.joints[1]
    jd.tau = jd.tau + _slow_excess(jd, 0.6)
    model, fit, ext = _stribeck_candidate(prep)
    jd.a = np.abs(jd.a) * np.sign(jd.v)
    t = comp.survives_both_speed_changes(prep, model, fit, ext, core.ALPHA, core.MIN_GAIN)
    assert t["significant"] and "too few rows" in t["skipped"]


def test_the_report_says_which_side_holds_it():
    from drake_est.diagnose import diagnose
    from drake_est.diagnose.report import markdown, rejection_reason
    from drake_est.diagnose.testbench import generate
    log, _ = generate({"asymmetric_coulomb": 1.0}, seed=2, duration=60.0, sample_rate=100.0, noise_std=0.05)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    c = d["findings"][0].setdefault("competition", {})
    c.setdefault("runner_up", "position_dependent_load")
    c.setdefault("runner_up_joint", 1)
    c["explained_by_periodic_residual"] = [{"effect": "stribeck", "joint": 1, "explained_by": "one_speed_change",
                                            "p_value": 0.13, "scale": -0.66}]
    md = markdown(d)
    assert ("Set aside: `stribeck` (joint 1) holds only where the joint speeds up out of a standstill or a "
            "reversal") in md
    assert "scale -0.66, held-out F-test p = 0.13)" in md
    assert rejection_reason({"explained_by_one_speed_change": True}) == \
        "only the samples speeding up out of a standstill or a reversal show it"


@pytest.mark.parametrize("ulps", [0, 3])
def test_loop_case_7981_null_log_names_no_stribeck(ulps):
    """Closed-loop spec 7981, a null log at 1000 Hz (Gaussian noise).  A Stribeck hump at 0.025 rad/s lowered the
    held-out RMSE by 2.1 % (p = 1e-124) and was named; its gain lies in the slow samples just after reversals, while
    the axis speeds up, and the slow samples slowing down into a stop lose by it.  Set aside: nothing is named."""
    from drake_est.diagnose import diagnose
    log, truth = bench_module("bench_diagnose_testbench").loop_log(7981, reference_ulps=ulps)
    assert truth["effects"] == []
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert d["findings"] == []
    st = [r for r in d["not_found"] if r["effect"] == "stribeck"]
    assert st and st[0].get("explained_by_one_speed_change")

