"""The ninety-fourth and ninety-fifth rounds: a motor ripple refined on the residual of the model without a law of
its joint's position that a round has just accepted (``core.ripple_refined_before_position_law``).  The ninety-fourth
round's rule (``core.RIPPLE_REFINED_BEFORE_POSITION_LAW_RULE``) was not kept; the ninety-fifth's
(``core.RIPPLE_REFINED_WHERE_LAW_FALLS_RULE``) acts only where the law falls given the refined ripple
(``benchmarks/results/diagnose_ripple_*_round9[45]_rule.txt``)."""
from types import SimpleNamespace

import numpy as np
import pytest

from drake_est.diagnose import core


def test_off_or_out_of_its_case_it_leaves_the_model(monkeypatch):
    """Both switches off, a shared law, a finding that is no law of position, or no ripple of the law's joint in the
    model: the model and fit come back as they were, with nothing moved and nothing fitted."""
    law = SimpleNamespace(effect="position_dependent_load", joint=1, shared=False)
    ripple = SimpleNamespace(effect="motor_position_ripple", joint=1, shared=False)
    model, fit = SimpleNamespace(exts=[ripple, law]), object()
    monkeypatch.setattr(core, "RIPPLE_REFINED_BEFORE_POSITION_LAW_RULE", False)
    monkeypatch.setattr(core, "RIPPLE_REFINED_WHERE_LAW_FALLS_RULE", False)
    assert core.ripple_refined_before_position_law(None, model, fit, None, law) == (model, fit, [])
    monkeypatch.setattr(core, "RIPPLE_REFINED_WHERE_LAW_FALLS_RULE", True)
    cases = [(model, SimpleNamespace(effect="position_dependent_load", joint=1, shared=True)),
             (model, SimpleNamespace(effect="abrupt_change", joint=1, shared=False)),
             (SimpleNamespace(exts=[SimpleNamespace(effect="motor_position_ripple", joint=2, shared=False), law]), law),
             (SimpleNamespace(exts=[law]), law)]
    for m, ext in cases:
        assert core.ripple_refined_before_position_law(None, m, fit, None, ext) == (m, fit, [])


def test_probe_touchable_and_control():
    """The probe's screen: a ripple and a law of position among the findings, named or set aside; the control draws
    100 rows that name a ripple and no law of position, the same keys on every call, none of them touchable."""
    from conftest import bench_module
    probe = bench_module("probe_ripple_before_position_law")
    assert probe.touchable({"got": "abrupt_change+motor_position_ripple+position_dependent_load"})
    assert probe.touchable({"got": "motor_position_ripple", "set_aside": ["position_dependent_friction"]})
    assert probe.touchable({"got": "ambiguous(abrupt_change|position_dependent_load)",
                            "set_aside": ["motor_position_ripple"]})
    assert not probe.touchable({"got": "motor_position_ripple+abrupt_change", "set_aside": ["stribeck"]})
    assert not probe.touchable({"got": "position_dependent_load"})
    assert probe.control({"got": "motor_position_ripple"})
    assert not probe.control({"got": "motor_position_ripple", "set_aside": ["position_dependent_load"]})
    keys = probe.control_keys("loop")
    assert len(keys) == probe.CONTROL_ROWS and keys == sorted(set(keys)) == probe.control_keys("loop")
    assert not set(keys) & set(probe.kept_keys("loop", probe.touchable))
    with pytest.raises(SystemExit, match="not a probe JSON"):
        probe.examined_keys(["no/such/lane.json"])


@pytest.fixture(scope="module")
def design_case():
    """Fresh spec 37278 (an abrupt change beside a motor ripple at 100 Hz, quantized torque) diagnosed with the
    ninety-fifth round's switch off and on: (module, spec, truth, off, on, None)."""
    from conftest import closed_loop_off_and_on
    return closed_loop_off_and_on(37278, "RIPPLE_REFINED_WHERE_LAW_FALLS_RULE")


def test_spec_37278_loses_the_load(design_case):
    """Off: the ripple stays at 5.529 cycles/rad beside the generator's 5.5704 and a load takes its phase misfit (a
    wrong name). On: the ripple refined without the load lies within 0.001 cycles/rad of the generator's frequency and
    harmonic, the load falls, and the change and the ripple are named."""
    mod, spec, truth, off, on, _ = design_case
    f0 = truth["motor_position_ripple"]["frequency_per_arm_rad"]
    assert mod.judge(spec, off)["wrong"] == ["position_dependent_load"]
    rip_off = next(f for f in off["findings"] if f["effect"] == "motor_position_ripple")
    assert abs(rip_off["evidence"]["frequencies_per_arm_rad"][0] - f0) > 0.03
    j = mod.judge(spec, on)
    assert j["wrong"] == [] and j["missed"] == [] and j["correct"]
    assert sorted(f["effect"] for f in on["findings"]) == ["abrupt_change", "motor_position_ripple"]
    rip = next(f for f in on["findings"] if f["effect"] == "motor_position_ripple")
    assert np.allclose(rip["evidence"]["frequencies_per_arm_rad"], [f0, 2 * f0], atol=1e-3)


@pytest.mark.long
@pytest.mark.xfail(strict=False, reason="known, measured 2026-12-07: on an AMD EPYC (e944c51's code and the "
                   "hundred-and-eighth round's alike) the ninety-fourth round's redo of 16004 names no position "
                   "friction, so the wrong name that made the round not kept does not show; it holds on the Intel Xeon "
                   "of the ninety-fourth round: the path depends on the CPU's last digits")
def test_spec_16004_why_the_ninety_fourth_round_was_not_kept():
    """16004 (an abrupt change beside a ripple at 37.56 cycles/rad, 250 Hz): the ninety-fourth round's rule moves the
    ripple a little, and the redo names a position friction the rule-off search sets aside; the ninety-fifth round's
    rule leaves it alone (the friction still stands given the refined ripple), so it is as with both switches off.
    With the hundredth round's switch off, as the rounds ran (on, the change's switch refined beside the ripple takes
    the friction's misfit first: tests/test_diagnose_change_refined_before_position_law.py)."""
    from conftest import closed_loop_case
    from drake_est.diagnose import diagnose
    mod, spec, log, truth = closed_loop_case(16004)
    mp = pytest.MonkeyPatch()
    got = {}
    try:
        mp.setattr(core, "CHANGE_REFINED_WHERE_LAW_FALLS_RULE", False)
        for name, s94, s95 in (("off", False, False), ("94", True, False), ("95", False, True)):
            mp.setattr(core, "RIPPLE_REFINED_BEFORE_POSITION_LAW_RULE", s94)
            mp.setattr(core, "RIPPLE_REFINED_WHERE_LAW_FALLS_RULE", s95)
            got[name] = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    finally:
        mp.undo()
    assert mod.judge(spec, got["off"])["correct"] and mod.judge(spec, got["95"])["correct"]
    assert mod.judge(spec, got["94"])["wrong"] == ["position_dependent_friction"]
    names = {k: sorted(f["effect"] for f in d["findings"]) for k, d in got.items()}
    assert names["off"] == names["95"] == ["abrupt_change", "motor_position_ripple"]


def test_kept_and_its_tables_are_its_jsons():
    """The ninety-fourth round: off; its lanes (a: the 92 touchable closed-loop rows below the fresh blocks 37400-37599,
    b: all 150 open-loop rows, c: the 100 control rows) gained 16004 a wrong name.  The ninety-fifth: on; it reran lanes
    a and c (and d: the two touchable fresh rows of 37400-37599; e: 38047 of 38000-38199), acted only in logs where the ninety-fourth fired, mended 37278 and
    lost nothing; its rule-on rows are the kept rows (folded)."""
    from conftest import bench_module, probe_lanes, probe_results
    assert core.RIPPLE_REFINED_BEFORE_POSITION_LAW_RULE is False
    assert core.RIPPLE_REFINED_WHERE_LAW_FALLS_RULE is True
    probe = bench_module("probe_ripple_before_position_law")
    doc94, f94, ex94, s94 = probe_lanes(probe, "diagnose_ripple_before_position_law_round94_lane_*.json", lanes="abc")
    doc95, f95, ex95, s95 = probe_lanes(probe, "diagnose_ripple_where_law_falls_round95_lane_*.json", lanes="acdefghijklmnopqrstuvwxyz")
    # drawn before the fold, which took 6346 and 37278 out of the touchable rows (6346 is now a control row), and
    # before the hundredth round's, which took 16004 out (no position friction set aside any more), and before the
    # hundred-and-sixth round's, which took 18768 out (no load set aside any more)
    touchable = probe.kept_keys("loop", probe.touchable)
    lane_a, lane_c = f94[0][1]["keys_examined"], f94[2][1]["keys_examined"]
    assert lane_a == f95[0][1]["keys_examined"] == sorted([k for k in touchable if k < 37400] + [6346, 16004, 18768, 37278])
    assert lane_c == f95[1][1]["keys_examined"] == sorted(set(lane_c)) and len(lane_c) == probe.CONTROL_ROWS
    kept = {k: r for (f, _, k), (_, r) in bench_module("bench_diagnose_testbench").kept_rows_naming("any").items()
            if f == "loop"}
    assert all(probe.control(kept[k]) for k in lane_c) and not set(lane_c) & set(lane_a)
    assert f95[2][1]["keys_examined"] == [k for k in touchable if 37400 <= k < 38000] == [37453, 37564]
    assert f95[3][1]["keys_examined"] == [k for k in touchable if 38000 <= k < 38400] == [38047]
    assert f95[4][1]["keys_examined"] == [k for k in touchable if 38400 <= k < 38600] == [38531]
    assert f95[5][1]["keys_examined"] == [k for k in touchable if 38600 <= k < 39000] == [38685]
    assert f95[6][1]["keys_examined"] == [k for k in touchable if 39000 <= k < 39400] == [39040, 39060]
    assert f95[7][1]["keys_examined"] == [k for k in touchable if 39400 <= k < 39600] == [39521]
    assert f95[8][1]["keys_examined"] == [k for k in touchable if 39600 <= k < 39800] == [39632]
    assert f95[9][1]["keys_examined"] == [k for k in touchable if 39800 <= k < 40800] == [39808]     # 40000-40799: none
    assert f95[10][1]["keys_examined"] == [k for k in touchable if 40800 <= k < 41000] == [40841]
    assert f95[11][1]["keys_examined"] == [k for k in touchable if 41000 <= k < 41200] == [41128]     # folded by the hundredth round
    assert f95[12][1]["keys_examined"] == [k for k in touchable if 41200 <= k < 41800] == [41303]     # 41400-41799: none
    assert f95[13][1]["keys_examined"] == [k for k in touchable if 41800 <= k < 42400] == [41808]     # 42000-42399: none
    assert f95[14][1]["keys_examined"] == [k for k in touchable if 42400 <= k < 42600] == [42448]
    assert f95[15][1]["keys_examined"] == [k for k in touchable if 42600 <= k < 42800] == [42689]
    assert f95[16][1]["keys_examined"] == [k for k in touchable if 42800 <= k < 43400] == [42800]
    assert f95[17][1]["keys_examined"] == [k for k in touchable if 43400 <= k < 44000] == [43915]
    # (44020 left the touchable rows when the hundred-and-sixth round folded it: no finding any more)
    assert f95[18][1]["keys_examined"] == [44020, 44054] and [k for k in touchable if 44000 <= k < 44200] == [44054]
    assert f95[19][1]["keys_examined"] == [k for k in touchable if 44200 <= k < 45200] == [45021, 45044]     # 44200-44999: none
    assert not [k for k in touchable if 45200 <= k < 45600]
    assert f95[20][1]["keys_examined"] == [k for k in touchable if 45600 <= k < 45800] == [45681]
    assert f95[21][1]["keys_examined"] == [k for k in touchable if 45800 <= k < 46000] == [45807]
    assert not [k for k in touchable if 46000 <= k < 46200]
    assert f95[22][1]["keys_examined"] == [k for k in touchable if 46200 <= k < 46400] == [46209, 46298]
    assert not [k for k in touchable if 46400 <= k < 46800]
    assert f95[23][1]["keys_examined"] == [k for k in touchable if 46800 <= k < 47000] == [46841]
    assert f95[24][1]["keys_examined"] == [k for k in touchable if 47000 <= k < 47200] == [47068]
    assert probe.examined_keys([f for f, _ in f94[:1]]) == lane_a
    assert len(ex94["testbench"]) == 150 and [t for t in f94[1][1]["touched"]] == []
    assert s94["wrong_gained"] == [16004] and s94["wrong_lost"] == [37278]
    fired94 = {t["k"] for _, d in f94 for t in d["touched"]}
    fired95 = [t["k"] for _, d in f95 for t in d["touched"]]
    assert fired95 == [6346, 37278, 13884, 42800] and set(fired95) - {42800} <= fired94     # 42800: a fresh row, after round 94
    assert s95["wrong_gained"] == s95["null_findings_gained"] == s95["oov_unexplained_lost"] == []
    assert s95["outright_lost"] == [] and s95["wrong_lost"] == [37278, 42800] and s95["missed_on"] <= s95["missed_off"]
    _, _, differences = probe_results("diagnose_ripple_where_law_falls_round95_lane_*.json")
    for f, d in f95:
        assert differences(d) == [], f.name
