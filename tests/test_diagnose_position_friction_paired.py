"""The eighty-second round: a position friction on a joint whose final residual holds structure must beat the model
without it on the paired held-out blocks at p < 0.01 (``core.POSITION_FRICTION_STRICT_PAIRED``;
``benchmarks/results/diagnose_position_friction_paired_round82_rule.txt``)."""
import os
import sys
from types import SimpleNamespace

import pytest

from drake_est.diagnose import core

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "benchmarks"))


def _step(effect, joint, p, shared=False):
    return SimpleNamespace(ext=SimpleNamespace(effect=effect, joint=joint, shared=shared),
                           test={"paired_p_value": p})


def test_the_check_reads_the_steps_paired_level_on_joints_with_structure(monkeypatch):
    steps = [_step("position_dependent_friction", 1, 0.03), _step("stribeck", 1, 0.04),
             _step("position_dependent_friction", 2, 1e-5)]
    unexplained = [{"variable": "time_correlation", "joint": 1}]
    assert core.position_friction_weak_on_blocks(None, steps, unexplained) is None      # switched off
    monkeypatch.setattr(core, "POSITION_FRICTION_STRICT_PAIRED", True)
    st, why = core.position_friction_weak_on_blocks(None, steps, unexplained)
    assert st is steps[0] and why["paired_p_value"] == 0.03 and why["weak_on_blocks"]
    assert core.position_friction_weak_on_blocks(None, steps, []) is None                # a white residual
    steps[0].test["paired_p_value"] = 0.009
    assert core.position_friction_weak_on_blocks(None, steps, unexplained) is None
    steps[0].test.pop("paired_p_value")
    assert core.position_friction_weak_on_blocks(None, steps, unexplained) is None


@pytest.mark.parametrize("noise", ["gaussian", "student_t"])
def test_fresh_oov_94_is_set_aside_with_the_rule_on(noise, monkeypatch):
    import bench_diagnose_testbench as B
    import bench_time_shift_null_rate as T
    from drake_est.diagnose import diagnose
    log, _ = B.loop_log(T.spec("oov", 94, 50.0, noise))
    off = diagnose(log, robot="generic", seed=0, simulate=False)
    assert off.effects == ["position_dependent_friction"]
    p = off.result.steps[0].test["paired_p_value"]
    assert core.PAIRED_ALPHA > p >= core.STRICT_PAIRED_ALPHA
    monkeypatch.setattr(core, "POSITION_FRICTION_STRICT_PAIRED", True)
    on = diagnose(log, robot="generic", seed=0, simulate=False)
    assert on.effects == [] and on.result.unexplained
    aside = [r for r in on.result.prep.meta["set_aside"] if r.get("weak_on_blocks")]
    assert [(r["effect"], r["joint"]) for r in aside] == [("position_dependent_friction", 1)]


def test_not_kept_and_its_table_is_its_jsons():
    """Not kept (condition 3): the switch is off; the docs' probe table is the JSONs', every kept row the rule can
    change (blocks up to 29699) was examined, and the missed effects rise."""
    import json
    from pathlib import Path
    from conftest import bench_module, probe_lanes
    assert core.POSITION_FRICTION_STRICT_PAIRED is False
    probe = bench_module("probe_position_friction_paired")
    doc, files, examined, s = probe_lanes(probe, "diagnose_position_friction_paired_round82_lane_*.json")
    # rows the ninetieth round refolded (14443) and the ninety-sixth (REFOLDED_ROUND_96) may have left the screen since
    from conftest import REFOLDED_ROUND_96
    refolded = {14443} | REFOLDED_ROUND_96
    assert examined["loop"] - refolded == {k for k in probe.touchable_keys("loop") if k < 29700} - refolded
    assert len(examined["loop"]) == 499
    assert examined["testbench"] == set(probe.touchable_keys("testbench"))
    assert s["fired"] == 6 and s["wrong_gained"] == [] and s["oov_unexplained_lost"] == []
    assert s["null_findings_gained"] == [] and (s["missed_off"], s["missed_on"]) == (3, 8)
    fired = sorted(t["k"] for _, d in files for t in d["touched"])
    assert fired == [4035, 10239, 14443, 20691, 25506, 28061]
    ps = [x["paired_p_value"] for _, d in files for t in d["touched"] for x in t["set_aside"]]
    assert min(ps) >= core.STRICT_PAIRED_ALPHA and max(ps) < core.PAIRED_ALPHA
    res = Path(__file__).resolve().parents[1] / "benchmarks" / "results"
    synth = json.loads((res / "diagnose_position_friction_paired_round82_synth_1.json").read_text())
    assert synth["on"]["got"] == synth["off"]["got"] == synth["kept"]["got"] == "position_dependent_friction"
