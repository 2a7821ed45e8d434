"""The hundred-and-third round: a law in time beside a law of the state, on a joint that cannot test a Stribeck law and
whose other finding is already ambiguous with one, is marked ambiguous with ``stribeck`` where a free function of the
joint's state with a speed block and the law explain each other (``core.mark_time_law_beside_untestable_stribeck``,
``core.TIME_LAW_BESIDE_UNTESTABLE_STRIBECK_RULE``; rule file
``benchmarks/results/diagnose_time_law_beside_untestable_stribeck_round103_rule.txt``)."""
from types import SimpleNamespace

import numpy as np
import pytest

from drake_est.diagnose import competition as comp
from drake_est.diagnose import core

RULE = "TIME_LAW_BESIDE_UNTESTABLE_STRIBECK_RULE"
T = {"rmse_reduction": -0.15, "p_value": 1.0, "score": -3.0}


def _step(effect, rivals=(), joint=1):
    ext = SimpleNamespace(effect=effect, joint=joint, shared=False, cols={joint: np.zeros((5, 1))})
    c = {"ambiguous": True, "ambiguous_with": list(rivals), "reason": "r"} if rivals else {"reason": ""}
    return SimpleNamespace(ext=ext, competition=c)


def _mark(monkeypatch, *, testable=False, other_rivals=("stribeck",), law_rivals=("energy_dependent_friction",),
          chosen=("speed", "inertia", "load"), back_significant=False, rule=True):
    """Run the mark on a law in time beside a load, every piece it reads stubbed: returns (marked, the law's step)."""
    law, other = _step("abrupt_change", law_rivals), _step("position_dependent_load", other_rivals)
    model = SimpleNamespace(exts=[other.ext, law.ext])
    jd = SimpleNamespace(v=np.linspace(0.01, 0.02, 5), rows=np.arange(5), train=np.ones(5, bool))
    prep = SimpleNamespace(joints={1: jd})
    monkeypatch.setattr(core, RULE, rule)
    monkeypatch.setattr(core, "_time_laws_beside_state", lambda model, steps: [(law.ext, ["position_dependent_load"])])
    monkeypatch.setattr(core.det, "stribeck_speeds", lambda v: np.ones(3) if testable else np.zeros(0))
    monkeypatch.setattr(core, "Model", lambda prep, exts: SimpleNamespace(exts=exts))
    monkeypatch.setattr(core, "state_check_rows", lambda prep, j: (None, 0))
    monkeypatch.setattr(core, "_model_solver", lambda m0, j: None)

    def explains(prep, m0, j, C, alpha, min_gain, rows=None, chosen=None, **kw):
        chosen += list(chosen_blocks)
        return np.ones((5, 3)), T, 0.425, 0.472
    chosen_blocks = chosen
    monkeypatch.setattr(core, "_state_explains", explains)
    monkeypatch.setattr(comp, "_partial_test", lambda *a, **kw: {"significant": back_significant,
                                                                   "rmse_reduction": -0.059, "p_value": 1.0,
                                                                   "score": -2.0})
    return core.mark_time_law_beside_untestable_stribeck(prep, model, [other, law], core.ALPHA, core.MIN_GAIN), law


def test_the_mark_where_every_condition_holds(monkeypatch):
    """Untestable Stribeck law, the load already ambiguous with stribeck, the function with a speed block and the law
    explaining each other: the law is marked ambiguous with stribeck after its rivals, the evidence stored and said."""
    marked, law = _mark(monkeypatch)
    assert marked == [law]
    c = law.competition
    assert c["ambiguous"] and c["ambiguous_with"] == ["energy_dependent_friction", "stribeck"]
    info = c["untestable_stribeck_beside"]
    assert info["blocks"] == ["speed", "inertia", "load"]
    assert info["finding_given_state"]["rmse_reduction"] == T["rmse_reduction"]
    assert info["state_given_finding"]["rmse_reduction"] == -0.059
    assert "cannot test a Stribeck law" in c["reason"] and c["reason"].startswith("r; ")


@pytest.mark.parametrize("change", [dict(rule=False), dict(testable=True), dict(other_rivals=()),
                                    dict(other_rivals=("asymmetric_coulomb",)), dict(chosen=("inertia", "load")),
                                    dict(back_significant=True),
                                    dict(law_rivals=("energy_dependent_friction", "stribeck"))])
def test_no_mark_where_a_condition_fails(monkeypatch, change):
    """Rule off; a joint that can test a Stribeck law; no other finding ambiguous with stribeck; a function without a
    speed block; a function that still predicts given the law (the one-way case the forty-sixth round sets aside);
    a law already ambiguous with stribeck: no mark, the law's step unchanged."""
    marked, law = _mark(monkeypatch, **change)
    assert marked == []
    assert "untestable_stribeck_beside" not in law.competition


def test_probe_touchable_and_control():
    """The probe's screen: a law in time named and not ambiguous with stribeck beside another finding ambiguous with
    stribeck; the control draws 100 rows naming a law in time beside a law of the state, the same keys on every call,
    none of them touchable."""
    from conftest import bench_module
    probe = bench_module("probe_time_law_beside_untestable_stribeck")
    assert probe.findings({"got": "ambiguous(abrupt_change|energy_dependent_friction)+stribeck"}) == [
        ("abrupt_change", ["energy_dependent_friction"]), ("stribeck", [])]
    assert probe.touchable({"got": "ambiguous(abrupt_change|energy_dependent_friction)+"
                                   "ambiguous(position_dependent_load|stribeck)"})
    assert probe.touchable({"got": "abrupt_change+ambiguous(motor_position_ripple|stribeck)"})
    assert not probe.touchable({"got": "ambiguous(abrupt_change|stribeck)+ambiguous(position_dependent_load|stribeck)"})
    assert not probe.touchable({"got": "abrupt_change+position_dependent_load"})
    assert not probe.touchable({"got": "ambiguous(position_dependent_load|stribeck)"})
    assert probe.control({"got": "abrupt_change+position_dependent_load"})
    assert not probe.control({"got": "abrupt_change"})
    keys = probe.control_keys("loop")
    assert len(keys) == probe.CONTROL_ROWS and keys == sorted(set(keys)) == probe.control_keys("loop")
    assert not set(keys) & set(probe.kept_keys("loop", probe.touchable))


@pytest.fixture(scope="module")
def design_case():
    """Fresh spec 41808 (a load beside Stribeck at 50 Hz with Student-t noise) diagnosed with the hundred-and-third
    round's switch off and on: (module, spec, truth, off, on, the mark's marked steps while on)."""
    from conftest import closed_loop_off_and_on, recording
    return closed_loop_off_and_on(41808, RULE, recording("mark_time_law_beside_untestable_stribeck",
                                                          lambda got, a, kw: got))


@pytest.mark.long
def test_spec_41808_reports_the_change_ambiguous_with_stribeck(design_case):
    """Off: the load (ambiguous with Stribeck) and an abrupt change ambiguous with an energy drift only, a wrong name.
    On: the same findings and held-out RMSE, the change now ambiguous with stribeck too; the state's function chose a
    speed block, and neither it given the change nor the change given it reaches the least gain."""
    mod, spec, truth, off, on, seen = design_case
    assert mod.judge(spec, off)["wrong"] == ["abrupt_change"]
    j = mod.judge(spec, on)
    assert j["wrong"] == [] and j["missed"] == [] and j["correct"]
    assert [f["effect"] for f in on["findings"]] == [f["effect"] for f in off["findings"]]
    change = next(f for f in on["findings"] if f["effect"] == "abrupt_change")
    assert change["ambiguous_between"][-1] == "stribeck" and "energy_dependent_friction" in change["ambiguous_between"]
    assert [st.ext.effect for st in seen] == ["abrupt_change"]
    info = seen[0].competition["untestable_stribeck_beside"]
    assert "speed" in info["blocks"]
    assert info["finding_given_state"]["rmse_reduction"] < core.MIN_GAIN
    assert info["state_given_finding"]["rmse_reduction"] < core.MIN_GAIN


def test_kept_and_its_table_is_its_jsons():
    """Kept: the switch is on; lane a examined every touchable closed-loop row (13056 and 41808, which the fold took
    out of them), lane b the 100 control rows; no open-loop row is touchable; the rule acted in 41808 only (mended,
    the change ambiguous with stribeck); no row gained a wrong name, a finding on a null log or lost `unexplained` or
    an outright name, the missed effects did not rise, every rule-on row is its log's kept row (41808's folded), and
    the docs' table holds each lane's row as --against-off-rows prints it."""
    from conftest import REFOLDED_ROUND_103, assert_rule_mended_only, bench_module, probe_lanes
    assert core.TIME_LAW_BESIDE_UNTESTABLE_STRIBECK_RULE is True
    probe = bench_module("probe_time_law_beside_untestable_stribeck")
    doc, files, examined, s = probe_lanes(probe, "diagnose_time_law_beside_untestable_stribeck_round103_lane_*.json",
                                          lanes="abc")
    keys = [d["keys_examined"] for _, d in files]
    assert REFOLDED_ROUND_103 == {41808}
    assert keys[0] == [13056, 41808]
    touchable = probe.kept_keys("loop", probe.touchable)
    assert [k for k in keys[0] if k not in REFOLDED_ROUND_103] == [k for k in touchable if k < 42000]
    # lane c: the touchable row of the fresh blocks 42000-42999 (42000-42599 and 42800-42999 have none, nor do
    # 43000-47199), 42666, which the hundred-and-fourth round's fold then took out of them
    from conftest import REFOLDED_ROUND_104
    assert keys[2] == [42666] and 42666 in REFOLDED_ROUND_104 and [k for k in touchable if k >= 42000] == []
    assert probe.kept_keys("testbench", probe.touchable) == []
    kept = {k: r for (f, _, k), (_, r) in bench_module("bench_diagnose_testbench").kept_rows_naming("any").items()
            if f == "loop"}
    # drawn before the fold added 41808 to the control rows' pool: today's draw may differ
    assert len(keys[1]) == probe.CONTROL_ROWS and keys[1] == sorted(set(keys[1]))
    assert all(probe.control(kept[k]) for k in keys[1]) and not set(keys[1]) & set(keys[0] + keys[2])
    assert_rule_mended_only("diagnose_time_law_beside_untestable_stribeck_round103_lane_*.json", files, s, 41808)
    for _, d in files:
        for t in d["touched"]:
            for marked in t["marked"]:
                for x in marked:
                    assert x["effect"] in core.TIME_LAWS and "speed" in x["blocks"]
                    assert x["rmse_reduction_given_state"] < core.MIN_GAIN
                    assert x["rmse_reduction_of_state_given_law"] < core.MIN_GAIN
    assert "The rule acted in one log of 103." in " ".join(doc.split())
