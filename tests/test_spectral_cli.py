"""CLI ``drake-est spectrum`` and the ``lpv-spectral`` reproduction."""
import json

import numpy as np
import pytest

from drake_est.cli import main
from drake_est.data import from_arrays, save_log
from drake_est.spectral import lomb_scargle, ls_scan
from drake_est.spectral.testsignal import ripple_signal


@pytest.fixture(scope="module")
def ripple_csv(tmp_path_factory):
    q, v, tau, truth = ripple_signal(n=12000, gear_ratio=117.0, harmonic=2, seed=5)
    t = np.arange(q.size) / 100.0
    log = from_arrays(t, q[:, None], tau=tau[:, None], dq=v[:, None])
    path = tmp_path_factory.mktemp("spec") / "ripple.csv"
    save_log(log, path)
    return path, truth


def test_cli_spectrum_writes_plots_and_json(ripple_csv, tmp_path, capsys):
    path, truth = ripple_csv
    out = tmp_path / "out"
    rc = main(["spectrum", str(path), "--signal", "tau1", "--position", "q1", "--schedule", "dq1",
               "--out", str(out), "--n-components", "2", "--gear-ratio", "117"])
    assert rc == 0
    res = json.loads((out / "spectrum.json").read_text())
    top = res["components"][0]
    assert abs(top["frequency_per_unit"] - truth["frequency_per_arm_rad"]) / truth["frequency_per_arm_rad"] < 0.01
    assert abs(top["frequency_per_motor_rev"] - 2.0) < 0.02
    assert res["frequency_unit"] == "cycles per motor revolution"
    assert top["amplitude_slope_vs_speed"] < 0
    for f in ("spectrum.png", "amplitude.png"):
        assert (out / f).stat().st_size > 10_000
    assert "cycles per motor revolution" in capsys.readouterr().out


def test_cli_bad_input_exits_2(ripple_csv, tmp_path, capsys):
    path, _ = ripple_csv
    assert main(["spectrum", str(path), "--signal", "tau7", "--position", "q1", "--out", str(tmp_path)]) == 2
    assert "tau7" in capsys.readouterr().err
    assert main(["spectrum", str(tmp_path / "nope.csv"), "--signal", "tau1", "--position", "q1"]) == 2
    err = capsys.readouterr().err
    assert "not found" in err and "Traceback" not in err
    assert main(["spectrum", str(path), "--signal", "tau1", "--position", "q1", "--f-max", "1e9",
                 "--out", str(tmp_path)]) == 2
    assert "sampling-density limit" in capsys.readouterr().err


def test_lomb_scargle_agrees_with_ls_scan_peak():
    rng = np.random.default_rng(0)
    x = np.sort(rng.uniform(0, 20, 400))
    y = np.cos(2 * np.pi * 1.7 * x + 0.3) + 0.2 * rng.standard_normal(400)
    f = np.linspace(0.1, 5, 2000)
    assert abs(f[np.argmax(lomb_scargle(x, y, f))] - 1.7) < 0.01
    assert abs(f[np.argmax(ls_scan(x, y - y.mean(), f))] - 1.7) < 0.01


def test_reproduce_lpv_spectral_quick(tmp_path):
    from drake_est.reproduce.spectral import lpv_spectral

    r = lpv_spectral(tmp_path, quick=True, seed=0)
    assert r["isolates_all_three"]["lpv"] and r["isolates_all_three"]["group_lasso_lpv"]
    assert not r["isolates_all_three"]["periodogram"] and not r["isolates_all_three"]["welch"]
    assert r["group_lasso"]["absent_all_zero"]
    assert np.all(np.asarray(r["amplitude_rmse_v_0.05_0.95"]) < 0.15)
    assert np.all(np.asarray(r["band_coverage_region"]) >= 0.9)
    for f in r["figures"]:
        assert (tmp_path / f).stat().st_size > 10_000
