"""The eighty-eighth round: the linear-response check also holds a disturbance periodic in time that is not stationary
over the log (``core.LINEAR_RESPONSE_DISTURBANCE_RULE``;
``benchmarks/results/diagnose_disturbance_stationary_round88_rule.txt``)."""
import pytest

from drake_est.diagnose import core, diagnose


def _capture_final_state(monkeypatch):
    """Record the arguments of every call of the linear-response check (the final model's state)."""
    calls = []
    original = core.finding_explained_by_linear_response

    def wrapped(*a):
        calls.append(a)
        return original(*a)
    monkeypatch.setattr(core, "finding_explained_by_linear_response", wrapped)
    return calls


@pytest.fixture(scope="module")
def design_case():
    from conftest import closed_loop_case
    return closed_loop_case(31260)


def test_spec_31260_ends_unexplained_with_the_rule_on(monkeypatch, design_case):
    """The design log (an elastic gear): off, a disturbance in time at 2.57 Hz (a wrong name); on, it is set aside,
    explained one way by a linear response to the acceleration and wandering over the log, and the log ends
    ``unexplained`` with no name."""
    mod, spec, log, truth = design_case
    monkeypatch.setattr(core, "LINEAR_RESPONSE_DISTURBANCE_RULE", False)
    off = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert [f["effect"] for f in off["findings"]] == ["time_periodic_disturbance"]
    assert mod.judge(spec, off)["wrong"] == ["time_periodic_disturbance"]
    monkeypatch.setattr(core, "LINEAR_RESPONSE_DISTURBANCE_RULE", True)
    on = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert on["findings"] == [] and truth["planted"] == ["compliance"]
    j = mod.judge(spec, on)
    assert j["correct"] and not j["wrong"]
    assert {u["variable"] for u in on["unexplained"]} >= {"acceleration", "time_correlation"}
    aside = [x for x in on["set_aside"] if x.get("explained_by_linear_response")]
    assert [x["effect"] for x in aside] == ["time_periodic_disturbance"]
    x = aside[0]
    assert x["finding_given_linear_response"]["p_value"] > core.ALPHA
    assert x["linear_response_given_finding"]["p_value"] < core.ALPHA
    st = x["disturbance_stationarity"]
    assert st["segments"] == core.DISTURBANCE_SEGMENTS == len(st["amplitudes"])
    assert st["coherence"] < core.DISTURBANCE_COHERENCE_MAX and st["heterogeneity"]["p_value"] < core.ALPHA
    assert max(st["amplitudes"]) > 3 * min(st["amplitudes"])
    assert "not stationary" in x["reason"] and "phasor coherence" in x["reason"]


def test_a_planted_disturbance_is_stationary(monkeypatch):
    """Spec 20747 (a disturbance at 12 Hz, 50 Hz sampling, 300 s), the planted disturbance with the lowest coherence
    among the seventeen the sixty-first round set aside: a free linear response explains it one way too, but its
    phasor over eighths of the log is steady, so it stands and is still named."""
    from conftest import closed_loop_case
    mod, spec, log, truth = closed_loop_case(20747)
    calls = _capture_final_state(monkeypatch)
    monkeypatch.setattr(core, "LINEAR_RESPONSE_DISTURBANCE_RULE", True)
    rep = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert mod.judge(spec, rep)["correct"] and "time_periodic_disturbance" in truth["planted"]
    prep, model, unexplained, alpha, min_gain = calls[-1]
    e = next(x for x in model.exts if x.effect == "time_periodic_disturbance")
    assert core._explained_one_way(prep, model, e, core.linear_response_nuisance(prep, e.joint), alpha,
                                   min_gain) is not None
    st = core.disturbance_stationarity(prep, model, e, alpha, min_gain)
    assert core.DISTURBANCE_COHERENCE_MAX < st["coherence"] <= 1.0 and st["heterogeneity"]["p_value"] > alpha
    assert core.disturbance_not_stationary(prep, model, e, alpha, min_gain) is None


def test_off_the_check_does_not_look_at_disturbances(monkeypatch, design_case):
    """With the switch off the check never asks how stationary a disturbance is (the smooth laws only, as before)."""
    _, _, log, _ = design_case

    def boom(*a, **k):
        raise AssertionError("stationarity computed with the rule off")
    monkeypatch.setattr(core, "LINEAR_RESPONSE_DISTURBANCE_RULE", False)
    monkeypatch.setattr(core, "disturbance_stationarity", boom)
    rep = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert [f["effect"] for f in rep["findings"]] == ["time_periodic_disturbance"]


def test_kept_and_its_table_is_its_jsons():
    """Kept: the switch is on; the docs' table holds each probe JSON's row as --against-off-rows prints it; lanes a and
    b are the 698 closed-loop logs of the screen (alternate keys), lane c the 4 of the fresh blocks 31800-31999, lane d
    the 9 of the fresh blocks 32000-32199, lane e the 2 of the fresh blocks 32200-32399, lane f the 6 of the fresh
    blocks 32400-32599, lane g the 4 of the fresh blocks 32600-32999, lane h the 4 of the fresh blocks 33000-33199, lane i the 5 of
    the fresh blocks 33200-33399, lane j the 4 of 33400-33599, lane k the 12 of
    33600-33999, lane l the 13 of 34000-34399, lane m the 8 of 34400-34799, lane n
    the 3 of 34800-34999, lane o the 10 of 35000-35399, lane p the 7 of
    35400-35599, lane q the 7 of 35600-35999, lane r the 7 of
    36000-36399, lane s the 14 of 36400-36799, lane t
    the 10 of 36800-37199, lane u the 2 of 37200-37399, lane v the 6 of 37400-37599, lane w the 10 of 37600-37999, lane x the 6 of 38000-38199, lane y the 3 of 38200-38399, lane z the 5 of 38400-38599, lane za the 4 of 38600-38799, lane zb the 2 of 38800-38999, lane zc the 2 of 39000-39199, lane zd the 7 of 39200-39399, lane ze the 5 of 39400-39599, lane zf the 4 of 39600-39799, lane zg the 5 of 39800-39999, lane zh the 7 of 40000-40199, lane zi the 5 of 40200-40399, lane zj the 3 of 40400-40599, lane zk the 8 of 40600-40799, lane zl the 2 of 40800-40999, lane zm the 4 of 41000-41199, lane zn the 4 of 41200-41399, lane zo the 5 of 41400-41599, lane zp the 4 of 41600-41799, lane zq the 6 of 41800-41999, lane zr the 6 of 42000-42199, lane zs the 5 of 42200-42399, lane zt the 4 of 42400-42599, lane zu the 3 of 42600-42799, lane zv the 7 of 42800-42999, lane zw the 8 of 43000-43399, lane zx the 20 of 43400-43999, lane zy the 6 of 44000-44199, lane zz the 3 of 44200-44399, lane zza the 1 of 44400-44599, lane zzb the 6 of 44600-44799, lane zzc the 5 of 44800-44999, lane zzd the 4 of 45000-45199, lane zze the 4 of 45200-45399, lane zzf the 1 of 45400-45599, lane zzg the 4 of 45600-45799, lane zzh the 6 of 45800-45999, lane zzi the 5 of 46000-46199, lane zzj the 4 of 46200-46399, lane zzk the 6 of 46400-46599, lane zzl the 2 of 46600-46799, lane zzm the 3 of 46800-46999, lane zzn the 5 of 47000-47199 (all run with the rule on); the
    rule fired in the design log only, which lost its wrong name (its rule-on row is now its kept row), and nothing
    was lost."""
    from conftest import assert_rule_mended_only, bench_module, probe_lanes
    assert core.LINEAR_RESPONSE_DISTURBANCE_RULE is True
    probe = bench_module("probe_disturbance_stationary")
    doc, files, examined, s = probe_lanes(probe, "diagnose_disturbance_stationary_round88_lane_*.json", lanes=[*"abcdefghijklmnopqrstuvwxyz", "za", "zb", "zc", "zd", "ze", "zf", "zg", "zh", "zi", "zj", "zk", "zl", "zm", "zn", "zo", "zp", "zq", "zr", "zs", "zt", "zu", "zv", "zw", "zx", "zy", "zz", "zza", "zzb", "zzc", "zzd", "zze", "zzf", "zzg", "zzh", "zzi", "zzj", "zzk", "zzl", "zzm", "zzn"])
    assert [len(d["keys_examined"]) for _, d in files] == [349, 349, 4, 9, 2, 6, 4, 4, 5, 4, 12, 13, 8, 3, 10,
                                                         7, 7, 7, 14, 10, 2, 6, 10, 6, 3, 5, 4, 2, 2, 7, 5, 4, 5, 7, 5, 3, 8, 2, 4, 4, 5, 4, 6, 6, 5, 4, 3, 7, 8, 20, 6, 3, 1, 6, 5, 4, 4, 1, 4, 6, 5, 4, 6, 2, 3, 5]
    assert len(examined["loop"]) == 1054 and 31260 in examined["loop"] and not examined["testbench"]
    assert set(probe.named_keys("loop")) <= examined["loop"] and probe.named_keys("testbench") == []
    assert_rule_mended_only("diagnose_disturbance_stationary_round88_lane_*.json", files, s, 31260)
    assert "It fired in one log of 1,054" in " ".join(doc.split())
