"""benchmarks/bench_time_shift_null_rate.py: fresh closed-loop logs at 50 Hz with a quantized torque, for the
false-alarm rate of the time-shift test's ADC-guard rules."""
import json

import pytest

from conftest import bench_module


@pytest.fixture(scope="module")
def mod():
    return bench_module("bench_time_shift_null_rate")


def test_specs_are_seeded_outside_the_benchmark_and_drawn_like_it(mod):
    bench = bench_module("bench_diagnose_testbench")
    seeds = {s["seed"] for s in bench.loop_cases(200)}
    a, b = mod.spec("null", 7), mod.spec("null", 7)
    assert a == b and a["effects"] == {} and a["sample_rate"] == 50.0 and a["noise"] == "quantized"
    assert 0.03 <= a["noise_std"] <= 0.15 and a["duration"] in (120.0, 300.0)
    o = [mod.spec("oov", i) for i in range(3)]
    assert [next(iter(s["effects"])) for s in o] == bench.LOOP_OOV
    assert not ({a["seed"]} | {s["seed"] for s in o}) & seeds and min(s["seed"] for s in o) >= 2_000_000
    with pytest.raises(SystemExit, match="--kind must be null or oov"):
        mod.spec("vocab", 0)


def _reading(p=1e-60, share=0.05, guarded=True, delay=0.03):
    return {"variable": mod_TS, "p_value": p, "share": share, "adc_guarded": guarded, "n_tests": 7,
            "torque_delay_s": delay, "largest_shift_s": 0.1}


mod_TS = "time_shift_torque_vs_position"


def test_could_fire_only_where_the_guard_holds_back_a_significant_reading(mod):
    r76, r77 = mod.RULES
    assert mod.could_fire(_reading(), r76) and mod.could_fire(_reading(), r77)
    assert mod.could_fire(_reading(delay=-0.25), r76) and not mod.could_fire(_reading(delay=-0.25), r77)
    assert not mod.could_fire(_reading(guarded=False), r76)            # reported already, or not held back
    assert not mod.could_fire(_reading(p=0.5), r76)
    assert not mod.could_fire(_reading(share=1e-4), r76)
    assert not mod.could_fire(None, r76)


def test_summary_counts_and_leaves_out_what_it_says(mod):
    off = {"findings": [], "unexplained": []}
    ts = {"findings": [], "unexplained": [mod_TS]}
    r76, r77 = mod.RULES
    rows = [{"i": 0, "kind": "null", "visible": [], "off": off, r76: ts, r77: off},
            {"i": 1, "kind": "null", "visible": [], "off": off, r76: off, r77: off},
            {"i": 2, "kind": "null", "refused": "too few samples"},
            {"i": 0, "kind": "oov", "visible": ["backlash"], "off": off, r76: ts, r77: ts},
            {"i": 1, "kind": "oov", "visible": [], "off": off, r76: off, r77: off}]
    s = mod.summary(rows)
    assert s["null"]["logs"] == 2 and s["null"]["refused"] == [2]
    assert s["null"][r76]["with_entry_or_finding"] == [0] and s["null"][r77]["with_entry_or_finding"] == []
    assert s["null"][r77]["upper_95"] == pytest.approx(1 - 0.05 ** 0.5)
    assert s["oov"]["logs"] == 1 and s["oov"]["not_visible"] == [1]
    assert s["oov"]["off"]["unexplained"] == [] and s["oov"][r77]["unexplained"] == [0]


def test_a_fresh_log_is_diagnosed_under_each_rule(mod, tmp_path):
    out = tmp_path / "o.json"
    rows = mod.run("oov", 2, 1, None, str(out))          # a sensor delay, 50 Hz, quantized torque
    assert json.loads(out.read_text()) == rows and len(rows) == 1
    r = rows[0]
    assert r["effect"] == "sensor_delay" and r["reading"]["variable"] == mod_TS
    assert set(r) >= {"off", *mod.RULES}
    for rule in mod.RULES:                               # where it cannot fire, the rule's verdict is the off one
        if not mod.could_fire(r["reading"], rule):
            assert r[rule] == r["off"]


def test_cli_errors_are_one_line(mod, tmp_path):
    with pytest.raises(SystemExit, match="--kind must be null or oov"):
        mod.main(["--kind", "vocab", "--n", "1"])
    with pytest.raises(SystemExit, match="cannot read"):
        mod.main(["--summary", str(tmp_path / "missing.json")])


def test_other_rates_and_noises_are_options_with_one_line_errors(mod):
    s = mod.spec("oov", 4, 100.0, "gaussian")
    assert (s["sample_rate"], s["noise"]) == (100.0, "gaussian")
    assert {k: v for k, v in s.items() if k not in ("sample_rate", "noise")} == \
        {k: v for k, v in mod.spec("oov", 4).items() if k not in ("sample_rate", "noise")}
    with pytest.raises(SystemExit, match="--noise must be one of"):
        mod.main(["--kind", "oov", "--noise", "pink", "--n", "1"])
    with pytest.raises(SystemExit, match="--rate must be a positive"):
        mod.main(["--kind", "oov", "--rate", "0", "--n", "1"])
