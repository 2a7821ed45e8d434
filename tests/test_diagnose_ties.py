"""A finding that the final model does not separate from a rival (core._mark_tied_rivals): the greedy search chose it
in an earlier round; given the other findings a rival scores within AMBIGUITY_MARGIN of it or predicts within
MIN_GAIN of its RMSE, so it is reported ambiguous with that rival."""
from types import SimpleNamespace

import pytest

from conftest import bench_module
from drake_est.diagnose import core


def _r(effect, score, red, significant=True):
    return (SimpleNamespace(effect=effect), {"score": score, "rmse_reduction": red, "significant": significant}, None,
            None)


def test_tied_rivals_are_the_close_significant_ones_best_first():
    e = SimpleNamespace(effect="position_dependent_load", joint=1)
    own = {"score": 1000.0, "rmse_reduction": 0.50}
    results = [_r("position_dependent_load", 1000.0, 0.50),
               _r("asymmetric_coulomb", 900.0, 0.495),          # 100 lower in score, but within 2 % of the RMSE
               _r("abrupt_change", 995.0, 0.30),                # within the score margin
               _r("energy_dependent_friction", 999.0, 0.499, significant=False),
               _r("motor_position_ripple", 500.0, 0.20),        # separated
               _r("stribeck", 2000.0, 0.7)]                     # higher: finding_to_set_aside's, not a tie
    amb = {}
    core._mark_tied_rivals(amb, e, own, results)
    c = amb[("position_dependent_load", 1)]
    assert c["ambiguous"] and c["ambiguous_with"] == ["abrupt_change", "asymmetric_coulomb"]
    assert c["runner_up"] == "abrupt_change"
    amb = {}
    core._mark_tied_rivals(amb, e, own, [results[0], results[4], results[5]])
    assert amb == {}


@pytest.mark.long
@pytest.mark.parametrize("ulps", [0, 1, 5])
def test_loop_case_4851_level_is_not_left_out_of_the_loads_ambiguity(ulps):
    """Closed-loop spec 4851 (1000 Hz: an asymmetric level beside Stribeck).  The load was accepted first, before
    Stribeck; given Stribeck, the asymmetric level predicts the held-out data within 0.2 % of the load's RMSE, so the
    load is reported ambiguous with it (it was named ambiguous with Stribeck only, the level missed).  The findings
    themselves do not change."""
    from drake_est.diagnose import diagnose
    log, truth = bench_module("bench_diagnose_testbench").loop_log(4851, reference_ulps=ulps)
    assert sorted(truth["effects"]) == ["asymmetric_coulomb", "stribeck"]
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    if [f["effect"] for f in d["findings"]] == ["asymmetric_coulomb", "stribeck"]:
        # on an AVX2 CPU at 5 ulps the level itself is named (the load never accepted first): nothing left out
        return
    assert [f["effect"] for f in d["findings"]] == ["position_dependent_load", "stribeck"]
    load = d["findings"][0]
    assert "asymmetric_coulomb" in load["ambiguous_between"]
    assert "asymmetric_coulomb" in load["competition"]["given_the_other_findings"]["ambiguous_with"]
