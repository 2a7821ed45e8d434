"""The snap test of the "unexplained" verdict (eleventh round): on the accelerating samples that the selection
(9.9) leaves out, the residual must not follow the snap d^4q/dt^4 by more than the Savitzky-Golay filter's own
error kappa x snap.  An elastic gear read by a motor-side encoder leaves about -(J_load^2 / k) snap there, which
the free snap nuisance of the jerk test had absorbed (loop spec 988: an elastic gear that ended as "none")."""
from __future__ import annotations

import numpy as np
import scipy.signal

from drake_est.diagnose import diagnose
from drake_est.diagnose.unexplained import filter_snap_gain

from conftest import bench_module


def test_filter_snap_gain_is_the_savgol_error_on_a_quartic():
    """qdd_hat - qdd = kappa * snap exactly for a quartic (the filter is exact up to its polynomial order), and kappa
    tends to L^2 / 14 for a window of half-width L."""
    for w, po, h in ((7, 3, 0.02), (25, 3, 0.004), (101, 3, 0.001), (11, 2, 0.01)):
        t = np.arange(400) * h
        snap = 3.7
        q = 0.2 * t ** 2 + snap * (t - 1.0) ** 4 / 24.0
        a_hat = scipy.signal.savgol_filter(q, w, po, deriv=2, delta=h)
        a_true = 0.4 + snap * (t - 1.0) ** 2 / 2.0
        k = filter_snap_gain(w, po, h)
        mid = slice(w, t.size - w)
        assert np.allclose(a_hat[mid] - a_true[mid], k * snap, rtol=1e-6, atol=1e-9), (w, po)
    L = 500 * 1e-4
    assert abs(filter_snap_gain(1001, 3, 1e-4) / (L ** 2 / 14) - 1) < 0.005


def _loop_spec(k, effects=None):
    loop_log = bench_module("bench_diagnose_testbench").loop_log
    log, truth = loop_log(k, effects)
    rep = diagnose(log, robot="generic", seed=0, simulate=False)
    return rep.to_dict(), truth, rep


def test_an_elastic_gear_is_unexplained_snap_structure_and_the_rigid_axis_is_clean(tmp_path):
    """Loop spec 988 (250 Hz, Gaussian noise, point-to-point moves): the elastic gear ends as structure in the
    snap, nothing named, and the report shows it; the same seed without the gear stays clean."""
    d, truth, rep = _loop_spec(988)
    assert truth["effects"] == ["compliance"]
    assert d["findings"] == []
    snap = [u for u in d["unexplained"] if u["variable"] == "snap_excluded_samples"]
    assert snap, d["unexplained"]
    u = snap[0]
    assert u["share_of_residual_variance"] >= 0.08 and u["p_value"] < 1e-6
    # below the resonance the gear's term is -(J_load^2 / k) snap: a negative coefficient
    assert u["snap_coefficient"] < 0
    assert len(u["profile_snap"]) == len(u["profile_mean_residual"]) >= 10
    rep.write(tmp_path)
    assert (tmp_path / "unexplained.png").stat().st_size > 1000
    # the console summary (drake-est diagnose) says what remains, not that the nominal model explains the data
    summ = rep.summary()
    assert "UNEXPLAINED joint 1: structure in snap_excluded_samples" in summ and "no cause named" in summ
    assert "nominal model explains" not in summ
    assert "snap_excluded_samples" in (tmp_path / "report.md").read_text()
    d0, truth0, rep0 = _loop_spec(988, effects={})
    assert truth0["effects"] == []
    assert d0["findings"] == [] and d0["unexplained"] == [], d0["unexplained"]
    assert "the nominal model explains the held-out data" in rep0.summary()
    assert "UNEXPLAINED" not in rep0.summary()


def test_the_snap_test_does_not_run_where_the_window_is_stretched():
    """Loop spec 1316: a null log at 50 Hz, where the 7-sample minimum stretches the 0.1 s derivative window to
    0.12 s and the snap test, run there in the first try, flagged outlying snap samples (share 0.10)."""
    d, truth, _ = _loop_spec(1316)
    assert truth["effects"] == []
    assert d["findings"] == [] and d["unexplained"] == [], d["unexplained"]


def test_quantized_elastic_gear_is_reported_and_quantized_null_logs_stay_clean(monkeypatch):
    """Loop spec 1934 (1000 Hz, quantized torque): the elastic gear's snap term has a fitted RMS between half a
    torque ADC step and one; with the rounding error's harmonics as nuisance columns
    (:func:`~drake_est.diagnose.unexplained.quantization_nuisance`) the snap test reports it without a guard, and a
    one-step guard on it (``QUANTIZATION_NUISANCE_TESTS`` empty) sets it aside.  Loop spec 238 (250 Hz, quantized,
    nothing planted) stays clean."""
    import drake_est.diagnose.unexplained as U
    d, truth, _ = _loop_spec(1934)
    assert truth["effects"] == ["compliance"]
    assert d["findings"] == []
    assert "snap_excluded_samples" in [u["variable"] for u in d["unexplained"]], d["unexplained"]
    d0, truth0, _ = _loop_spec(238)
    assert truth0["effects"] == [] and d0["findings"] == [] and d0["unexplained"] == [], d0["unexplained"]
    monkeypatch.setattr(U, "QUANTIZATION_NUISANCE_TESTS", ())
    d1, _, _ = _loop_spec(1934)
    # with the one-step guard the snap entry is set aside; the matched-filter test (fifteenth round), whose
    # structure is larger than one step here, still reports the gear
    assert d1["findings"] == [] and "snap_excluded_samples" not in [u["variable"] for u in d1["unexplained"]], \
        d1["unexplained"]