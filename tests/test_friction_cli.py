"""drake-est fit-friction and the friction reproductions."""
import json

import numpy as np
import pytest

from drake_est.cli import main
from drake_est.data import from_arrays, save_log


def _sweep_log(path, seed=0, duration=120.0, fs=50.0, single_speed=False):
    rng = np.random.default_rng(seed)
    dt = 1.0 / fs
    t = np.arange(0.0, duration, dt)
    q = np.empty_like(t)
    v = np.empty_like(t)
    qk, vk, d, vc = 0.0, 0.0, 1.0, 0.5
    for k in range(t.size):
        vk += np.clip(d * vc - vk, -2 * dt, 2 * dt)
        qk += vk * dt
        if not single_speed and ((d > 0 and qk >= 1.5) or (d < 0 and qk <= -1.5)):
            d, vc = -d, rng.choice([0.2, 0.5, 0.8, 1.1])
        q[k], v[k] = qk, vk
    F = 1.2 * v + np.sign(v) * (3.0 + 0.8 * np.exp(-0.5 * ((q - 0.4) / 0.3) ** 2))
    tau = F + 0.05 * rng.standard_normal(t.size)
    log = from_arrays(t, q[:, None], tau=tau[:, None], dq=v[:, None], joints=[1])
    return save_log(log, path)


def test_fit_friction_cli_writes_params_and_plots(tmp_path, capsys):
    path = _sweep_log(tmp_path / "sweep.csv")
    out = tmp_path / "fit"
    rc = main(["fit-friction", str(path), "--model", "position", "--joint", "1", "--out", str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    assert "validation" in text and "RMSE" in text and "dropped" in text
    doc = json.loads((out / "params.json").read_text())
    assert doc["model"]["format"] == "drake_est.friction/2"
    assert doc["model"]["joint"] == 1 and doc["model"]["index"] == 0     # 1-based joint number in files
    assert doc["validation"]["rmse"] < 0.1
    for name in ("torque_vs_position_velocity.png", "residual_histogram.png", "fit_over_time.png"):
        assert (out / name).stat().st_size > 1000
    # the written model drops into the Drake system
    from drake_est.systems.friction import FrictionModel
    fm = FrictionModel.from_json(out / "params.json")
    assert fm.friction([0.4], [0.5])[0] == pytest.approx(1.2 * 0.5 + 3.8, abs=0.15)


def test_fit_friction_cli_bad_inputs(tmp_path, capsys):
    path = _sweep_log(tmp_path / "one_speed.csv", duration=20.0, single_speed=True)
    rc = main(["fit-friction", str(path), "--model", "nominal", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2
    assert "not identifiable" in err or "not excited" in err
    assert "Traceback" not in err
    rc = main(["fit-friction", str(tmp_path / "missing.csv"), "--out", str(tmp_path / "o")])
    assert rc == 2
    path = _sweep_log(tmp_path / "short.csv", duration=16.0, fs=10.0)
    rc = main(["fit-friction", str(path), "--model", "motor", "--gear-ratio", "100", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and "too few samples" in err


def test_reproduce_friction_energy_quick(tmp_path):
    from drake_est.reproduce.friction import friction_energy
    res = friction_energy(tmp_path, quick=True, seed=0, realizations=4)
    a = res["algorithm6_anderson"]
    assert a["median_npe"] < 0.05
    assert abs(a["rmse_over_noise"] - 1.0) < 0.10
    assert (tmp_path / "fig9_5_errors.png").exists()


def test_params_json_joint_numbers_are_one_based(tmp_path):
    """issue #18: a model of joint 2 fitted from a log holding only joints [2, 3] (data column 0) lands
    on joint 2 of the plant, not on joint 1; old 0-based files load with a DeprecationWarning."""
    import warnings

    from drake_est.identification.friction import JointFriction
    from drake_est.systems.friction import FrictionModel
    m = JointFriction.coulomb_viscous(3.0, 1.0, index=0, joint_number=2)   # data column 0 holds joint 2
    d = {"model": m.to_dict()}
    fm = FrictionModel.from_params(d, n_joints=3)
    F = fm.friction([0, 0, 0], [0.0, 0.5, 0.0])
    assert F[0] == 0.0 and F[1] == pytest.approx(3.0 + 0.5) and F[2] == 0.0
    p = fm.write_json(tmp_path / "params.json")
    doc = json.loads(p.read_text())
    assert list(doc["models"]) == ["2"] and doc["models"]["2"]["joint"] == 2
    np.testing.assert_array_equal(FrictionModel.from_json(p).friction([0, 0, 0], [0.0, 0.5, 0.0]), F)
    legacy = {"models": {"1": dict(m.to_dict(), format="drake_est.friction/1", joint=1)}}
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        fl = FrictionModel.from_params(legacy, n_joints=3)
    assert any("0-based" in str(x.message) for x in w)
    np.testing.assert_array_equal(fl.friction([0, 0, 0], [0.0, 0.5, 0.0]), F)
    from drake_est.errors import DataError
    with pytest.raises(DataError, match="1-based"):
        FrictionModel({0: m}, n_joints=3)
