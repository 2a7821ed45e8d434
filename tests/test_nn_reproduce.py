"""Reproductions nn-linear / nn-cartpole (thesis Sec. 8.6) at tiny sizes, the benchmark, and a Jacprop
speed check that is a ratio (not a timed assertion) kept behind the benchmark marker."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from drake_est.jsonutil import dump_json
from drake_est.reproduce import experiments
from drake_est.reproduce.nn import nn_cartpole, nn_linear

ROOT = Path(__file__).resolve().parents[1]


def test_registered():
    exps = experiments()
    assert exps["nn-linear"] is nn_linear and exps["nn-cartpole"] is nn_cartpole


@pytest.mark.slow
@pytest.mark.parametrize("func", [nn_linear, nn_cartpole])
def test_reproduction_figures(func, tmp_path, monkeypatch):
    monkeypatch.setenv("DRAKE_EST_NO_PROGRESS", "1")
    res = func(tmp_path, quick=True, seed=1, n_runs=2, n_tune=1, epochs=3, workers=1,
               grid={"weight_decay": (1e-3,), "jacprop": (0.1,)})
    assert len(res["figures"]) == 3
    for f in res["figures"]:
        assert (tmp_path / f).stat().st_size > 5000


@pytest.mark.parametrize("func", [nn_linear, nn_cartpole])
def test_reproduction_runs_small(func, tmp_path, monkeypatch):
    monkeypatch.setenv("DRAKE_EST_NO_PROGRESS", "1")
    res = func(tmp_path, quick=True, seed=1, n_runs=2, n_tune=1, epochs=3, workers=1, figures=False,
               grid={"weight_decay": (1e-3, 1e-1), "jacprop": (0.1,)})
    assert res["figures"] == []
    dump_json(res, tmp_path / "r.json")                      # JSON-able, no NaN/Inf
    back = json.loads((tmp_path / "r.json").read_text())
    assert set(back["results"]) == {f"{f}/{m}" for f in "fg" for m in ("none", "weight_decay", "jacprop")}
    for key, r in back["results"].items():
        assert r["val_mse"]["n"] == 2 and r["val_mse"]["min"] <= r["val_mse"]["median"] <= r["val_mse"]["max"]
        assert len(r["jac_err_runs"]) == 2 and all(np.isfinite(r["jac_err_runs"]))
    for key, v in back["chosen"].items():                     # chosen value is the tuning minimum
        t = back["tuning_median_val_mse"][key]
        assert t[f"{v:g}"] == min(t.values())
    assert isinstance(back["checks"]["jacprop_lowers_median_jac_err_g"], bool)


def test_reproduction_parallel_equals_serial(tmp_path, monkeypatch):
    """Monte-Carlo draws are seeded per run: a process pool gives the same numbers as one process."""
    monkeypatch.setenv("DRAKE_EST_NO_PROGRESS", "1")
    kw = dict(quick=True, seed=2, n_runs=2, n_tune=1, epochs=2, grid={"weight_decay": (1e-3,), "jacprop": (0.1,)})
    a = nn_linear(tmp_path / "a", workers=1, figures=False, **kw)
    b = nn_linear(tmp_path / "b", workers=2, figures=False, **kw)
    for k in a["results"]:
        np.testing.assert_allclose(a["results"][k]["jac_err_runs"], b["results"][k]["jac_err_runs"], rtol=1e-10)


@pytest.mark.benchmark
def test_bench_nn_writes_json(tmp_path):
    out = tmp_path / "b.json"
    subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_nn.py"), "--repeat", "1", "--epochs", "2",
                    "--json", str(out)], check=True, capture_output=True)
    res = json.loads(out.read_text())
    assert res["epoch_ms_jacprop"] > 0 and res["epoch_ms_plain"] > 0
    assert res["n_samples"] == 398
