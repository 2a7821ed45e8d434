"""Acceptance checks of issue 7 at full size (run with: pytest -m slow tests/test_calibration_slow.py)."""
import numpy as np
import pytest


@pytest.mark.slow
def test_laser_acceptance_100_realizations(tmp_path):
    from drake_est.reproduce.calibration import laser_calibration

    r = laser_calibration(tmp_path, n_real=100, seed=0)
    it = r["methods"]["iterative"]
    assert it["success_rate"] == 1.0
    assert it["median_translation_mm"] < 0.5 and it["median_rotation_deg"] < 0.1
    assert 0.4 < r["final_rms_mm_median"] < 0.6  # converged to the noise level


@pytest.mark.slow
def test_ft_acceptance_noise_sweep(tmp_path):
    from drake_est.reproduce.calibration import ft_calibration

    r = ft_calibration(tmp_path, quick=False, seed=0)
    assert r["relaxation_m0_2m_not_worse_than_cayley_true_mass_all_levels"]
    low = r["lowest_noise"]
    assert low["mass_rel_error_max"] < 0.01 and low["com_rel_error_max"] < 0.01
    assert low["with_offset_estimation_mass_rel_error_max"] < 0.01
