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
    assert det.KERNEL_SUPPORT_RULE is False
    e = det.position_load(jd, None, fit_inner)
    assert tried == list(det.BFE_SIZES) and e.evidence["n_kernels"] == 64
    tried.clear()
    monkeypatch.setattr(det, "KERNEL_SUPPORT_RULE", True)
    e = det.position_load(jd, None, fit_inner)
    assert 64 not in tried and e.evidence["n_kernels"] == max(tried)
