"""The seventy-second round: position laws on a joint whose final residual still depends on the velocity are held
against a free friction curve of the speed in their place, and reported ambiguous with stribeck when the held-out
blocks do not separate the two (core.mark_position_laws_within_speed_curve behind
core.POSITION_LAWS_AGAINST_SPEED_CURVE)."""
import pytest

from drake_est.diagnose import core, diagnose
from conftest import bench_module, closed_loop_case, probe_results

POSITION_LAWS = ("position_dependent_friction", "position_dependent_load")


def _velocity_entry(j=1):
    return [{"joint": j, "variable": "velocity"}]


def test_a_position_friction_beside_a_stribeck_law_is_not_named_outright():
    # loop spec 25506 (a load beside Stribeck at 10 Hz, Student-t noise): a position friction was named outright beside
    # a level ambiguous with Stribeck and the load; the speed curve in its place is not separated (paired p = 0.071).
    # (The ninety-sixth round, switched off, named the load and Stribeck outright here: it left out the 6 held-out rows
    # beyond the training positions)
    mod, spec, log, _ = closed_loop_case(25506)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert mod.judge(spec, d)["wrong"] == [], d["findings"]
    for f in d["findings"]:
        if f["effect"] in POSITION_LAWS:
            assert "stribeck" in f["ambiguous_between"], f
            c = f["competition"].get("speed_curve_in_place")
            if c is not None:
                assert c["paired_p_value"] >= core.PAIRED_ALPHA
                assert "free friction curve" in f["competition"]["reason"]


def test_the_mark_follows_the_switch_and_the_paired_test(monkeypatch):
    # a final model with a position friction and no Stribeck law, whose speed curve in its place the held-out blocks
    # do not separate: loop spec 18524 (Stribeck alone at 50 Hz, named as a position friction; paired p = 0.36-0.44
    # over 0-3 ulps of its position reference on the eighty-eighth round's Intel Xeon).  The competition already marks
    # that friction ambiguous with stribeck (position and speed confounded), so its step is set back to outright here,
    # as spec 25506's was on the seventy-second round's machine (where that log's search holds the friction named
    # outright; on the Intel Xeon it does so at one last digit of 0-20 only).  The mark turns it ambiguous with stribeck
    # only with the switch on
    monkeypatch.setattr(core, "POSITION_LAWS_AGAINST_SPEED_CURVE", False)
    _, _, log, _ = closed_loop_case(18524)
    r = core.run_diagnosis(log, robot="generic", seed=0)
    pf = [st for st in r.steps if st.ext.effect == "position_dependent_friction"]
    assert pf and not any(st.ext.effect == "stribeck" for st in r.steps), [st.ext.effect for st in r.steps]
    c = pf[0].competition
    pf[0].competition = {k: c[k] for k in ("runner_up", "runner_up_joint", "runner_up_score", "runner_up_significant",
                                           "margin", "runner_up_rmse_reduction") if k in c}
    pf[0].competition["ambiguous"] = False
    assert core.mark_position_laws_within_speed_curve(r.prep, r.final_model, r.final_fit, r.steps, r.unexplained,
                                                      r.sigma) == []
    monkeypatch.setattr(core, "POSITION_LAWS_AGAINST_SPEED_CURVE", True)
    got = core.position_laws_not_separated_from_speed_curve(r.prep, r.final_model, r.final_fit, 1, r.sigma)
    assert got is not None and got["paired_p_value"] >= core.PAIRED_ALPHA
    assert got["position_laws"] == ["position_dependent_friction"]
    # no velocity entry: nothing is marked
    assert core.mark_position_laws_within_speed_curve(r.prep, r.final_model, r.final_fit, r.steps, [], r.sigma) == []
    marked = core.mark_position_laws_within_speed_curve(r.prep, r.final_model, r.final_fit, r.steps,
                                                        _velocity_entry(), r.sigma)
    assert [st.ext.effect for st in marked] == ["position_dependent_friction"]
    c = marked[0].competition
    assert c["ambiguous"] and c["ambiguous_with"][-1] == "stribeck"
    assert c["speed_curve_in_place"]["paired_p_value"] == got["paired_p_value"]
    # marked once: a second pass adds nothing
    assert core.mark_position_laws_within_speed_curve(r.prep, r.final_model, r.final_fit, r.steps,
                                                      _velocity_entry(), r.sigma) == []


def test_a_position_friction_the_speed_curve_cannot_take_stays_named():
    # loop spec 135 (a position friction alone at 10 Hz): the curve in its place predicts the held-out blocks worse
    mod, spec, log, _ = closed_loop_case(135)
    r = core.run_diagnosis(log, robot="generic", seed=0)
    assert [e.effect for e in r.final_model.exts] == ["position_dependent_friction"]
    assert not r.steps[0].competition.get("ambiguous")
    assert core.position_laws_not_separated_from_speed_curve(r.prep, r.final_model, r.final_fit, 1, r.sigma) is None
    assert core.mark_position_laws_within_speed_curve(r.prep, r.final_model, r.final_fit, r.steps,
                                                      _velocity_entry(), r.sigma) == []


@pytest.mark.long
def test_a_level_beside_stribeck_is_not_named_as_two_position_laws():
    # loop spec 19899 (an asymmetric level beside Stribeck at 50 Hz, speeds within a factor 3, so no Stribeck
    # candidate): named as a position load and a position friction; with the curve in the place of both, paired p = 0.053
    mod, spec, log, _ = closed_loop_case(19899)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert mod.judge(spec, d)["wrong"] == [], d["findings"]
    laws = [f for f in d["findings"] if f["effect"] in POSITION_LAWS]
    assert laws
    for f in laws:
        assert "stribeck" in f["ambiguous_between"]


def test_the_probe_lists_the_rows_the_rule_can_touch():
    probe = bench_module("probe_position_laws_speed_curve")
    assert probe.finding_heads("ambiguous(position_dependent_load|stribeck)+abrupt_change") == [
        "position_dependent_load", "abrupt_change"]
    assert probe.finding_heads("none") == probe.finding_heads("unexplained") == []
    row = {"got": "abrupt_change+ambiguous(position_dependent_friction|stribeck)", "unexplained": ["velocity"]}
    assert probe.touchable(row)
    assert not probe.touchable({**row, "unexplained": ["time"]})
    assert not probe.touchable({**row, "got": "ambiguous(stribeck|position_dependent_friction)"})


def test_the_rule_is_on_and_its_table_is_its_jsons():
    """The seventy-second round was kept: the switch is on, the docs' table holds each probe JSON's row as
    --against-off-rows prints it, no row gained a wrong name, 19899 and 25506 lost theirs, one outright-correct row
    turned ambiguous (26893), and every row where the rule fired is the kept row of its log (folded), but for 13530 and
    8965, folded again by the seventy-fourth and seventy-fifth rounds."""
    assert core.POSITION_LAWS_AGAINST_SPEED_CURVE is True
    probe = bench_module("probe_position_laws_speed_curve")
    doc, files, differences = probe_results("diagnose_position_laws_speed_curve_round72_*.json")
    assert len(files) == 2
    assert probe.AGAINST_OFF_HEADER in doc
    lost, outright, examined = [], [], 0
    for f, d in files:
        s = probe.against_off([str(f)])
        assert probe.against_off_row(f.name, s) in doc
        assert s["wrong_gained"] == s["null_findings_gained"] == s["oov_unexplained_lost"] == []
        assert s["missed_on"] <= s["missed_off"]
        lost += s["wrong_lost"]
        outright += s["outright_lost"]
        examined += s["examined"]
        # rows folded again by later rounds: 13530 by the seventy-fourth (a load kept in its check: a second ambiguous
        # finding, still correct), 8965 by the seventy-fifth (J kept positive: Stribeck named outright)
        # (7975's kept row was refolded by the ninetieth round, 25506's by the ninety-sixth: its rule-off row on an
        # Intel Xeon)
        assert [x["k"] for x in differences(d)] == ([8965, 13530] if f.name.endswith("_lane_a.json") else
                                                     [7975, 25506] if f.name.endswith("_lane_b.json") else []), f.name
    assert sorted(lost) == [19899, 25506]
    assert outright == [26893]
    assert f"all {examined} such kept rows" in " ".join(doc.split())
