"""The hundred-and-second round: the forty-sixth round's check of a law in time beside a Stribeck law against a free
function of the joint's state may also take the derivative filter's error through the friction curve's slope
(``core.filter_slope_block``, ``core.TIME_LAW_BESIDE_STRIBECK_FILTER_SLOPE_RULE``; rule file
``benchmarks/results/diagnose_time_law_beside_stribeck_filter_slope_round102_rule.txt``)."""
from types import SimpleNamespace

import numpy as np
import pytest

from drake_est.diagnose import competition as comp
from drake_est.diagnose import core

RULE = "TIME_LAW_BESIDE_STRIBECK_FILTER_SLOPE_RULE"


def test_the_block_is_the_filter_slope_columns_only_with_the_rule_on(monkeypatch):
    """Off: None.  On: the hundred-and-first round's columns under the name ``filter_slope``; None where the training
    speeds span no range."""
    from conftest import nominal_candidates
    prep, _, _ = nominal_candidates({"position_dependent_load": 1.0}, seed=3)
    monkeypatch.setattr(core, RULE, False)
    assert core.filter_slope_block(prep, 1) is None
    monkeypatch.setattr(core, RULE, True)
    got = core.filter_slope_block(prep, 1)
    assert list(got) == ["filter_slope"] and np.array_equal(got["filter_slope"], comp.filter_slope_columns(prep, 1))
    monkeypatch.setattr(comp, "filter_slope_columns", lambda prep, j: None)
    assert core.filter_slope_block(prep, 1) is None


def _ext(effect, joint=1):
    return SimpleNamespace(effect=effect, joint=joint, shared=False, cols={joint: np.zeros((5, 1))})


@pytest.mark.parametrize("beside, offered", [("stribeck", True), ("position_dependent_load", False)])
def test_only_the_check_beside_a_stribeck_law_offers_the_block(monkeypatch, beside, offered):
    """time_law_explained_by_state offers the block to the state's function of a law in time beside a Stribeck law,
    not beside another law of the state; where the function then explains the law with the block among its chosen
    blocks, the set-aside entry says so."""
    law, other = _ext("abrupt_change"), _ext(beside)
    model = SimpleNamespace(exts=[law, other])
    monkeypatch.setattr(core, RULE, True)
    monkeypatch.setattr(core, "filter_slope_block", lambda prep, j: {"filter_slope": np.ones((5, 2))})
    monkeypatch.setattr(core, "Model", lambda prep, exts: SimpleNamespace(exts=exts))
    seen = {}
    t = {"rmse_reduction": 0.001, "p_value": 0.5, "score": 0.1}

    def one_way(prep, m0, j, C, alpha, min_gain, extra=None, chosen=None):
        seen["extra"] = extra
        if chosen is not None and extra:
            chosen.append("filter_slope")
        return ((np.ones((5, 3)), t, 0.05, 0.4), t, 0)
    monkeypatch.setattr(core, "_state_explains_one_way", one_way)
    got = core.time_law_explained_by_state(None, model, [], core.ALPHA, core.MIN_GAIN)
    assert got[:2] == ("abrupt_change", 1)
    assert (seen["extra"] is not None) is offered
    assert bool(got[2].get("filter_slope_chosen")) is offered
    assert ("derivative filter's error" in got[2]["reason"]) is offered


def test_probe_touchable_and_control():
    """The probe's screen: a law in time and a Stribeck law among the findings, named or set aside, whatever the
    noise; the control draws 100 rows with a Stribeck law and no law in time, the same keys on every call, none of
    them touchable."""
    from conftest import bench_module
    probe = bench_module("probe_time_law_beside_stribeck_filter_slope")
    assert probe.touchable({"got": "ambiguous(abrupt_change|energy_dependent_friction)+stribeck"})
    assert probe.touchable({"got": "stribeck", "set_aside": ["energy_dependent_friction"]})
    assert probe.touchable({"got": "abrupt_change", "set_aside": ["stribeck"]})
    assert not probe.touchable({"got": "abrupt_change+position_dependent_load"})
    assert probe.control({"got": "position_dependent_load+stribeck"})
    assert not probe.control({"got": "stribeck", "set_aside": ["abrupt_change"]})
    keys = probe.control_keys("loop")
    assert len(keys) == probe.CONTROL_ROWS and keys == sorted(set(keys)) == probe.control_keys("loop")
    assert not set(keys) & set(probe.kept_keys("loop", probe.touchable))


@pytest.fixture(scope="module")
def design_case():
    """Fresh spec 41591 (an asymmetric level beside Stribeck at 250 Hz, a quantized torque) diagnosed with the
    hundred-and-second round's switch off and on: (module, spec, truth, off, on, the check's set-asides while on)."""
    from conftest import closed_loop_off_and_on, recording
    return closed_loop_off_and_on(41591, RULE, recording("time_law_explained_by_state",
                                                          lambda got, a, kw: [] if got is None else [got]))


@pytest.mark.long
def test_spec_41591_loses_the_change(design_case):
    """Off: an abrupt change is named beside the level (ambiguous with a load) and the Stribeck law, a wrong name.
    On: the state's function, holding the jerk through the speed kernels, explains the change (given it the change
    lowers the held-out RMSE by less than the least gain, the function alone by more than the change alone), the
    change is set aside with that reason, and the level (ambiguous with a load) and the Stribeck law are named."""
    mod, spec, truth, off, on, seen = design_case
    assert mod.judge(spec, off)["wrong"] == ["abrupt_change"]
    j = mod.judge(spec, on)
    assert j["wrong"] == [] and j["missed"] == [] and j["correct"]
    assert "abrupt_change" not in {f["effect"] for f in on["findings"]}
    assert {"stribeck"} <= {f["effect"] for f in on["findings"]}
    changes = [w for e, _, w in seen if e == "abrupt_change"]
    assert changes and all(w.get("filter_slope_chosen") for w in changes)
    for w in changes:
        assert w["state_law_test"]["rmse_reduction"] < core.MIN_GAIN
        assert w["state_heldout_rmse_reduction"] >= w["heldout_rmse_reduction_alone"]
    aside = {s["effect"]: s for s in on["set_aside"]}
    assert "derivative filter's error" in aside["abrupt_change"]["reason"]


def test_kept_and_its_table_is_its_jsons():
    """Kept: the switch is on; lanes a and b examined every touchable closed-loop row (41591 in b), lane c the 100
    control rows; no open-loop row is touchable; the rule acted in 13761 (its change already set aside with the rule
    off) and 41591 (mended); no row gained a wrong name, a finding on a null log or lost `unexplained` or an outright
    name, the missed effects did not rise, every rule-on row is its log's kept row (41591's folded), and the docs'
    table holds each lane's row as --against-off-rows prints it."""
    from conftest import REFOLDED_ROUND_102, bench_module, probe_lanes, probe_results
    assert core.TIME_LAW_BESIDE_STRIBECK_FILTER_SLOPE_RULE is True
    probe = bench_module("probe_time_law_beside_stribeck_filter_slope")
    doc, files, examined, s = probe_lanes(probe, "diagnose_time_law_beside_stribeck_filter_slope_round102_lane_*.json",
                                          lanes=[*"abcdefghijklmnopqrstuvwxyz", "za", "zb"])
    keys = [d["keys_examined"] for _, d in files]
    assert len(keys[0]) == len(keys[1]) == 282 and max(keys[0]) < min(keys[1]) and 41591 in keys[1]
    assert REFOLDED_ROUND_102 == {41591}
    # 41591, folded, still sets its change aside: it stays touchable
    touchable = probe.kept_keys("loop", probe.touchable)
    assert keys[0] + keys[1] == [k for k in touchable if k < 41600]
    # lane d: the touchable rows of the fresh blocks 41600-41799, run with the rule on
    assert keys[3] == [k for k in touchable if 41600 <= k < 41800] == [41613, 41679, 41701, 41723]
    # lane e: those of 41800-41999
    assert keys[4] == [k for k in touchable if 41800 <= k < 42000] == [41808, 41811, 41921, 41984]
    # lane f: those of 42000-42199
    assert keys[5] == [k for k in touchable if 42000 <= k < 42200] == [42050, 42097]
    # lane g: those of 42200-42399
    assert keys[6] == [k for k in touchable if 42200 <= k < 42400] == [42218, 42292, 42317, 42363]
    # lane h: those of 42400-42599
    assert keys[7] == [k for k in touchable if 42400 <= k < 42600] == [42405, 42495, 42504, 42556]
    # lane i: those of 42600-42799
    assert keys[8] == [k for k in touchable if 42600 <= k < 42800] == [42628, 42666, 42735, 42790]
    # lane j: those of 42800-42999
    assert keys[9] == [k for k in touchable if 42800 <= k < 43000] == [42845, 42864, 42889, 42971]
    # lane k: those of 43000-43399
    assert keys[10] == [k for k in touchable if 43000 <= k < 43400] == [43010, 43065, 43172, 43326, 43333, 43373]
    # lane l: those of 43400-43999
    assert keys[11] == [k for k in touchable if 43400 <= k < 44000] == [43461, 43505, 43538, 43703, 43714, 43744, 43747, 43788, 43857, 43898, 43945, 43967, 43986]
    # lane m: those of 44000-44199
    assert keys[12] == [k for k in touchable if 44000 <= k < 44200] == [44140, 44143]
    # lane n: those of 44200-44399
    assert keys[13] == [k for k in touchable if 44200 <= k < 44400] == [44264]
    # lane o: those of 44400-44599
    assert keys[14] == [k for k in touchable if 44400 <= k < 44600] == [44429, 44440, 44473]
    # lane p: those of 44600-44799
    assert keys[15] == [k for k in touchable if 44600 <= k < 44800] == [44668, 44671, 44737, 44756]
    assert keys[16] == [k for k in touchable if 44800 <= k < 45000] == [44836, 44957]
    assert keys[17] == [k for k in touchable if 45000 <= k < 45200] == [45045, 45067, 45133]
    assert keys[18] == [k for k in touchable if 45200 <= k < 45400] == [45232, 45298]
    assert keys[19] == [k for k in touchable if 45400 <= k < 45600] == [45419, 45430, 45460, 45526]
    assert keys[20] == [k for k in touchable if 45600 <= k < 45800] == [45631, 45705, 45749, 45795]
    assert keys[21] == [k for k in touchable if 45800 <= k < 46000] == [45966, 45993]
    assert keys[22] == [k for k in touchable if 46000 <= k < 46200] == [46057, 46145]
    assert keys[23] == [k for k in touchable if 46200 <= k < 46400] == [46276, 46277, 46343]
    assert keys[24] == [k for k in touchable if 46400 <= k < 46600] == [46453, 46475, 46563]
    assert keys[25] == [k for k in touchable if 46600 <= k < 46800] == [46607, 46651, 46783]
    assert keys[26] == [k for k in touchable if 46800 <= k < 47000] == [46915, 46934]
    assert keys[27] == [k for k in touchable if 47000 <= k < 47200] == [47028, 47069, 47113]
    assert probe.kept_keys("testbench", probe.touchable) == []
    # (drawn before the fresh blocks 41600-41799 joined the control rows' pool: today's draw differs)
    kept = {k: r for (f, _, k), (_, r) in bench_module("bench_diagnose_testbench").kept_rows_naming("any").items()
            if f == "loop"}
    assert len(keys[2]) == probe.CONTROL_ROWS and keys[2] == sorted(set(keys[2])) and max(keys[2]) < 41600
    assert all(probe.control(kept[k]) for k in keys[2]) and not set(keys[2]) & set(keys[0] + keys[1])
    assert [t["k"] for _, d in files for t in d["touched"]] == [13761, 41591]
    assert s["wrong_gained"] == s["null_findings_gained"] == s["oov_unexplained_lost"] == s["outright_lost"] == []
    assert s["wrong_lost"] == [41591] and s["missed_on"] <= s["missed_off"]
    for _, d in files:
        for t in d["touched"]:
            assert all(x["effect"] in core.TIME_LAWS and x["rmse_reduction_given_state"] < core.MIN_GAIN
                       and x["state_rmse_reduction"] >= x["rmse_reduction_alone"] for x in t["set_aside"])
    _, _, differences = probe_results("diagnose_time_law_beside_stribeck_filter_slope_round102_lane_*.json")
    for f, d in files:
        assert differences(d) == [], f.name
    assert "The rule acted in two logs of 752." in " ".join(doc.split())
