"""Benchmark of the LPV spectral estimator (run with: .venv/bin/pytest -m benchmark tests/test_spectral_bench.py -s)."""
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))


@pytest.mark.benchmark
def test_lpv_benchmark_n50000():
    from bench_spectral import run

    res = run(repeats=1)
    print(res)
    d = res["direct_N50000_p2000"]
    assert d["solver"] == "direct" and d["params"] == 2000
    assert d["seconds"] < 10.0                      # acceptance: < 10 s on 2 cores
    assert res["auto_N50000_p4000"]["solver"] == "iterative"
    assert res["auto_N50000_p4000"]["converged"]
    assert res["find_periodic_components_N45000"]["rel_error"] < 0.01
