"""benchmarks/bench_acceleration_smooth_fresh.py: the eightieth round's rule on fresh closed-loop logs."""
import json

import pytest

from conftest import bench_module


@pytest.fixture(scope="module")
def mod():
    return bench_module("bench_acceleration_smooth_fresh")


def test_summary_counts_and_leaves_out_what_it_says(mod):
    none = {"findings": [], "unexplained": []}
    acc = {"findings": [], "unexplained": ["acceleration"]}
    named = {"findings": ["stribeck"], "unexplained": []}
    rows = [{"i": 0, "kind": "null", "visible": [], "on": none, "off": acc, "held_back": [[0.2, 0.004]]},
            {"i": 1, "kind": "null", "visible": [], "on": none, "off": none, "held_back": []},
            {"i": 2, "kind": "null", "refused": "too few samples"},
            {"i": 0, "kind": "oov", "visible": ["backlash"], "on": none, "off": acc, "held_back": [None]},
            {"i": 1, "kind": "oov", "visible": ["compliance"], "on": named, "off": acc, "held_back": [[1e-9, 0.01]]},
            {"i": 2, "kind": "oov", "visible": [], "on": none, "off": none, "held_back": []}]
    s = mod.summary(rows)
    n, o = s["null"], s["oov"]
    assert n["logs"] == 2 and n["refused"] == [2] and n["fired"] == [0]
    assert n["off"]["with_entry_or_finding"] == [0] and n["on"]["with_entry_or_finding"] == []
    assert n["on"]["upper_95"] == pytest.approx(1 - 0.05 ** 0.5)
    assert o["logs"] == 2 and o["not_visible"] == [2]
    assert o["lost_unexplained"] == [0, 1] and o["name_gained"] == [1]
    assert o["off"]["unexplained"] == [0, 1] and o["on"]["named_something"] == [1]


def test_a_fresh_log_is_diagnosed_with_the_rule_and_off_only_where_it_fired(mod, tmp_path):
    out = tmp_path / "o.json"
    rows = mod.run("null", 41, 1, None, str(out), 50.0, "gaussian")      # a design case: the rule fires
    assert json.loads(out.read_text()) == rows and len(rows) == 1
    r = rows[0]
    assert r["held_back"] and r["off"]["unexplained"] == ["acceleration"] and r["on"] == {"findings": [],
                                                                                          "unexplained": []}
    rows = mod.run("null", 0, 1, None, None, 50.0, "gaussian")
    assert rows[0]["held_back"] or rows[0]["on"] == rows[0]["off"]


def test_cli_errors_are_one_line(mod, tmp_path):
    with pytest.raises(SystemExit, match="--kind must be null or oov"):
        mod.main(["--kind", "vocab", "--n", "1"])
    with pytest.raises(SystemExit, match="cannot read"):
        mod.main(["--summary", str(tmp_path / "missing.json")])
