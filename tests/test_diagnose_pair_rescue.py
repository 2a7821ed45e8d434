"""The seventieth round: two effects of one joint that mask each other, let through together (core.pair_rescue behind
core.PAIR_RESCUE)."""
from types import SimpleNamespace

import numpy as np
import pytest

from drake_est.diagnose import core, diagnose
from drake_est.diagnose.report import markdown

from conftest import closed_loop_case


def _held_back(effect, joint, score, **flags):
    """A round's entry (ext, test, fit1, model1) of a candidate held back by the paired block test alone."""
    ext = SimpleNamespace(effect=effect, joint=joint, shared=False)
    tst = {"p_value": 0.0, "rmse_reduction": 0.2, "score": score, "significant": False,
           "not_separated_on_held_out_blocks": True, **flags}
    return ext, tst, None, None


def test_only_candidates_held_back_by_the_blocks_alone_of_one_joint_are_paired():
    # no pair to try: nothing is fitted (the model and fits are None here) and nothing is let through
    cases = [
        [_held_back("abrupt_change", 1, 50.0), _held_back("motor_position_ripple", 2, 40.0)],       # two joints
        [_held_back("abrupt_change", 1, 50.0), _held_back("abrupt_change", 1, 40.0)],               # one effect
        [_held_back("abrupt_change", 1, 50.0),
         _held_back("motor_position_ripple", 1, 40.0, below_quantization_step=True)],             # another test failed
        [_held_back("abrupt_change", 1, 50.0), _held_back("stribeck", 1, -1.0)],                    # score <= 0
    ]
    for results in cases:
        assert core.pair_rescue(None, None, None, None, results, core.ALPHA, core.MIN_GAIN) is None
    # a candidate that passed (significant) is no member either: the round had a winner then
    ext = SimpleNamespace(effect="stribeck", joint=1, shared=False)
    passed = (ext, {"p_value": 0.0, "rmse_reduction": 0.2, "score": 9.0, "significant": True}, None, None)
    assert core.pair_rescue(None, None, None, None, [_held_back("abrupt_change", 1, 5.0), passed],
                            core.ALPHA, core.MIN_GAIN) is None


@pytest.mark.long
def test_an_abrupt_change_and_a_ripple_that_mask_each_other_are_named(monkeypatch):
    # loop spec 19128 (an abrupt change with a motor ripple of 9.708 cycles/rad and its harmonic, 1000 Hz, quantized
    # torque) with its position reference moved by 1, 2, 3, 5, 8 and 10 ulps, as other CPUs' last digits would: on the
    # seventieth round's AMD EPYC each alone is held back by the paired block test (p = 0.053 for the change) and the
    # search names nothing; together they are named every time, the ripple at the generator's frequencies.  On the
    # eighty-eighth round's Intel Xeon the pair needs the rescue at 8 and 10 ulps only (at 0-7 each is named alone)
    monkeypatch.setattr(core, "PAIR_RESCUE", True)
    kept = []
    for ulps in (1, 2, 3, 5, 8, 10):
        _, _, log, truth = closed_loop_case(19128, reference_ulps=ulps)
        rep = diagnose(log, robot="generic", seed=0, simulate=False)
        assert sorted(rep.effects) == ["abrupt_change", "motor_position_ripple"], ulps
        first = rep.result.steps[0]
        if "significant_beside" not in first.test:
            continue
        kept.append(ulps)
        beside = first.test["significant_beside"]
        assert beside["partner"] == rep.result.steps[1].ext.effect != first.ext.effect
        assert beside["paired_p_value_of_both"] < core.PAIRED_ALPHA
        # report.json says how it entered, and report.md in one sentence
        w = rep.to_dict()["findings"][0]["evidence"]["entered_with"]
        assert w["partner"] == beside["partner"] and w["paired_p_value_alone"] >= core.PAIRED_ALPHA
        assert f"Entered together with `{w['partner']}`" in markdown(rep.to_dict())
        for t in (beside["test_given_partner"], beside["partner_test_given_this"]):
            assert t["paired_p_value"] < core.PAIRED_ALPHA and t["p_value"] < core.ALPHA
        rip = [e for e in rep.result.final_model.exts if e.effect == "motor_position_ripple"][0]
        f0 = truth["motor_position_ripple"]["frequency_per_arm_rad"]
        np.testing.assert_allclose(np.sort(rip.spec["frequencies_per_arm_rad"]), [f0, 2 * f0], rtol=2e-3)
    assert kept, "no pair was let through at any of the six last digits"


@pytest.mark.long
def test_a_pair_whose_partner_does_not_win_the_next_round_is_undone(monkeypatch):
    # a rescue whose partner can never win (an effect no detector proposes): the search returns to where it stopped,
    # and the diagnosis is exactly the one without the rule (loop spec 13453, an asymmetric level beside Stribeck at
    # 250 Hz, whose last round holds candidates held back by the paired block test alone)
    _, _, log, _ = closed_loop_case(13453)
    monkeypatch.setattr(core, "PAIR_RESCUE", False)
    off = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    fired = []

    def rescue_without_partner(prep, model, fit, sigma, results, alpha, min_gain):
        held = [r for r in results if r[1].get("not_separated_on_held_out_blocks")]
        if not held:
            return None
        a = max(held, key=lambda r: r[1]["score"])
        fired.append(a[0].effect)
        return (a[0], {**a[1], "significant": True}, a[2], a[3]), "no_such_effect", {"joint": int(a[0].joint)}

    monkeypatch.setattr(core, "pair_rescue", rescue_without_partner)
    monkeypatch.setattr(core, "PAIR_RESCUE", True)
    on = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert fired
    for key in ("findings", "not_found", "unexplained"):
        assert on[key] == off[key], key


def test_the_rule_is_on_and_its_table_is_its_jsons():
    """The seventieth round was kept: both switches are on, the docs' table holds each probe JSON's row as
    --table-row prints it, the first rule's only wrong name is 2145, the second rule's rows gain none, and every row
    where it fired is the kept row of its log (the bench's own comparison, on every outcome field)."""
    from conftest import REFOLDED_ROUND_96, REFOLDED_ROUND_106, bench_module, probe_results
    assert core.PAIR_RESCUE is True and core.PAIR_RESCUE_PARTNER_WINS is True
    probe = bench_module("probe_pair_rescue")
    doc, files, differences = probe_results("diagnose_pair_rescue_round70_*.json")
    assert len(files) == 7
    for f, d in files:
        s = probe.summary([str(f)])
        assert probe.table_row(f.name, s) in doc
        wrong = [x["k"] for x in s["cases"].get("wrong name", [])]
        if "first_rule" in f.name:
            assert wrong == ([2145] if f.name.endswith("first_rule_lane_a.json") else [])
            continue
        assert wrong == [] and "null log, entry gained" not in s["classes"]
        # (rows the ninety-sixth and hundred-and-sixth rounds refolded left out)
        assert [x for x in differences(d) if x["k"] not in REFOLDED_ROUND_96 | REFOLDED_ROUND_106] == [], f.name


@pytest.mark.long
def test_a_load_that_entered_beside_the_level_is_not_named(monkeypatch):
    # loop spec 2145: an asymmetric level beside Stribeck at 50 Hz with Student-t noise.  The first rule let a load in
    # beside the level; the next round chose the Stribeck law and the load stayed, a wrong name.  The second rule (the
    # partner must win the next round) names no effect that was not planted
    monkeypatch.setattr(core, "PAIR_RESCUE", True)
    monkeypatch.setattr(core, "PAIR_RESCUE_PARTNER_WINS", True)
    _, _, log, truth = closed_loop_case(2145)
    assert sorted(truth["planted"]) == ["asymmetric_coulomb", "stribeck"]
    rep = diagnose(log, robot="generic", seed=0, simulate=False)
    named = {f["effect"] for f in rep.to_dict()["findings"]}
    assert named <= set(truth["planted"]), named


def test_the_cost_sentence_is_its_json():
    import json
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    d = json.loads((root / "benchmarks" / "results" / "diagnose_pair_rescue_cost.json").read_text())
    doc = " ".join((root / "docs" / "readme" / "diagnose_testbench.md").read_text().split())
    assert (f"the speed benchmark's {d['logs']} closed-loop logs take {d['cpu_s_on']:.1f} s of CPU with the rule and "
            f"{d['cpu_s_off']:.1f} s without (ratio {d['ratio_on_to_off']:.3f}), with the same findings") in doc
    assert d["same_findings"] is True
