"""A Stribeck law beside an abrupt change must hold on both sides of the change (fifty-first round:
core.stribeck_on_one_side_of_change): a friction hump of the contact (Sec. 9.1) does not vanish when the Coulomb and
viscous levels change, so a law whose gain lies after the change only has taken the change's misfit there."""
import pytest

from drake_est.diagnose import core
from drake_est.diagnose.core import Model, run_diagnosis

from conftest import bench_module, closed_loop_case, search_names


def _model_with_stribeck_beside_change(d):
    kinds = {e.effect for e in d.final_model.exts}
    return {"stribeck", "abrupt_change"} <= kinds


@pytest.mark.parametrize("ulps", [0, pytest.param(3, marks=pytest.mark.long)])
def test_loop_case_16580_stribeck_after_a_change_only_is_set_aside(monkeypatch, ulps):
    # loop spec 16580: a third-size abrupt change at 100 Hz with a quantized torque; before the fifty-first round
    # Stribeck was named beside it, its gain all after the change (where the change's viscous part was fitted on
    # slow rows); also at 3 ulps of the position reference (another CPU's last digits)
    mod, spec, log, _ = closed_loop_case(16580, reference_ulps=ulps)
    planted = {e for e in spec["effects"] if not e.startswith("_")}
    assert planted == {"abrupt_change"}
    d = run_diagnosis(log, robot="generic")
    assert set(search_names(d)) == {"abrupt_change"}
    side = [x for x in d.prep.meta["set_aside"] if x.get("one_side_of_change")]
    assert [(x["effect"], x["side"]) for x in side] == [("stribeck", "before")]
    x = side[0]
    assert x["heldout_rmse_reduction_on_side"] < 0 < x["heldout_rmse_reduction_other_side"]
    assert x["share_slower_than_2vs"] >= core.det.STRIBECK_MIN_LOW
    assert "before the abrupt change of joint 1" in x["reason"]
    # without the check Stribeck stays beside the change: the check is what removes it
    check = core.stribeck_on_one_side_of_change
    monkeypatch.setattr(core, "stribeck_on_one_side_of_change", lambda *a, **k: None)
    d0 = run_diagnosis(log, robot="generic")
    assert set(search_names(d0)) == {"abrupt_change", "stribeck"}
    # ... which reads that final model so; without the change there is nothing to hold the law against
    m = d0.final_model
    e, why = check(d0.prep, m)
    assert e.effect == "stribeck" and why["side"] == "before"
    assert check(d0.prep, Model(d0.prep, [x for x in m.exts if x.effect != "abrupt_change"])) is None


def test_stribeck_planted_beside_a_change_is_kept():
    # spec 16588's settings (100 Hz, quantized torque, 120 s) with a Stribeck law and an abrupt change both planted:
    # the law lowers the held-out error on both sides of the change, and both are named
    mod = bench_module("bench_diagnose_testbench")
    spec = mod.loop_cases(16589)[16588]
    log, truth = mod.loop_log(spec, effects={"stribeck": 1.0, "abrupt_change": 1.0})
    assert set(truth["effects"]) == {"stribeck", "abrupt_change"}
    d = run_diagnosis(log, robot="generic")
    assert set(search_names(d)) == {"stribeck", "abrupt_change"}
    assert _model_with_stribeck_beside_change(d)
    assert core.stribeck_on_one_side_of_change(d.prep, d.final_model) is None
    assert not [x for x in d.prep.meta["set_aside"] if x.get("one_side_of_change")]
