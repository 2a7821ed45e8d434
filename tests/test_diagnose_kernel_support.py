"""The eighty-third round: the position laws choose their number of Gaussian kernels only among the sizes whose every
kernel holds one training sample's worth of weight (``detectors.KERNEL_SUPPORT_RULE``;
``benchmarks/results/diagnose_kernel_support_round83_rule.txt``)."""
import os
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from drake_est.diagnose import detectors as det

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "benchmarks"))


def _positions_with_hole(n=2000, hole=(0.40, 0.70), seed=0):
    rng = np.random.default_rng(seed)
    q = rng.uniform(-1.0, 1.0, n)
    return q[(q < hole[0]) | (q > hole[1])]


def test_kernel_support_is_each_kernels_summed_weight():
    q = np.array([0.0, 0.0, 1.0])
    s = det.kernel_support(q, 2, 0.0, 1.0)          # kernels at 0 and 1, width 1
    w = np.exp(-0.5)
    assert s == pytest.approx([2.0 + w, 2 * w + 1.0])


def test_a_hole_in_the_training_positions_drops_the_fine_sizes_only():
    q = _positions_with_hole()
    lo, hi = np.quantile(q, [0.002, 0.998])
    sup = {K: det.kernel_support(q, K, lo, hi).min() for K in det.BFE_SIZES}
    assert sup[64] < det.MIN_KERNEL_SUPPORT <= sup[16]
    got = det.supported_sizes(q, lo, hi)
    assert got[0] == det.BFE_SIZES[0] and 64 not in got and 16 in got
    assert det.supported_sizes(np.random.default_rng(1).uniform(-1, 1, 4000), lo, hi) == list(det.BFE_SIZES)
    # the smallest size is always tried, even where nothing supports it
    assert det.supported_sizes(np.zeros(5), -1.0, 1.0) == [det.BFE_SIZES[0]]


def test_the_detector_skips_unsupported_sizes_only_with_the_rule_on(monkeypatch):
    q = _positions_with_hole()
    n = q.size
    jd = SimpleNamespace(q=q, v=np.ones(n), rows=np.arange(n), train=np.ones(n, bool), joint=1,
                         cached_columns=lambda key, make: make())
    tried = []

    def fit_inner(C):
        tried.append(C.shape[1] - 2)                 # a load's columns: sin q, cos q, then the kernels
        return -float(C.shape[1])                    # the finest size would win
    monkeypatch.setattr(det, "KERNEL_SUPPORT_RULE", False)
    e = det.position_load(jd, None, fit_inner)
    assert tried == list(det.BFE_SIZES) and e.evidence["n_kernels"] == 64
    tried.clear()
    monkeypatch.setattr(det, "KERNEL_SUPPORT_RULE", True)
    e = det.position_load(jd, None, fit_inner)
    assert 64 not in tried and e.evidence["n_kernels"] == max(tried)


def test_spec_29730_names_the_load_and_stribeck_with_the_rule_on(monkeypatch):
    """The design log: with the rule off the load candidate takes 64 kernels, one over a hole in the training
    positions, and the search names an asymmetric level; with it on, both planted effects are named."""
    from conftest import closed_loop_case
    from drake_est.diagnose import diagnose
    _, _, log, truth = closed_loop_case(29730)
    monkeypatch.setattr(det, "KERNEL_SUPPORT_RULE", False)
    assert diagnose(log, robot="generic", seed=0, simulate=False).effects == ["asymmetric_coulomb"]
    monkeypatch.setattr(det, "KERNEL_SUPPORT_RULE", True)
    on = diagnose(log, robot="generic", seed=0, simulate=False)
    assert sorted(on.effects) == sorted(truth["planted"]) == ["position_dependent_load", "stribeck"]


def test_kept_and_its_table_is_its_jsons():
    """Kept: the switch is on; the docs' table holds each probe JSON's row as --against-off-rows prints it; every log
    the screens list was examined; no row gained a wrong name, lost `unexplained` or a finding on a null log, and the
    missed effects did not rise; 29730 lost its wrong name and its rule-on row is now its kept row (folded); the rows
    that differ from their kept rows otherwise differ with the rule off as well (not the rule's doing)."""
    import json
    from pathlib import Path
    from conftest import bench_module, probe_lanes, probe_results
    assert det.KERNEL_SUPPORT_RULE is True
    probe = bench_module("probe_kernel_support")
    doc, files, examined, s = probe_lanes(probe, "diagnose_kernel_support_round83_lane_*.json", lanes="abcd")
    res = Path(__file__).resolve().parents[1] / "benchmarks" / "results"
    screens = sorted(res.glob("diagnose_kernel_support_round83_screen_*.json"))
    assert [f.name[-14:] for f in screens] == ["_screen_b.json", "_screen_c.json", "_screen_d.json"]
    for f, (_, d) in zip(screens, files[1:]):
        assert set(d["keys_examined"]) == set(probe.screened_keys([str(f)])), f.name
    assert examined["loop"] >= {29730} and not examined["testbench"]
    assert s["wrong_gained"] == s["null_findings_gained"] == s["oov_unexplained_lost"] == s["outright_lost"] == []
    assert s["wrong_lost"] == [29730] and s["missed_on"] <= s["missed_off"]
    _, _, differences = probe_results("diagnose_kernel_support_round83_lane_*.json")
    for f, d in files:
        on = {x["k"] for x in differences(d)}
        assert on <= {x["k"] for x in differences({"rows": d["rows_off"]})}, f.name
    screened = sum(json.loads(f.read_text())["logs"] for f in screens)
    assert f"{screened:,} kept logs screened" in " ".join(doc.split())
