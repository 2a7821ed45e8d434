"""Real-data calibration case studies (issue 8): YuMi F/T log and line-scanner board profiles."""
import numpy as np
import pytest

from drake_est.errors import DataError


def test_loaders_fail_clearly_without_data(tmp_path):
    from drake_est.datasets.linescanner import load_board
    from drake_est.datasets.yumi import load_gravitylog

    with pytest.raises(DataError, match="not found"):
        load_gravitylog(tmp_path)
    with pytest.raises(DataError, match="not found"):
        load_board(tmp_path)
    with pytest.raises(DataError, match="not found"):
        load_board(tmp_path / "missing")


def test_scan_yaml_parser(tmp_path):
    from drake_est.datasets.linescanner import parse_scan_yaml

    f = tmp_path / "1_3C_line.yml"
    f.write_text("%YAML:1.0\n---\nscan_line: [ 1.5, 0., .Nan, -2.0e+01,\n    0., 3. ]\n")
    p = parse_scan_yaml(f)
    assert p.shape == (2, 3) and np.isnan(p[0, 2]) and p[1, 0] == -20.0
    f.write_text("scan_line: [ 1, 2 ]\n")
    with pytest.raises(DataError, match="multiple of 3"):
        parse_scan_yaml(f)


@pytest.mark.requires_data("yumi_gravitylog/gravitylog.mat")
def test_real_yumi_ft_calibration(tmp_path):
    from drake_est.datasets.yumi import load_gravitylog
    from drake_est.cases.calibration import real_yumi_ft

    log = load_gravitylog()
    assert log.q.shape == (13802, 7) and log.wrench.shape == (13802, 6)
    r = real_yumi_ft(tmp_path, quick=True)
    assert r["chosen_variant"].startswith("chain order, joint-4 offset +90")
    f = r["force_rms_N"]
    # the calibrated model explains most of the force variation on the held-out half
    assert f["validation_after"] < 0.2 * f["validation_before"]
    assert 0.1 < r["tool_mass_kg"] < 0.5
    assert (tmp_path / "real_yumi_ft_validation.png").exists()


@pytest.mark.requires_data("linescanner/board/rob2board.txt")
def test_real_linescanner_board(tmp_path):
    from drake_est.datasets.linescanner import load_board, surface_points

    b = load_board()
    assert len(b.profiles) == 12 and b.raw_poses.shape == (12, 6)
    assert np.all(np.abs(b.profiles[0][:, 1]) == 0)  # (x, 0, z) profiles
    m, rms = surface_points(b.profiles[0])
    assert 0.5 < m.mean() < 0.9 and rms < 0.1e-3  # grooves removed, flat part at the sensor noise level
    from drake_est.cases.calibration import real_linescanner

    r = real_linescanner(tmp_path, quick=True)
    assert r["plane_rms_after_mm"] < r["plane_rms_before_mm"]
    assert "non-parallel planes" in r["thesis_method_check"]
    assert (tmp_path / "real_linescanner.png").exists()
