"""EMPS real-data case study (../shared/data/emps): loader units, nominal parameters against the
published benchmark values, and the held-out gain of position-dependent friction between recordings."""
import json
import subprocess
import sys

import numpy as np
import pytest

from drake_est.datasets.paths import default_data_dir
from drake_est.errors import DataError

needs_data = pytest.mark.requires_data("emps/DATA_EMPS.mat")  # skip locally, fail under CI=true


def test_missing_folder_is_a_data_error(tmp_path):
    from drake_est.datasets.emps import load_emps
    with pytest.raises(DataError, match="not found"):
        load_emps("emps", tmp_path / "nowhere")
    (tmp_path / "emps").mkdir()
    with pytest.raises(DataError, match="DATA_EMPS_PULSES.mat"):
        load_emps("pulses", tmp_path)


def test_not_a_mat_file(tmp_path):
    from drake_est.datasets.emps import load_emps
    (tmp_path / "emps").mkdir()
    (tmp_path / "emps" / "DATA_EMPS.mat").write_text("hello")
    with pytest.raises(DataError, match="not a readable MATLAB file"):
        load_emps("emps", tmp_path)


@needs_data
def test_loader_units():
    import scipy.io
    from drake_est.datasets.emps import load_emps, pulse_edges
    log = load_emps("emps")
    raw = scipy.io.loadmat(str(default_data_dir() / "emps" / "DATA_EMPS.mat"))
    assert log.joints == [1] and log.q.shape == (24841, 1)
    assert abs(log.sample_rate - 1000.0) < 1.0
    np.testing.assert_allclose(log.tau[:, 0], raw["gtau"].item() * raw["vir"].ravel())
    assert 0.2 < np.ptp(log.q) < 0.3        # metres, not mm
    assert len(pulse_edges(log)) == 0
    lp = load_emps("pulses")
    assert len(pulse_edges(lp)) == 49
    assert set(np.unique(lp.channels["pulses_N"])) == {0.0, 5.0}


@needs_data
def test_case_study_nominal_and_heldout_gain():
    from drake_est.cases.emps import emps_case_study
    res = emps_case_study(quick=True, run_diagnose=False)
    for d in res["directions"]:
        p = d["nominal_params"]
        assert 85 < p["M"] < 105, p          # published about 95 kg
        assert 180 < p["Fv"] < 230, p        # about 200 N s/m
        assert 17 < p["Fc"] < 24, p          # about 20 N
        assert d["val_rmse_nominal_N"] < 3.0
        # position-dependent friction fitted on one recording lowers the other's RMSE by >= 20 %
        assert d["rmse_reduction"] >= 0.20, d
        assert d["steady_motion"]["rmse_reduction"] > 0.10, d
    ex = res["data"]["DATA_EMPS_PULSES"]["excluded"]
    assert ex["pulse_edges"] == 49 and ex["pulse_transients"] > 0
    assert res["data"]["DATA_EMPS"]["excluded"]["pulse_transients"] == 0
    # the pattern is the same in both recordings
    assert min(res["summary"]["pattern_correlation_between_recordings"].values()) > 0.7


@needs_data
def test_prepare_rejects_bad_cutoff():
    from drake_est.cases.emps import prepare
    from drake_est.datasets.emps import load_emps
    with pytest.raises(DataError, match="cut-off"):
        prepare(load_emps("emps"), fc=900.0)


@needs_data
def test_diagnose_finds_position_effects():
    from drake_est.cases.emps import _diagnose_log, _summarize_diagnosis, prepare
    from drake_est.datasets.emps import load_emps
    log = load_emps("emps")
    d = _summarize_diagnosis(_diagnose_log(log, prepare(log), seed=0))
    effects = [f["effect"] for f in d["findings"]]
    assert "position_dependent_friction" in effects or "motor_position_ripple" in effects, effects
    assert d["final_heldout_rmse_N"] < 0.8 * d["nominal_heldout_rmse_N"]


@pytest.mark.slow   # ~25 s; tutorials/83_real_emps runs the same case study (emps_case_study, quick) by default
@needs_data
def test_cli_reproduce_real_emps(tmp_path):
    out = tmp_path / "o"
    r = subprocess.run([sys.executable, "-m", "drake_est", "reproduce", "real-emps", "--quick", "--out", str(out)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    res = json.loads((out / "real-emps.json").read_text())
    assert res["summary"]["goal_20pct_met"]
    assert (out / "emps_position_friction.png").exists()
    assert "held-out RMSE" in r.stdout


def test_cli_missing_data_exits_2(tmp_path):
    r = subprocess.run([sys.executable, "-m", "drake_est", "reproduce", "real-emps", "--out", str(tmp_path / "o"),
                        "--data", str(tmp_path / "none")], capture_output=True, text=True, timeout=300)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    assert "not found" in (r.stderr + r.stdout)


def test_fast_ridge_cv_matches_reference():
    from drake_est.bfe import cv_error
    from drake_est.cases._ridge import ridge_cv_grid
    rng = np.random.default_rng(0)
    A = rng.normal(size=(400, 25)) * np.r_[100.0, 0.01, np.ones(23)]
    y = A @ rng.normal(size=25) + rng.normal(size=400)
    pen = np.r_[0.0, 0.0, np.ones(23)]
    lams = (0.01, 1.0, 100.0)
    ref = [cv_error(A, y, lam, pen, 5, True) for lam in lams]
    np.testing.assert_allclose(ridge_cv_grid(A, y, pen, lams, folds=5), ref, rtol=1e-6)
