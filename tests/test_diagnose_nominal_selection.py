"""The velocity jitter behind the data selection's speed bound (9.9): nominal.velocity_jitter."""
from __future__ import annotations

import numpy as np
import pytest

from drake_est.diagnose import nominal


def test_velocity_jitter_of_white_noise_is_its_level_for_both_orders():
    rng = np.random.default_rng(0)
    v = 0.02 * rng.standard_normal(20000)
    assert nominal.velocity_jitter(v, 1) == pytest.approx(0.02, rel=0.05)
    assert nominal.velocity_jitter(v, 2) == pytest.approx(0.02, rel=0.05)


def test_second_differences_do_not_see_a_smooth_motion_sampled_at_10hz():
    """A multisine velocity sampled at 10 Hz without noise: its first differences are the motion (the speed bound
    then sits near half the top speed, as in the Stribeck misses at 10 Hz); its second differences are far smaller."""
    t = np.arange(0.0, 120.0, 0.1)
    v = 0.5 * np.sin(2 * np.pi * 0.2 * t) + 0.3 * np.sin(2 * np.pi * 0.45 * t + 1.0)
    j1, j2 = nominal.velocity_jitter(v, 1), nominal.velocity_jitter(v, 2)
    assert 10 * j1 > 0.2 * np.quantile(np.abs(v), 0.95)
    assert j2 < 0.25 * j1


def test_selection_uses_the_configured_order_and_default_is_first_differences(monkeypatch):
    t = np.arange(0.0, 120.0, 0.1)
    v = 0.5 * np.sin(2 * np.pi * 0.2 * t) + 0.3 * np.sin(2 * np.pi * 0.45 * t + 1.0)
    a = np.gradient(v, t)
    vref = float(np.quantile(np.abs(v), 0.95))
    assert nominal.V_JITTER_DIFFERENCE_ORDER == 1
    _, _, thr1 = nominal.select_rows(v, a, t)
    assert thr1["v_min"] == pytest.approx(10 * nominal.velocity_jitter(v, 1))
    monkeypatch.setattr(nominal, "V_JITTER_DIFFERENCE_ORDER", 2)
    _, _, thr2 = nominal.select_rows(v, a, t)
    assert thr2["v_min"] == pytest.approx(max(nominal.V_MIN_FRACTION * vref, 10 * nominal.velocity_jitter(v, 2)))
    assert thr2["v_min"] < 0.5 * thr1["v_min"]


def test_velocity_jitter_refuses_other_orders():
    with pytest.raises(ValueError, match="order must be 1 or 2"):
        nominal.velocity_jitter(np.zeros(10), 3)


def _probe():
    from conftest import bench_module
    return bench_module("probe_jitter_second_differences")


def test_probe_classifies_a_row_against_its_kept_row():
    probe = _probe()
    kept = {"got": "none", "correct": False, "wrong": [], "missed": ["stribeck"], "truth": "stribeck"}
    row = {"got": "stribeck", "correct": True, "wrong": [], "truth": "stribeck", "kept_row": kept}
    assert probe.classify(row) == "mended"
    row = dict(row, got="stribeck+position_dependent_load", correct=False, wrong=["position_dependent_load"])
    assert probe.classify(row) == "wrong name"
    null_kept = {"got": "none", "correct": True, "wrong": [], "missed": [], "truth": "none"}
    assert probe.classify({"got": "unexplained", "correct": True, "wrong": [], "truth": "none",
                           "kept_row": null_kept}) == "null log, entry gained"


def test_sixty_seventh_round_table_is_its_jsons():
    """docs/readme/diagnose_testbench.md's table of the sixty-seventh round holds each JSON's row as the probe's
    --table-row prints it, and the text names the specs that gained a wrong name."""
    from pathlib import Path

    from conftest import probe_results
    probe = _probe()
    root = Path(__file__).resolve().parents[1]
    doc, files, _ = probe_results("diagnose_jitter_second_differences_round67_*.json")
    flat = " ".join(doc.split())
    assert len(files) == 5
    wrong, summaries = [], {}
    for f, d in files:
        assert d["jitter_difference_order"] == 2
        s = summaries[f.name] = probe.summary([str(f)])
        assert probe.table_row(f.name, s) in doc
        wrong += [x["k"] for x in s["cases"].get("wrong name", [])]
    assert sorted(wrong) == [596, 670, 8461, 17589]
    assert "670, 8461 and 17589 at 10 Hz and 596 at 50 Hz gain a wrong name" in " ".join(
        (root / "docs" / "readme" / "_roadmap.md").read_text().split())
    s = summaries["diagnose_jitter_second_differences_round67_missed_stribeck_10hz.json"]
    assert f"of the {s['touched']} missed-Stribeck logs whose bound moves, {s['mended_missed_stribeck']} now" in flat
    assert s["examined"] == 211 and "211 kept closed-loop rows at 10 Hz miss" in flat
