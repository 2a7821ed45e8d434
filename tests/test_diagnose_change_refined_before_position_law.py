"""The hundredth round: an abrupt change whose switch is chosen again jointly with the rest of the model when a round
accepts a law of its joint's position beside it, kept where the law then falls
(``core.change_refined_before_position_law``, ``core.CHANGE_REFINED_WHERE_LAW_FALLS_RULE``; rule file
``benchmarks/results/diagnose_change_refined_before_position_law_round100_rule.txt``)."""
from types import SimpleNamespace

import numpy as np
import pytest

from drake_est.diagnose import core
from drake_est.diagnose import detectors as det


def test_joint_split_costs_are_those_of_each_split_fitted_on_its_own():
    """At every split the cost is the RSS of y on [X, C after the split] by least squares, inf for segments shorter
    than ``min_len``; the least-cost split of a step planted beside columns that partly fit it is the planted one."""
    rng = np.random.default_rng(100)
    n, min_len = 120, 15
    t = np.linspace(0.0, 1.0, n)
    X = np.column_stack([np.ones(n), np.sin(6 * t), np.cos(6 * t), t])
    v = rng.normal(size=n)
    C = np.column_stack([v, np.sign(v)])
    y = X @ rng.normal(size=4) + (t >= t[70]) * (C @ np.array([0.8, 1.5])) + 0.05 * rng.normal(size=n)
    got = det.joint_split_costs(X, C, y, min_len)
    assert got.shape == (n + 1,) and np.isinf(got[:min_len]).all() and np.isinf(got[n - min_len + 1:]).all()
    for k in range(min_len, n - min_len + 1):
        A = np.column_stack([X, C * (np.arange(n) >= k)[:, None]])
        e = y - A @ np.linalg.lstsq(A, y, rcond=None)[0]
        assert got[k] == pytest.approx(float(e @ e), rel=1e-8, abs=1e-10)
    assert int(np.argmin(got)) == 70
    assert np.isinf(det.joint_split_costs(X, C, y, n)).all()      # no split leaves two segments that long
    # collinear columns (a repeated column, a sum of two) span no more than X: the same costs
    Xc = np.column_stack([X, X[:, 1], X[:, 2] + X[:, 3]])
    assert np.allclose(det.joint_split_costs(Xc, C, y, min_len)[min_len:n - min_len + 1], got[min_len:n - min_len + 1],
                       rtol=1e-8)


def test_off_or_out_of_its_case_it_leaves_the_model(monkeypatch):
    """Switch off, a shared law, a finding that is no law of position, or no change of the law's joint in the model:
    the model and fit come back as they were, with nothing moved and nothing fitted."""
    law = SimpleNamespace(effect="position_dependent_load", joint=1, shared=False)
    change = SimpleNamespace(effect="abrupt_change", joint=1, shared=False)
    model, fit = SimpleNamespace(exts=[change, law]), object()
    monkeypatch.setattr(core, "CHANGE_REFINED_WHERE_LAW_FALLS_RULE", False)
    assert core.change_refined_before_position_law(None, model, fit, None, law) == (model, fit, [])
    monkeypatch.setattr(core, "CHANGE_REFINED_WHERE_LAW_FALLS_RULE", True)
    cases = [(model, SimpleNamespace(effect="position_dependent_load", joint=1, shared=True)),
             (model, SimpleNamespace(effect="motor_position_ripple", joint=1, shared=False)),
             (SimpleNamespace(exts=[SimpleNamespace(effect="abrupt_change", joint=2, shared=False), law]), law),
             (SimpleNamespace(exts=[law]), law)]
    for m, ext in cases:
        assert core.change_refined_before_position_law(None, m, fit, None, ext) == (m, fit, [])


def test_probe_touchable_and_control():
    """The probe's screen: an abrupt change and a law of position among the findings, named or set aside; the control
    draws 100 rows that name a change and no law of position, the same keys on every call, none of them touchable."""
    from conftest import bench_module
    probe = bench_module("probe_change_refined_before_position_law")
    assert probe.touchable({"got": "abrupt_change+motor_position_ripple+position_dependent_load"})
    assert probe.touchable({"got": "abrupt_change", "set_aside": ["position_dependent_friction"]})
    assert probe.touchable({"got": "ambiguous(abrupt_change|energy_dependent_friction)+position_dependent_load"})
    assert probe.touchable({"got": "position_dependent_load", "set_aside": ["abrupt_change"]})
    assert not probe.touchable({"got": "abrupt_change+motor_position_ripple", "set_aside": ["stribeck"]})
    assert not probe.touchable({"got": "position_dependent_load"})
    assert probe.control({"got": "abrupt_change+motor_position_ripple"})
    assert not probe.control({"got": "abrupt_change", "set_aside": ["position_dependent_load"]})
    keys = probe.control_keys("loop")
    assert len(keys) == probe.CONTROL_ROWS and keys == sorted(set(keys)) == probe.control_keys("loop")
    assert not set(keys) & set(probe.kept_keys("loop", probe.touchable))


@pytest.fixture(scope="module")
def design_case():
    """Fresh spec 41128 (an abrupt change at 63.0 s beside a motor ripple at 100 Hz, Student-t noise) diagnosed with
    the hundredth round's switch off and on: (module, spec, truth, off, on, None)."""
    from conftest import closed_loop_off_and_on
    return closed_loop_off_and_on(41128, "CHANGE_REFINED_WHERE_LAW_FALLS_RULE")


def test_spec_41128_loses_the_load(design_case):
    """Off: the change sits at 44.1 s, 19 s before the generator's switch, and a load takes the misplaced switch's
    misfit (a wrong name).  On: the switch chosen jointly with the ripple lies within the training rows' gap around
    the generator's (62.9-68.7 s), the load falls, and the change and the ripple are named."""
    mod, spec, truth, off, on, _ = design_case
    t_true = truth["abrupt_change"]["t_change"]
    assert mod.judge(spec, off)["wrong"] == ["position_dependent_load"]
    ch_off = next(f for f in off["findings"] if f["effect"] == "abrupt_change")
    assert abs(ch_off["parameters"]["t_change_s"] - t_true) > 15
    j = mod.judge(spec, on)
    assert j["wrong"] == [] and j["missed"] == [] and j["correct"]
    assert sorted(f["effect"] for f in on["findings"]) == ["abrupt_change", "motor_position_ripple"]
    ch = next(f for f in on["findings"] if f["effect"] == "abrupt_change")
    assert 62.9 <= ch["parameters"]["t_change_s"] <= 68.7 and abs(ch["parameters"]["t_change_s"] - t_true) < 3


def test_kept_and_its_table_is_its_jsons():
    """Kept: the switch is on; lanes a and b examined every touchable closed-loop row as drawn (41128 among them),
    lane c every touchable open-loop row, lane d the 100 control rows; the rule acted in 16004 (the same names) and
    41128 (mended) only; no row gained a wrong name, a finding on a null log or lost `unexplained` or an outright
    name, the missed effects did not rise, every rule-on row is its log's kept row (the two folded), and the docs'
    table holds each lane's row as --against-off-rows prints it."""
    from conftest import REFOLDED_ROUND_100, bench_module, probe_lanes, probe_results
    assert core.CHANGE_REFINED_WHERE_LAW_FALLS_RULE is True
    probe = bench_module("probe_change_refined_before_position_law")
    doc, files, examined, s = probe_lanes(probe, "diagnose_change_refined_before_position_law_round100_lane_*.json",
                                          lanes=[*"abcdefghijklmnopqrstuvwxyz", "za", "zb", "zc", "zd", "ze"])
    keys = [d["keys_examined"] for _, d in files]
    lane_ab = sorted(keys[0] + keys[1])
    assert len(keys[0]) == len(keys[1]) == 276 and lane_ab == sorted(set(lane_ab)) and 41128 in keys[0]
    # as drawn: the touchable kept rows below the fresh blocks from 41200 on; of the two folded rows 16004 no longer
    # sets a position friction aside and left the screen, 41128 still sets one aside; 36374, folded by the
    # hundred-and-first round, names no change any more and left it too
    from conftest import REFOLDED_ROUND_101
    touchable = probe.kept_keys("loop", probe.touchable)
    assert set(lane_ab) - {16004} - REFOLDED_ROUND_101 == {k for k in touchable if k < 41200}
    assert REFOLDED_ROUND_100 == {16004, 41128} and REFOLDED_ROUND_100 & set(touchable) == {41128}
    assert keys[2] == probe.kept_keys("testbench", probe.touchable) and files[2][1]["family"] == "testbench"
    # lane e: the touchable rows of the fresh blocks 41200-41399, run with the rule on
    assert keys[4] == [k for k in touchable if 41200 <= k < 41400] == [41233, 41284]
    # lane f: the touchable rows of the fresh blocks 41400-41599, run with the rule on
    assert keys[5] == [k for k in touchable if 41400 <= k < 41600] == [41591]
    # lane g: the touchable rows of the fresh blocks 41600-41799, run with the rule on
    assert keys[6] == [k for k in touchable if 41600 <= k < 41800] == [41613, 41651, 41677, 41679, 41723]
    assert keys[7] == [k for k in touchable if 41800 <= k < 42000] == [41803, 41808, 41878, 41921, 41984]
    assert keys[8] == [k for k in touchable if 42000 <= k < 42200] == [42001, 42097, 42142]
    assert keys[9] == [k for k in touchable if 42200 <= k < 42400] == [42292, 42317, 42363]
    assert keys[10] == [k for k in touchable if 42400 <= k < 42600] == [42429, 42448, 42495, 42510]
    assert keys[11] == [k for k in touchable if 42600 <= k < 42800] == [42627, 42664, 42666, 42735]
    assert keys[12] == [k for k in touchable if 42800 <= k < 43000] == [42800, 42816, 42845, 42864, 42889, 42971]
    assert keys[13] == [k for k in touchable if 43000 <= k < 43400] == [43060, 43065, 43089, 43132, 43172, 43200]
    assert keys[14] == [k for k in touchable if 43400 <= k < 44000] == [43461, 43505, 43585, 43747, 43788, 43838, 43915, 43945]
    assert keys[15] == [k for k in touchable if 44000 <= k < 44200] == [44054, 44140]
    assert [k for k in touchable if 44200 <= k < 44400] == []
    assert keys[16] == [k for k in touchable if 44400 <= k < 44600] == [44409, 44581]
    assert keys[17] == [k for k in touchable if 44600 <= k < 44800] == [44647, 44668, 44737, 44756]
    assert keys[18] == [k for k in touchable if 44800 <= k < 45000] == [44924, 44938, 44957]
    assert keys[19] == [k for k in touchable if 45000 <= k < 45200] == [45037, 45044, 45045, 45067, 45133, 45157, 45172]
    assert keys[20] == [k for k in touchable if 45200 <= k < 45400] == [45238]
    assert keys[21] == [k for k in touchable if 45400 <= k < 45600] == [45419, 45433, 45526]
    assert keys[22] == [45631, 45705, 45749, 45772, 45795]
    # lane x: 45767, which the hundred-and-eighth round's fold made touchable (its change set aside beside a drift)
    from conftest import REFOLDED_ROUND_108
    assert keys[23] == [45767] and REFOLDED_ROUND_108 == {45767}
    assert keys[24] == [k for k in touchable if 45800 <= k < 46000] == [45966, 45993]
    assert keys[25] == [k for k in touchable if 46000 <= k < 46200] == [46057]
    assert keys[26] == [k for k in touchable if 46200 <= k < 46400] == [46233, 46298, 46343, 46360, 46362, 46366]
    assert keys[27] == [k for k in touchable if 46400 <= k < 46600] == [46453]
    assert keys[28] == [k for k in touchable if 46600 <= k < 46800] == [46607, 46627, 46762]
    assert keys[29] == [k for k in touchable if 46800 <= k < 47000] == [46808, 46825, 46934, 46974]
    assert keys[30] == [k for k in touchable if 47000 <= k < 47200] == [47068, 47069]
    assert [k for k in touchable if 45600 <= k < 45800] == sorted(keys[22] + keys[23])
    kept = {k: r for (f, _, k), (_, r) in bench_module("bench_diagnose_testbench").kept_rows_naming("any").items()
            if f == "loop"}
    assert len(keys[3]) == probe.CONTROL_ROWS and all(probe.control(kept[k]) for k in keys[3])
    assert not set(keys[3]) & set(lane_ab)
    assert [t["k"] for _, d in files for t in d["touched"]] == [16004, 41128]
    moved = {t["k"]: t["refined"][0]["moved"][0] for _, d in files for t in d["touched"]}
    assert moved[41128]["from_t_change_s"] == pytest.approx(44.095) and 62.9 <= moved[41128]["to_t_change_s"] <= 68.7
    assert abs(moved[16004]["to_t_change_s"] - 54.356) < 0.05 < abs(moved[16004]["from_t_change_s"] - 54.356)
    assert s["wrong_gained"] == s["null_findings_gained"] == s["oov_unexplained_lost"] == s["outright_lost"] == []
    assert s["wrong_lost"] == [41128] and s["missed_on"] <= s["missed_off"]
    _, _, differences = probe_results("diagnose_change_refined_before_position_law_round100_lane_*.json")
    for f, d in files:
        assert differences(d) == [], f.name
    assert "The rule acted in two logs of 753." in " ".join(doc.split())
