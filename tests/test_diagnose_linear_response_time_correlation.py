"""The seventy-eighth round: the linear-response check (an elastic gear's resonance) also holds the laws of a joint
whose final residual is correlated in time (core.LINEAR_RESPONSE_ON_TIME_CORRELATION)."""
import pytest

from drake_est.diagnose import core, diagnose

from conftest import bench_module


@pytest.fixture(scope="module")
def compliance_160():
    """Fresh closed-loop log i = 160 of bench_time_shift_null_rate.py --kind oov: an elastic gear, 50 Hz, quantized."""
    nr = bench_module("bench_time_shift_null_rate")
    spec = nr.spec("oov", 160)
    log, truth = nr.B.loop_log(spec)
    assert spec["effects"] == {"compliance": 1.0} and truth["effects"] == ["compliance"]
    return nr.B, spec, log


def test_an_elastic_gear_named_a_position_load_is_set_aside_with_the_rule(monkeypatch, compliance_160):
    B, spec, log = compliance_160
    monkeypatch.setattr(core, "LINEAR_RESPONSE_ON_TIME_CORRELATION", False)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert B.judge(spec, d)["wrong"] == ["position_dependent_load"]
    # the final residual is correlated in time and shows no dependence on the acceleration: the check did not run
    assert "time_correlation" in [u["variable"] for u in d["unexplained"]]
    assert "acceleration" not in [u["variable"] for u in d["unexplained"]]
    monkeypatch.setattr(core, "LINEAR_RESPONSE_ON_TIME_CORRELATION", True)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert B.judge(spec, d) == {"wrong": [], "missed": [], "oov_unexplained": True, "correct": True}
    (s,) = d["set_aside"]
    assert s["effect"] == "position_dependent_load" and s["explained_by_linear_response"]
    assert s["finding_given_linear_response"]["p_value"] > 0.01
    assert s["linear_response_given_finding"]["rmse_reduction"] > 0.3


def test_the_trigger_set_follows_the_switch(monkeypatch):
    # a joint with only a time_correlation entry is held by the check only with the switch on
    seen = []
    monkeypatch.setattr(core, "_latest_explained_one_way", lambda prep, model, laws, *a: seen.append(laws) or None)

    class E:
        shared, joint, effect = False, 1, "position_dependent_load"

    class M:
        exts = [E()]

    for on in (False, True):
        monkeypatch.setattr(core, "LINEAR_RESPONSE_ON_TIME_CORRELATION", on)
        assert core.finding_explained_by_linear_response(None, M(), [{"joint": 1, "variable": "time_correlation"}],
                                                         1e-4, 0.02) is None
    assert [len(x) for x in seen] == [0, 1]


def test_the_rule_is_on_and_its_table_is_its_jsons():
    """Kept: over the 446 kept rows it can touch it fired in none; the docs' table is the JSONs'."""
    from conftest import probe_results
    assert core.LINEAR_RESPONSE_ON_TIME_CORRELATION is True
    probe = bench_module("probe_linear_response_time_correlation")
    doc, files, differences = probe_results("diagnose_linear_response_time_correlation_round78_lane_*.json")
    assert [f.name[-12:] for f, _ in files] == ["_lane_a.json", "_lane_b.json"]
    examined = set()
    for f, d in files:
        s = probe.against_off([str(f)])
        assert probe.against_off_row(f.name, s) in doc
        assert d["touched"] == [] and d["rows"] == [] and d["refused"] == []
        examined |= set(d["keys_examined"])
    # the selection: every touchable kept row that ran before the rule (fresh blocks from 29100 on ran with it)
    assert examined == {k for k in probe.touchable_keys("loop") if k < 29100} and len(examined) == 446
    assert "**fired in none of the 446 kept rows**" in " ".join(doc.split())


def test_fresh_logs_at_other_rates_name_no_cause():
    """The docs' counts of the 240 fresh out-of-vocabulary logs at 10, 100 and 250 Hz are their JSONs'."""
    import json
    from pathlib import Path
    res = Path(__file__).resolve().parents[1] / "benchmarks" / "results"
    got = {}
    for tag in ("10_q", "100_g", "100_q", "250_t"):
        rows = json.loads((res / f"time_shift_guard_fresh_oov_rate_{tag}.json").read_text())
        assert len(rows) == 60 and not [r for r in rows if "refused" in r or r["off"]["findings"]]
        vis = [r for r in rows if r["visible"]]
        got[tag] = (sum(bool(r["off"]["unexplained"]) for r in vis), len(vis))
    assert got == {"10_q": (0, 46), "100_g": (45, 49), "100_q": (46, 51), "250_t": (46, 49)}
    doc = " ".join((res.parents[1] / "docs" / "readme" / "diagnose_testbench.md").read_text().split())
    assert "**None of the 240 is named a cause.**" in doc and "0 of 46 at 10 Hz" in doc
    assert "45 of 49, 46 of 51 and 46 of 49" in doc
