"""`drake-est calibrate ft|laser` and the calibration reproductions (quick sizes)."""
import json

import numpy as np
import pytest

from drake_est.calibration import (
    perturb_transform, random_ft_poses, random_laser_problem, random_rotation, rotation_error, simulate_ft,
    transform_error,
)
from drake_est.cli import main


def _ft_files(tmp_path):
    rng = np.random.default_rng(0)
    poses = random_ft_poses(rng, 40)
    R = random_rotation(rng)
    W = simulate_ft(poses, R, 1.3, [0.01, 0.0, 0.07], [0.3, -0.2, 0.5], [0.01, 0, 0], 0.01, 0.001, rng=rng)
    np.savez(tmp_path / "ft.npz", poses=poses, wrench=W)
    cols = {f"r{i+1}{j+1}": poses[:, i, j] for i in range(3) for j in range(3)}
    cols.update(px=poses[:, 0, 3], py=poses[:, 1, 3], pz=poses[:, 2, 3])
    cols.update({k: W[:, i] for i, k in enumerate(["fx", "fy", "fz", "tx", "ty", "tz"])})
    header = ",".join(cols)
    np.savetxt(tmp_path / "ft.csv", np.column_stack(list(cols.values())), delimiter=",", header=header, comments="")
    return R


def test_cli_ft_npz_and_csv(tmp_path, capsys):
    R = _ft_files(tmp_path)
    for name in ("ft.npz", "ft.csv"):
        out = tmp_path / ("out_" + name)
        assert main(["calibrate", "ft", str(tmp_path / name), "--out", str(out)]) == 0
        s = json.loads((out / "calibrate_ft.json").read_text())
        assert rotation_error(np.array(s["R_S_TF"]), R) < 3e-3
        assert abs(s["mass_kg"] - 1.3) < 0.013
        assert s["residual_rms_force_N"] < 0.02 < s["before_rms_force_N"]
        assert (out / "ft_residual_histogram.png").stat().st_size > 1000
    assert "condition number" in capsys.readouterr().out


def test_cli_ft_bad_input_exits_2(tmp_path, capsys):
    rng = np.random.default_rng(1)
    poses = np.repeat(random_ft_poses(rng, 1), 10, axis=0)
    np.savez(tmp_path / "same.npz", poses=poses, wrench=rng.normal(size=(10, 6)))
    assert main(["calibrate", "ft", str(tmp_path / "same.npz"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "same orientation" in err and "Traceback" not in err
    np.savez(tmp_path / "nopose.npz", wrench=rng.normal(size=(10, 6)))
    assert main(["calibrate", "ft", str(tmp_path / "nopose.npz"), "--out", str(tmp_path / "o")]) == 2
    assert main(["calibrate", "ft", str(tmp_path / "missing.npz"), "--out", str(tmp_path / "o")]) == 2


def test_cli_laser_npz_mm_units_and_auto_planes(tmp_path, capsys):
    rng = np.random.default_rng(3)
    pr = random_laser_problem(rng, n_rays=24, tilt_deg=45)
    T0 = perturb_transform(pr.T_true, rng, 0.01, 2.0)
    P_mm = pr.poses.copy()
    P_mm[:, :3, 3] *= 1e3
    T0_mm = T0.copy()
    T0_mm[:3, 3] *= 1e3
    np.savez(tmp_path / "laser.npz", poses=P_mm, points=pr.points * 1e3, pose_index=pr.pose_index, T0=T0_mm)
    out = tmp_path / "out"
    assert main(["calibrate", "laser", str(tmp_path / "laser.npz"), "--out", str(out), "--length-scale", "0.001",
                 "--assign-threshold", "0.01"]) == 0
    s = json.loads((out / "calibrate_laser.json").read_text())
    et, er = transform_error(np.array(s["T_TF_S"]), pr.T_true)
    assert et < 1.5e-3 and np.degrees(er) < 0.3 and s["n_planes"] == 3
    assert abs(s["rms_m"] - 0.5e-3) < 0.1e-3 and s["rms_before_m"] > 2 * s["rms_m"]
    assert (out / "laser_residual_histogram.png").exists()


def test_cli_laser_csv_with_labels_and_bad_input(tmp_path, capsys):
    rng = np.random.default_rng(4)
    pr = random_laser_problem(rng, n_rays=16, tilt_deg=45)
    P = pr.poses[pr.pose_index]
    cols = {f"r{i+1}{j+1}": P[:, i, j] for i in range(3) for j in range(3)}
    cols.update(px=P[:, 0, 3], py=P[:, 1, 3], pz=P[:, 2, 3], x=pr.points[:, 0], y=pr.points[:, 1],
                z=pr.points[:, 2], plane=pr.labels)
    np.savetxt(tmp_path / "l.csv", np.column_stack(list(cols.values())), delimiter=",", header=",".join(cols),
               comments="")
    out = tmp_path / "o"
    from pydrake.math import RollPitchYaw, RotationMatrix

    t = pr.T_true
    rpy = np.degrees(RollPitchYaw(RotationMatrix(t[:3, :3])).vector()) + [5, -5, 5]
    assert main(["calibrate", "laser", str(tmp_path / "l.csv"), "--out", str(out), "--T0",
                 f"{t[0, 3] + 0.1} {t[1, 3]} {t[2, 3]} {rpy[0]} {rpy[1]} {rpy[2]}", "--method", "tls"]) == 0
    s = json.loads((out / "calibrate_laser.json").read_text())
    et, er = transform_error(np.array(s["T_TF_S"]), pr.T_true)
    assert et < 2e-3 and np.degrees(er) < 0.3
    # only two planes -> a one-line error that says what to collect
    keep = pr.labels < 2
    cols2 = {k: v[keep] for k, v in cols.items()}
    np.savetxt(tmp_path / "two.csv", np.column_stack(list(cols2.values())), delimiter=",",
               header=",".join(cols2), comments="")
    capsys.readouterr()
    assert main(["calibrate", "laser", str(tmp_path / "two.csv"), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "at least 3 non-parallel planes" in err and len(err.strip().splitlines()) == 1


def test_reproduce_quick(tmp_path):
    from drake_est.reproduce.calibration import ft_calibration, laser_calibration

    r = ft_calibration(tmp_path, quick=True)
    assert r["lowest_noise"]["mass_rel_error_max"] < 0.01 and r["lowest_noise"]["com_rel_error_max"] < 0.01
    assert (tmp_path / "ft_calibration_fig13_1.png").exists()
    r = laser_calibration(tmp_path, quick=True, n_real=3)
    assert r["methods"]["iterative"]["success_rate"] == 1.0
    assert (tmp_path / "laser_convergence_fig13_4.png").exists() and (tmp_path / "laser_errors_fig13_5.png").exists()


def test_cli_ft_from_irb140_joint_angles(tmp_path):
    from drake_est.robots import irb140

    rng = np.random.default_rng(7)
    Q = rng.uniform(-1.5, 1.5, (30, 6))
    poses = irb140().forward_kinematics_batch(Q)
    R = random_rotation(rng)
    W = simulate_ft(poses, R, 0.8, [0.0, 0.02, 0.05], noise_force=0.005, noise_torque=5e-4, rng=rng)
    np.savez(tmp_path / "q.npz", q=Q, wrench=W)
    out = tmp_path / "o"
    assert main(["calibrate", "ft", str(tmp_path / "q.npz"), "--out", str(out)]) == 0
    s = json.loads((out / "calibrate_ft.json").read_text())
    assert rotation_error(np.array(s["R_S_TF"]), R) < 3e-3 and abs(s["mass_kg"] - 0.8) < 0.008
