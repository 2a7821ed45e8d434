"""The loop the diagnosis rules' probes share (benchmarks/probe_runner.py)."""
import json

import pytest

from drake_est.diagnose import core

from conftest import bench_module


def test_a_probe_records_each_firing_stores_the_rows_beside_the_kept_ones_and_restores_the_core(tmp_path):
    runner = bench_module("probe_runner")
    was, original = core.HELD_BACK_RIVALS, core._evaluate
    calls = []

    def record(got, a, kw):
        # every candidate of every round "fires", and the rule's switch is seen as the probe set it
        calls.append(core.HELD_BACK_RIVALS)
        return {"effect": got[0].effect}

    out = tmp_path / "probe.json"
    # open-loop testbench spec 24 (a position friction at 10 Hz): a diagnosis of well under a second
    res = runner.run_rule_probe(str(out), [24], "testbench", rule="HELD_BACK_RIVALS", func="_evaluate",
                                record=record, hits_key="fired", compare_off=True)
    assert core.HELD_BACK_RIVALS is was and core._evaluate is original
    assert res["examined"] == 1 and res["keys_examined"] == [24]
    assert [t["k"] for t in res["touched"]] == [24] and res["touched"][0]["fired"]
    assert True in calls and False in calls          # the rule on, then off for the same log again
    assert res["refused"] == res["refused_off"] == []
    (row,), (off,) = res["rows"], res["rows_off"]
    assert row["k"] == off["k"] == 24 and row["kept_row"]["k"] == 24 and row["kept_json"]
    assert json.loads(out.read_text())["examined"] == 1


def test_a_probe_refuses_a_key_without_a_kept_row_and_an_unknown_family():
    runner = bench_module("probe_runner")
    with pytest.raises(SystemExit, match="no kept testbench row for k = 99999"):
        runner.kept_rows("testbench", [99999])
    with pytest.raises(SystemExit, match="--family must be loop or testbench"):
        runner.kept_rows("synth", [1])


def test_a_probe_switches_a_rule_of_another_module_and_restores_it(tmp_path):
    # the seventy-sixth round's rule lives in drake_est.diagnose.unexplained, not in core
    import drake_est.diagnose.unexplained as U
    runner = bench_module("probe_runner")
    was, original = U.TIME_SHIFT_NO_ADC_GUARD, U.residual_structure
    seen = []

    def record(got, a, kw):
        seen.append(U.TIME_SHIFT_NO_ADC_GUARD)
        return None                                  # never fires: no rule-off run

    res = runner.run_rule_probe(str(tmp_path / "p.json"), [24], "testbench", rule="TIME_SHIFT_NO_ADC_GUARD",
                                func="residual_structure", record=record, hits_key="entries", compare_off=True,
                                module="unexplained")
    assert U.TIME_SHIFT_NO_ADC_GUARD is was and U.residual_structure is original
    assert seen and set(seen) == {True}
    assert res["touched"] == [] and res["rows"] == [] and res["rows_off"] == []
