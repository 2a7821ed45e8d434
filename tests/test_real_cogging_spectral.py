"""Real data: LPV spectral analysis of the ODrive cogging logs (gchenfc/ODrive, MIT)."""
import numpy as np
import pytest

from drake_est.errors import DataError

needs_data = pytest.mark.requires_data("odrive_cogging/slow2/nocomp_0.npy")  # skip locally, fail under CI=true


@needs_data
def test_load_log_and_map():
    from drake_est.datasets.odrive import load_cogging_map, load_odrive_log

    log = load_odrive_log("slow2/nocomp_0.npy")
    assert log.meta["tau_unit"] == "A" and not log.meta["compensated"]
    assert log.n_samples > 4000
    # one revolution: the motor angle spans about 2 pi, the mean velocity is positive
    assert 5.5 < np.ptp(log.q[:, 0]) < 7.0
    assert np.median(log.dq[:, 0]) > 0
    assert load_odrive_log("slow2/comp_0.npy").meta["compensated"]
    ang, cur = load_cogging_map("cogging_measure_final_a_16.npy")
    assert ang.size == 512 and np.all(np.diff(ang) > 0) and np.all(cur != 0)
    ang, cur = load_cogging_map("cogging_measure_final_a_4_interp.npy")
    assert ang.size == 8192


def test_missing_data_is_a_data_error(tmp_path):
    from drake_est.datasets.odrive import load_odrive_log

    with pytest.raises(DataError, match="not found"):
        load_odrive_log("slow2/nocomp_0.npy", data=tmp_path)


@needs_data
def test_cogging_case_study(tmp_path):
    from drake_est.cases.cogging_spectral import cogging_case_study

    r = cogging_case_study(out_dir=tmp_path)
    # harmonics near 7, 14, 28 and 36 per revolution are found without being told
    assert all(r["expected_found_within_0.5_per_rev"].values()), r["harmonics_per_rev"]
    assert abs(r["harmonics_per_rev"][0] - 7.0) < 0.2          # the dominant one
    # they explain most of what Coulomb + viscous friction leave, also on held-out logs
    assert r["total_explained_fraction_of_cv_residual"] > 0.8
    for name, h in r["held_out"].items():
        assert h["with_harmonics_rms_A"] < 0.75 * h["coulomb_viscous_rms_A"], name
    # anti-cogging compensation removes most of the velocity ripple at those harmonics
    s = r["velocity_ripple_summary"]
    assert s["compensated_mean_ripple_rms_rad_s"] < 0.5 * s["uncompensated_mean_ripple_rms_rad_s"]
    # the estimated ripple resembles the measured cogging map
    assert r["map_comparison"]["correlation"] > 0.6
    for f in r["figures"]:
        assert (tmp_path / f).stat().st_size > 10_000
