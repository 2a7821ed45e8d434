"""The seventy-third round: the check that sets a finding aside as "not significant given the other findings" also
tests the finding as it stands, when the fresh re-detection of its effect on the model without it is not significant
(core._own_finding_given_others behind core.OWN_FINDING_IN_ITS_CHECK)."""
import numpy as np
import pytest

from drake_est.diagnose import core, detectors as det, diagnose
from conftest import closed_loop_case, closed_loop_case_where, load_set_aside_as_not_significant


def test_the_finding_as_accepted_stands_in_for_a_fresh_candidate_only_when_it_passes():
    # loop spec 135 (a position friction alone at 10 Hz): the friction as accepted, given nothing else, passes every
    # test of the round; a made-up candidate of noise columns does not, and the check keeps what it had
    _, _, log, _ = closed_loop_case(135)
    r = core.run_diagnosis(log, robot="generic", seed=0)
    (e,) = r.final_model.exts
    m0 = core.Model(r.prep, [])
    f0 = m0.fit(r.sigma)
    sentinel = [("fresh",)]
    got = core._own_finding_given_others(r.prep, m0, f0, r.sigma, e, core.ALPHA, core.MIN_GAIN, sentinel)
    assert got is not sentinel and got[0][0] is e
    assert got[0][1]["significant"] and got[0][1]["as_accepted"]
    n = e.cols[1].shape[0]
    noise = det.Extension("position_dependent_friction", 1, {1: np.random.default_rng(73).standard_normal((n, 3))},
                          ["a", "b", "c"], {"effect": "position_dependent_friction"})
    assert core._own_finding_given_others(r.prep, m0, f0, r.sigma, noise, core.ALPHA, core.MIN_GAIN,
                                          sentinel) is sentinel


@pytest.mark.long
def test_a_load_is_not_set_aside_for_a_fresh_shape_that_predicts_worse(monkeypatch):
    # loop spec 11558 (a load beside Stribeck at 1000 Hz, quantized torque): the load as accepted (16 kernels) lowers the
    # held-out RMSE by 54 % given a drift and a level; the fresh load of the check (32 kernels) raised it by 54 %, the
    # load was set aside, and the report named a position friction ambiguous with a change, a level and a drift.
    # Whether the search reaches that check with the load depends on the CPU's last digits (see
    # test_diagnose_position_law_as_accepted.py): the log is taken at the first of a few last digits of its position
    # reference where the diagnosis with neither round's check sets the load aside as not significant
    monkeypatch.setattr(core, "POSITION_LAW_AS_ACCEPTED_IN_ITS_CHECK", False)
    monkeypatch.setattr(core, "OWN_FINDING_IN_ITS_CHECK", False)
    found = closed_loop_case_where(11558, load_set_aside_as_not_significant)
    if found is None:
        pytest.fail("at none of the last digits tried is the load set aside as not significant without the checks")
    mod, spec, log, _, _ = found
    monkeypatch.setattr(core, "OWN_FINDING_IN_ITS_CHECK", True)      # the rule is off by default (not kept)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert mod.judge(spec, d)["wrong"] == [], d["findings"]
    assert "position_dependent_load" in {f["effect"] for f in d["findings"]}
    assert not any(s["effect"] == "position_dependent_load" and s["joint"] == 1 for s in d["set_aside"])


def test_the_rule_is_off_and_its_table_is_its_jsons():
    """The seventy-third round was tried and not kept: the switch is off, the docs' table holds each probe JSON's row as
    --against-off-rows prints it, 11558 lost its wrong name and 4035 gained one (rule (1) of the rule file), and no
    row the rule fired in was folded (each rule-off row is its kept row)."""
    from conftest import bench_module, probe_results
    assert core.OWN_FINDING_IN_ITS_CHECK is False
    probe = bench_module("probe_own_finding_in_check")
    doc, files, _ = probe_results("diagnose_own_finding_in_check_round73_*.json")
    assert len(files) == 3
    gained, lost = [], []
    for f, d in files:
        s = probe.against_off([str(f)])
        assert probe.against_off_row(f.name, s) in doc
        assert s["off_differs_from_kept_row"] == []
        gained += s["wrong_gained"]
        lost += s["wrong_lost"]
    assert gained == [4035] and lost == [11558]
