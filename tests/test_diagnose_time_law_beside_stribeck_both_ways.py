"""The hundred-and-fifth round: a law in time beside a Stribeck law of its joint is marked ambiguous with ``stribeck``
where a free function of the joint's state with a speed block and the law explain each other
(``core.mark_time_law_beside_stribeck_both_ways``, ``core.TIME_LAW_BESIDE_STRIBECK_BOTH_WAYS_RULE``; rule file
``benchmarks/results/diagnose_time_law_beside_stribeck_both_ways_round105_rule.txt``)."""
from types import SimpleNamespace

import numpy as np
import pytest

from drake_est.diagnose import competition as comp
from drake_est.diagnose import core

RULE = "TIME_LAW_BESIDE_STRIBECK_BOTH_WAYS_RULE"
T = {"rmse_reduction": 0.012, "p_value": 1.5e-19, "score": -3.0}


def _step(effect, rivals=(), joint=1):
    ext = SimpleNamespace(effect=effect, joint=joint, shared=False, cols={joint: np.zeros((5, 1))})
    c = {"ambiguous": True, "ambiguous_with": list(rivals), "reason": "r"} if rivals else {"reason": ""}
    return SimpleNamespace(ext=ext, competition=c)


def _mark(monkeypatch, *, beside=("stribeck",), law_rivals=("position_dependent_friction",),
          chosen=("speed", "jerk"), back_significant=False, explains=True, rule=True):
    """Run the mark on a change beside a Stribeck law, every piece it reads stubbed: returns (marked, the change's
    step, what the state function was offered)."""
    law, stri = _step("abrupt_change", law_rivals), _step("stribeck")
    model = SimpleNamespace(exts=[stri.ext, law.ext])
    monkeypatch.setattr(core, RULE, rule)
    monkeypatch.setattr(core, "_time_laws_beside_state", lambda model, steps: [(law.ext, list(beside))])
    monkeypatch.setattr(core, "Model", lambda prep, exts: SimpleNamespace(exts=exts))
    monkeypatch.setattr(core, "state_check_rows", lambda prep, j: (None, 0))
    monkeypatch.setattr(core, "_model_solver", lambda m0, j: None)
    monkeypatch.setattr(core, "filter_slope_block", lambda prep, j: {"filter_slope": np.ones((5, 2))})
    offered = []

    def state_explains(prep, m0, j, C, alpha, min_gain, rows=None, chosen=None, extra=None, **kw):
        offered.append(extra)
        chosen += list(chosen_blocks)
        return (np.ones((5, 3)), T, 0.169, 0.172) if explains else None
    chosen_blocks = chosen
    monkeypatch.setattr(core, "_state_explains", state_explains)
    monkeypatch.setattr(comp, "_partial_test", lambda *a, **kw: {"significant": back_significant,
                                                                   "rmse_reduction": 0.015, "p_value": 1e-11,
                                                                   "score": -2.0})
    return core.mark_time_law_beside_stribeck_both_ways(None, model, [stri, law], core.ALPHA, core.MIN_GAIN), law, \
        offered


def test_the_mark_where_every_condition_holds(monkeypatch):
    """Beside a Stribeck law, the function (offered the filter's block) with a speed block and the change explaining
    each other: the change is marked ambiguous with stribeck after its rivals, the evidence stored and said."""
    marked, law, offered = _mark(monkeypatch)
    assert marked == [law]
    assert list(offered[0]) == ["filter_slope"]
    c = law.competition
    assert c["ambiguous"] and c["ambiguous_with"] == ["position_dependent_friction", "stribeck"]
    info = c["stribeck_shape_beside"]
    assert info["blocks"] == ["speed", "jerk"]
    assert info["finding_given_state"]["rmse_reduction"] == T["rmse_reduction"]
    assert info["state_given_finding"]["rmse_reduction"] == 0.015
    assert "explain each other beside its Stribeck law" in c["reason"] and c["reason"].startswith("r; ")


@pytest.mark.parametrize("change", [dict(rule=False), dict(beside=("position_dependent_load",)),
                                    dict(chosen=("jerk",)), dict(back_significant=True), dict(explains=False),
                                    dict(law_rivals=("position_dependent_friction", "stribeck"))])
def test_no_mark_where_a_condition_fails(monkeypatch, change):
    """Rule off; a law beside other laws of the state (the hundred-and-third round's case); a function without a
    speed block; a function that still predicts given the law (the one-way case the forty-sixth round sets aside);
    a function that does not explain the law; a law already ambiguous with stribeck: no mark, the step unchanged."""
    marked, law, _ = _mark(monkeypatch, **change)
    assert marked == []
    assert "stribeck_shape_beside" not in law.competition


def test_probe_touchable_and_control():
    """The probe's screen: a law in time named and not ambiguous with stribeck beside a named Stribeck law; the
    control: every row naming a law in time beside Stribeck named or as a rival (fewer than 100), the same keys on
    every call, none of them touchable."""
    from conftest import bench_module
    probe = bench_module("probe_time_law_beside_stribeck_both_ways")
    assert probe.touchable({"got": "ambiguous(abrupt_change|position_dependent_friction)+position_dependent_load+"
                                   "stribeck"})
    assert probe.touchable({"got": "energy_dependent_friction+stribeck"})
    assert not probe.touchable({"got": "ambiguous(abrupt_change|stribeck)+stribeck"})
    assert not probe.touchable({"got": "abrupt_change+ambiguous(position_dependent_load|stribeck)"})
    assert probe.control({"got": "abrupt_change+ambiguous(position_dependent_load|stribeck)"})
    assert probe.control({"got": "ambiguous(abrupt_change|stribeck)+stribeck"})
    assert not probe.control({"got": "abrupt_change+position_dependent_load"})
    keys = probe.control_keys("loop")
    assert 0 < len(keys) <= probe.CONTROL_ROWS and keys == sorted(set(keys)) == probe.control_keys("loop")
    assert not set(keys) & set(probe.kept_keys("loop", probe.touchable))


@pytest.fixture(scope="module")
def design_case():
    """Fresh spec 43172 (a load beside a Gaussian-law Stribeck hump at 100 Hz with a quantized torque) diagnosed with
    the hundred-and-fifth round's switch off and on: (module, spec, truth, off, on, the mark's marked steps while
    on)."""
    from conftest import closed_loop_off_and_on, recording
    return closed_loop_off_and_on(43172, RULE, recording("mark_time_law_beside_stribeck_both_ways",
                                                          lambda got, a, kw: got))


@pytest.mark.long
def test_spec_43172_reports_the_change_ambiguous_with_stribeck(design_case):
    """Off: the load, the Stribeck law and an abrupt change ambiguous with a position friction and a time-periodic
    disturbance, a wrong name.  On: the same findings and held-out RMSE, the change now ambiguous with stribeck too;
    the state's function chose a speed block, and neither it given the change nor the change given it reaches the
    least gain."""
    mod, spec, truth, off, on, seen = design_case
    assert mod.judge(spec, off)["wrong"] == ["abrupt_change"]
    j = mod.judge(spec, on)
    assert j["wrong"] == [] and j["missed"] == [] and j["correct"]
    assert [f["effect"] for f in on["findings"]] == [f["effect"] for f in off["findings"]]
    change = next(f for f in on["findings"] if f["effect"] == "abrupt_change")
    assert change["ambiguous_between"][-1] == "stribeck"
    assert [st.ext.effect for st in seen] == ["abrupt_change"]
    info = seen[0].competition["stribeck_shape_beside"]
    assert "speed" in info["blocks"]
    assert info["finding_given_state"]["rmse_reduction"] < core.MIN_GAIN
    assert info["state_given_finding"]["rmse_reduction"] < core.MIN_GAIN


def test_kept_and_its_table_is_its_jsons():
    """Kept: the switch is on; lane a examined the one touchable closed-loop row (43172, which the fold took out of
    them), lane b every control row (68); no open-loop row is touchable; the rule acted in 43172 only (mended, the
    change ambiguous with stribeck); no row gained a wrong name, a finding on a null log or lost `unexplained` or an
    outright name, the missed effects did not rise, every rule-on row is its log's kept row (43172's folded), and the
    docs' table holds each lane's row as --against-off-rows prints it."""
    from conftest import REFOLDED_ROUND_105, assert_rule_mended_only, bench_module, probe_lanes
    assert core.TIME_LAW_BESIDE_STRIBECK_BOTH_WAYS_RULE is True
    probe = bench_module("probe_time_law_beside_stribeck_both_ways")
    doc, files, examined, s = probe_lanes(probe, "diagnose_time_law_beside_stribeck_both_ways_round105_lane_*.json",
                                          lanes="ab")
    keys = [d["keys_examined"] for _, d in files]
    assert REFOLDED_ROUND_105 == {43172}
    assert keys[0] == [43172]
    assert [k for k in probe.kept_keys("loop", probe.touchable) if k < 43400] == []
    assert probe.kept_keys("testbench", probe.touchable) == []
    kept = {k: r for (f, _, k), (_, r) in bench_module("bench_diagnose_testbench").kept_rows_naming("any").items()
            if f == "loop"}
    assert len(keys[1]) == 68 and keys[1] == sorted(set(keys[1]))
    assert all(probe.control(kept[k]) for k in keys[1]) and 43172 not in keys[1]
    assert_rule_mended_only("diagnose_time_law_beside_stribeck_both_ways_round105_lane_*.json", files, s, 43172)
    for _, d in files:
        for t in d["touched"]:
            for marked in t["marked"]:
                for x in marked:
                    assert x["effect"] in core.TIME_LAWS and "speed" in x["blocks"]
                    assert x["rmse_reduction_given_state"] < core.MIN_GAIN
                    assert x["rmse_reduction_of_state_given_law"] < core.MIN_GAIN
    assert "The rule acted in one log of 69." in " ".join(doc.split())
