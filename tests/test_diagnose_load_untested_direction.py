"""The ninety-third round: a position load whose held-out gain lies mostly on the few samples moving in the direction
in which the log cannot test an asymmetric Coulomb level is reported ambiguous with that level
(``core.LOAD_IN_UNTESTED_DIRECTION_RULE``; ``benchmarks/results/diagnose_load_untested_direction_round93_rule.txt``)."""
from types import SimpleNamespace

import numpy as np
import pytest

from drake_est.diagnose import core
from drake_est.diagnose import detectors as det


def _joint(n_neg_train, n_train=400, n_val=400, n_neg_val=30):
    """A stand-in joint: ``n_train`` training rows (``n_neg_train`` moving in the negative direction), then ``n_val``
    held-out rows (``n_neg_val`` of them negative)."""
    v_tr = np.r_[-np.ones(n_neg_train), np.ones(n_train - n_neg_train)]
    v_va = np.r_[-np.ones(n_neg_val), np.ones(n_val - n_neg_val)]
    v = 0.1 * np.r_[v_tr, v_va]
    train = np.r_[np.ones(n_train, bool), np.zeros(n_val, bool)]
    return SimpleNamespace(joint=1, v=v, rows=np.arange(v.size), train=train, val=~train)


def test_untested_direction():
    """None where each direction holds at least 5 % (and 20) of the training rows; else the rare direction, its
    held-out rows and its training count, either way round."""
    assert core.untested_direction(_joint(40)) is None
    name, rows, n_rare, n_tr = core.untested_direction(_joint(8))
    assert (name, int(rows.sum()), n_rare, n_tr) == ("negative", 30, 8, 400)
    assert not det.asymmetric_testable(_joint(8))
    name, rows, n_rare, n_tr = core.untested_direction(_joint(395, n_neg_val=390))
    assert (name, int(rows.sum()), n_rare, n_tr) == ("positive", 10, 5, 400)
    jd = _joint(8)
    jd.train = np.zeros(jd.v.size, bool)
    assert core.untested_direction(jd) is None


def test_asymmetric_level_whether_or_not_testable():
    """``asymmetric_level`` builds the level's column (1 while moving in the negative direction) also where
    ``asymmetric`` refuses it."""
    jd = _joint(8)
    assert det.asymmetric(jd, None) is None
    lvl = det.asymmetric_level(jd)
    assert lvl.effect == "asymmetric_coulomb" and lvl.cols[1][:, 0].tolist() == (jd.v < 0).astype(float).tolist()
    assert det.asymmetric(_joint(40), None).cols[1].tolist() == det.asymmetric_level(_joint(40)).cols[1].tolist()


def test_off_it_marks_nothing(monkeypatch):
    """Switched off it returns at once (nothing fitted)."""
    monkeypatch.setattr(core, "LOAD_IN_UNTESTED_DIRECTION_RULE", False)
    assert core.mark_load_in_untested_direction(None, None, None, None, None) == []


def test_probe_candidates():
    """The probe's candidates: kept rows naming a position load, alone or in an ambiguity."""
    from conftest import bench_module
    probe = bench_module("probe_load_untested_direction")
    assert probe.candidate({"got": "position_dependent_load"})
    assert probe.candidate({"got": "ambiguous(asymmetric_coulomb|position_dependent_load)+stribeck"})
    assert not probe.candidate({"got": "asymmetric_coulomb"}) and not probe.candidate({"got": "none"})


@pytest.fixture(scope="module")
def design_case():
    """Fresh spec 35997 (an asymmetric level at 250 Hz, Student-t noise, moving in the negative direction in 8 of its
    6,344 selected training samples) diagnosed with the switch off and on: (module, spec, truth, off, on, None)."""
    from conftest import closed_loop_off_and_on
    return closed_loop_off_and_on(35997, "LOAD_IN_UNTESTED_DIRECTION_RULE")


def test_spec_35997_load_ambiguous_with_the_level(design_case):
    """Off: a position load named alone (a wrong name, the level missed). On: the same model, the load ambiguous with
    the level: 85 % of its held-out gain lies in the 57 held-out samples moving in the negative direction, and the
    level in its place predicts as well; the next experiment still asks for passes in that direction."""
    mod, spec, truth, off, on, _ = design_case
    assert truth["planted"] == ["asymmetric_coulomb"]
    assert [f["effect"] for f in off["findings"]] == ["position_dependent_load"]
    assert mod.judge(spec, off)["wrong"] == ["position_dependent_load"]
    assert [f["effect"] for f in on["findings"]] == ["position_dependent_load"]
    c = on["findings"][0]["competition"]
    assert c["ambiguous"] and c["ambiguous_with"] == ["asymmetric_coulomb"]
    info = c["untested_direction"]
    assert info["direction"] == "negative" and info["held_out_samples_in_direction"] == [57, 6935]
    assert info["selected_training_samples_in_direction"][0] == 8
    assert info["held_out_gain_share_in_direction"] > 0.8 and info["paired_p_value"] >= core.PAIRED_ALPHA
    j = mod.judge(spec, on)
    assert j["wrong"] == [] and j["missed"] == [] and j["correct"]
    assert any(n.get("direction") == "negative" for n in on["next_experiment"])


def test_kept_and_its_table_is_its_jsons():
    """Kept: the switch is on; the screens covered every kept row naming a load (9,494 closed-loop rows below the fresh
    blocks 36000-36399 in two lanes, 66 with an untestable level and held-out rows in its rare direction, one refused;
    the 23 open-loop rows, none; screen c: the 109 of 36000-36399, one; screen d: the 107 of 36400-36799, none;
    screen e: the 104 of 36800-37199, none; screen f: the 51 of 37200-37399, none; screen g: the 52 of
    37400-37599, none; screen h: the 105 of 37600-37999, none; screen i: the 53 of
    38000-38199, none; screen j: the 54 of 38200-38399, one); the probe every screened log
    (lanes a and b, alternate keys; c; d); the rule marked a load in the design log only, which lost its wrong name, and
    nothing was lost; the docs' table holds each lane's row as --against-off-rows prints it."""
    import json
    from pathlib import Path
    from conftest import assert_fresh_screens, bench_module, probe_lanes, probe_results
    assert core.LOAD_IN_UNTESTED_DIRECTION_RULE is True
    probe = bench_module("probe_load_untested_direction")
    root = Path(__file__).resolve().parents[1] / "benchmarks" / "results"
    screens = {x: json.loads((root / f"diagnose_load_untested_direction_round93_screen_{x}.json").read_text())
               for x in ("0", "1", "testbench", "c", "d", "e", "f", "g", "h", "i", "j", "k", "l", "m", "n", "o", "p", "q", "r", "s", "t", "u", "v", "w", "x", "y", "z", "za", "zb", "zc", "zd", "ze", "zf", "zg", "zh", "zi", "zj", "zk", "zl", "zm", "zn", "zo", "zp", "zq", "zr", "zs", "zt", "zu", "zv", "zw", "zx", "zy")}
    loop = [k for x in ["0", "1", *"cdefghijklmnopqrstuvwxyz", "za", "zb", "zc", "zd", "ze", "zf", "zg", "zh", "zi", "zj", "zk", "zl", "zm", "zn", "zo", "zp", "zq", "zr", "zs", "zt", "zu", "zv", "zw", "zx", "zy"] for k in screens[x]["keys_screened"]]
    # (37278 was screened before the ninety-fifth round's fold took its load away)
    # (and the ninety-sixth round's fold made some rows name a load: REFOLDED_ROUND_96)
    from conftest import REFOLDED_ROUND_96
    assert sorted(set(loop) - {37278} - REFOLDED_ROUND_96) == [k for k in probe.candidate_keys("loop")
                                                              if k not in REFOLDED_ROUND_96]
    assert len(set(loop)) == len(loop)
    assert len(loop) - sum(len(screens[x]["keys_screened"]) for x in [*"cdefghijklmnopqrstuvwxyz", "za", "zb", "zc", "zd", "ze", "zf", "zg", "zh", "zi", "zj", "zk", "zl", "zm", "zn", "zo", "zp", "zq", "zr", "zs", "zt", "zu", "zv", "zw", "zx", "zy"]) == 9494
    assert max(screens["0"]["keys_screened"]) < 36000
    # the fresh blocks' screens c-l: (size, first spec of the blocks); d-i list no log, j lists 38332, k 38420, l 38706, m none, n 39019, o 39209, p none, q 39647, r none, s 40044, t none, u none, v none, w none, x none, y none, z none, za none, zb none, zc none, zd 42252 and 42375, ze none, zf none, zg none, zh 43065 and 43125, zi 43462 and 43630 and 43915, zj none, zk none, zl none, zm none, zn none, zo 45020, zp 45302, zq none, zr none, zs 45883, zt 46055 and 46138, zu 46358, zv none, zw 46715, zx 46934, zy none
    assert_fresh_screens(zip((screens[x] for x in [*"cdefghijklmnopqrstuvwxyz", "za", "zb", "zc", "zd", "ze", "zf", "zg", "zh", "zi", "zj", "zk", "zl", "zm", "zn", "zo", "zp", "zq", "zr", "zs", "zt", "zu", "zv", "zw", "zx", "zy"]), (109, 107, 104, 51, 52, 105, 53, 54, 53, 55, 52, 51, 51, 50, 49, 53, 51, 53, 52, 54, 52, 51, 53, 55, 52, 53, 54, 58, 53, 54, 53, 105, 156, 53, 50, 55, 51, 53, 55, 54, 53, 52, 52, 53, 48, 49, 57, 48, 52),
                             (36000, 36400, 36800, 37200, 37400, 37600, 38000, 38200, 38400, 38600, 38800, 39000,
                              39200, 39400, 39600, 39800, 40000, 40200, 40400, 40600, 40800, 41000, 41200, 41400, 41600, 41800, 42000, 42200, 42400, 42600, 42800, 43000, 43400, 44000, 44200, 44400, 44600, 44800, 45000, 45200, 45400, 45600, 45800, 46000, 46200, 46400, 46600, 46800, 47000),
                             strict=True))
    assert all(screens[x]["touched"] == [] for x in "defghi")
    assert [k for k, _ in screens["j"]["touched"]] == [38332]
    assert [k for k, _ in screens["k"]["touched"]] == [38420]
    assert [k for k, _ in screens["l"]["touched"]] == [38706]
    assert screens["m"]["touched"] == []
    assert [k for k, _ in screens["n"]["touched"]] == [39019]
    assert [k for k, _ in screens["o"]["touched"]] == [39209]
    assert screens["p"]["touched"] == []
    assert [k for k, _ in screens["q"]["touched"]] == [39647]
    assert screens["r"]["touched"] == []
    assert [k for k, _ in screens["s"]["touched"]] == [40044]
    assert screens["t"]["touched"] == [] and screens["u"]["touched"] == [] and screens["v"]["touched"] == [] and screens["w"]["touched"] == [] and screens["x"]["touched"] == [] and screens["y"]["touched"] == [] and screens["z"]["touched"] == [] and screens["za"]["touched"] == [] and screens["zb"]["touched"] == [] and screens["zc"]["touched"] == []
    assert [k for k, _ in screens["zd"]["touched"]] == [42252, 42375] and screens["ze"]["touched"] == [] == screens["zf"]["touched"]
    assert [k for k, _ in screens["zg"]["touched"]] == []
    assert [k for k, _ in screens["zh"]["touched"]] == [43065, 43125]
    assert [k for k, _ in screens["zi"]["touched"]] == [43462, 43630, 43915]
    assert [k for k, _ in screens["zj"]["touched"]] == []
    assert [k for k, _ in screens["zk"]["touched"]] == []
    assert [k for k, _ in screens["zl"]["touched"]] == []
    assert [k for k, _ in screens["zm"]["touched"]] == []
    assert [k for k, _ in screens["zn"]["touched"]] == []
    assert [k for k, _ in screens["zo"]["touched"]] == [45020]
    assert [k for k, _ in screens["zp"]["touched"]] == [45302]
    assert [k for k, _ in screens["zq"]["touched"]] == []
    assert [k for k, _ in screens["zr"]["touched"]] == []
    assert [k for k, _ in screens["zs"]["touched"]] == [45883]
    assert [k for k, _ in screens["zt"]["touched"]] == [46055, 46138]
    assert [k for k, _ in screens["zu"]["touched"]] == [46358]
    assert [k for k, _ in screens["zv"]["touched"]] == []
    assert [k for k, _ in screens["zw"]["touched"]] == [46715]
    assert [k for k, _ in screens["zx"]["touched"]] == [46934]
    assert [k for k, _ in screens["zy"]["touched"]] == []
    assert screens["testbench"]["keys_screened"] == probe.candidate_keys("testbench")
    assert len(screens["testbench"]["keys_screened"]) == 23 and screens["testbench"]["touched"] == []
    assert [k for x in ["0", "1", *"cdefghijklmnopqrstuvwxyz", "za", "zb", "zc", "zd", "ze", "zf", "zg", "zh", "zi", "zj", "zk", "zl", "zm", "zn", "zo", "zp", "zq", "zr", "zs", "zt", "zu", "zv", "zw", "zx", "zy"] for k, _ in screens[x]["refused"]] == [17787]
    listed = probe.screened_keys([root / f"diagnose_load_untested_direction_round93_screen_{x}.json" for x in ["0", "1", *"cdefghijklmnopqrstuvwxyz", "za", "zb", "zc", "zd", "ze", "zf", "zg", "zh", "zi", "zj", "zk", "zl", "zm", "zn", "zo", "zp", "zq", "zr", "zs", "zt", "zu", "zv", "zw", "zx", "zy"]])
    assert len(listed) == 89 and 35997 in listed
    doc, files, examined, s = probe_lanes(probe, "diagnose_load_untested_direction_round93_lane_*.json", lanes="abcdefghijklmnopqrst")
    assert [len(d["keys_examined"]) for _, d in files] == [33, 33, 1, 1, 1, 1, 1, 1, 1, 1, 2, 2, 3, 1, 1, 1, 2, 1, 1, 1]
    assert sorted(examined["loop"]) == listed and not examined["testbench"]
    # it marked the design log 35997 and, in lane h, 39209 (an asymmetric level at 50 Hz, quantized): both lose a
    # wrong name; in lane l, 43065 (an asymmetric level beside Stribeck at 10 Hz, Student-t): its level, missed with the
    # rule off, is named; every rule-on row is its log's kept row (35997's folded, the others their fresh block's, run
    # with the rule)
    assert [t["k"] for _, d in files for t in d["touched"]] == [35997, 39209, 43065]
    assert s["wrong_gained"] == s["null_findings_gained"] == s["oov_unexplained_lost"] == s["outright_lost"] == []
    assert s["wrong_lost"] == [35997, 39209] and s["missed_on"] < s["missed_off"]
    _, _, differences = probe_results("diagnose_load_untested_direction_round93_lane_*.json")
    for f, d in files:
        assert differences(d) == [], f.name
    assert "It marked a load in three logs of 89" in " ".join(doc.split())
