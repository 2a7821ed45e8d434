"""The ninety-second round: a law in time set aside as not significant given later findings, among which the other
law in time stands, is tried again with that law closed (``core.SET_ASIDE_TIME_LAW_ALTERNATIVE``;
``benchmarks/results/diagnose_set_aside_time_law_round92_rule.txt``)."""
from types import SimpleNamespace

import pytest

from drake_est.diagnose import core


def _out(effects):
    """A stand-in for a search output whose model names ``effects`` (effect, joint) pairs."""
    exts = [SimpleNamespace(effect=e, joint=j, shared=False) for e, j in effects]
    return (None, None, None, [], None, SimpleNamespace(exts=exts), None, None)


def test_off_or_out_of_its_case_it_never_searches(monkeypatch):
    """Switched off, or where its case does not hold (the set-aside entry is no law in time, was set aside for a
    rival, the other law in time is not named on its joint, or nothing else is named there), it returns None without
    running a search."""
    def boom(*a, **k):
        raise AssertionError("searched")
    monkeypatch.setattr(core, "_search", boom)
    change = {"effect": "abrupt_change", "joint": 1, "reason": core.NOT_SIGNIFICANT_GIVEN_OTHERS}
    final = _out([("energy_dependent_friction", 1), ("position_dependent_friction", 1)])
    monkeypatch.setattr(core, "SET_ASIDE_TIME_LAW_ALTERNATIVE", False)
    assert core.set_aside_time_law_alternative(None, final, [change], 6, 0.01, 0.01) is None
    monkeypatch.setattr(core, "SET_ASIDE_TIME_LAW_ALTERNATIVE", True)
    cases = [
        ([{**change, "effect": "position_dependent_load"}], final),
        ([{**change, "reason": "stribeck explains the joint's residual better given the other findings"}], final),
        ([change], _out([("energy_dependent_friction", 2), ("position_dependent_friction", 1)])),
        ([change], _out([("energy_dependent_friction", 1), ("position_dependent_friction", 2)])),
        ([change], _out([("abrupt_change", 1), ("energy_dependent_friction", 1), ("position_dependent_load", 1)])),
    ]
    for aside, out in cases:
        assert core.set_aside_time_law_alternative(None, out, aside, 6, 0.01, 0.01) is None
    with pytest.raises(AssertionError, match="searched"):
        core.set_aside_time_law_alternative(None, final, [change], 6, 0.01, 0.01)


def test_probe_touchable():
    """The probe's screen: one law in time among the findings set aside and the other named, alone or in an
    ambiguity."""
    from conftest import bench_module
    probe = bench_module("probe_set_aside_time_law")
    assert probe.touchable({"got": "energy_dependent_friction+position_dependent_load", "set_aside": ["abrupt_change"]})
    assert probe.touchable({"got": "ambiguous(abrupt_change|stribeck)", "set_aside": ["energy_dependent_friction"]})
    assert not probe.touchable({"got": "abrupt_change", "set_aside": ["position_dependent_load"]})
    assert not probe.touchable({"got": "abrupt_change", "set_aside": ["abrupt_change"]})
    assert not probe.touchable({"got": "energy_dependent_friction"})


@pytest.fixture(scope="module")
def design_case():
    """Fresh spec 35738 (an abrupt change beside a motor ripple, 10 Hz, Gaussian noise) diagnosed with the switch off
    and on: (module, spec, truth, off, on, None)."""
    from conftest import closed_loop_off_and_on
    return closed_loop_off_and_on(35738, "SET_ASIDE_TIME_LAW_ALTERNATIVE")


def test_spec_35738_names_the_change_again(design_case):
    """Off: the change is set aside as not significant given the drift and a position friction found after it, and
    the drift, the friction and a load are named beside the ripple (three wrong names). On: with the drift closed the
    search ends at the change and the ripple, whose held-out RMSE is lower than the final model's; the change is named,
    ambiguous with the drift, which is set aside in its place; the change's earlier entry is gone."""
    mod, spec, truth, off, on, _ = design_case
    assert sorted(truth["planted"]) == ["abrupt_change", "motor_position_ripple"]
    assert sorted(mod.judge(spec, off)["wrong"]) == ["energy_dependent_friction", "position_dependent_friction",
                                                      "position_dependent_load"]
    assert [(s["effect"], s["reason"]) for s in off["set_aside"]] == [
        ("abrupt_change", core.NOT_SIGNIFICANT_GIVEN_OTHERS)]
    j = mod.judge(spec, on)
    assert j["wrong"] == [] and j["missed"] == [] and j["correct"]
    assert sorted(f["effect"] for f in on["findings"]) == ["abrupt_change", "motor_position_ripple"]
    change = next(f for f in on["findings"] if f["effect"] == "abrupt_change")
    assert "energy_dependent_friction" in change["competition"]["ambiguous_with"]
    [entry] = on["set_aside"]
    assert entry["effect"] == "energy_dependent_friction"
    info = entry["set_aside_time_law_alternative"]
    assert info["dropped"] == ["position_dependent_friction", "position_dependent_load"]
    assert info["alternative_findings"] == ["abrupt_change", "motor_position_ripple"]
    assert info["heldout_rmse"] < info["heldout_rmse_of_final_model"] and info["paired_p_value"] >= core.PAIRED_ALPHA
    assert info["set_aside_before"]["effect"] == "abrupt_change"


def test_kept_and_its_table_is_its_jsons():
    """Kept: the switch is on; the docs' table holds each lane's row as --against-off-rows prints it; lane a is every
    touchable closed-loop kept row below the fresh blocks 35600-35999 (16), lane b all 150 open-loop rows, lane c
    35738, lane d 37564 (the one of the fresh blocks 37400-37599), lane e 39828 (the one of 39800-39999), lane f 41128 (the one of 41000-41199), lane g 42666 (the one of 42600-42799), lane h 42864 (of 42800-42999), lane i 43065 and 43152 (of 43000-43399), lane j 43788 (of 43400-43999), lane k 45708 (of 45600-45799), lane l 45767 (folded by the hundred-and-eighth round); every touchable row was examined; the rule acted in the design log only, which lost its wrong names, and
    nothing was lost."""
    from conftest import assert_rule_mended_only, bench_module, probe_lanes
    assert core.SET_ASIDE_TIME_LAW_ALTERNATIVE is True
    probe = bench_module("probe_set_aside_time_law")
    doc, files, examined, s = probe_lanes(probe, "diagnose_set_aside_time_law_round92_lane_*.json", lanes="abcdefghijkl")
    assert [len(d["keys_examined"]) for _, d in files] == [16, 150, 1, 1, 1, 1, 1, 1, 2, 1, 1, 1]
    # (30544, whose stale kept row the ninety-sixth round folded back to today's, became touchable then: REFOLDED_ROUND_96)
    from conftest import REFOLDED_ROUND_96
    assert set(probe.touchable_keys("loop")) - REFOLDED_ROUND_96 <= examined["loop"] and 35738 in examined["loop"]
    assert len(examined["testbench"]) == 150
    assert_rule_mended_only("diagnose_set_aside_time_law_round92_lane_*.json", files, s, 35738)
    assert "It acted in one log of 177" in " ".join(doc.split())
