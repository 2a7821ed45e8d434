"""Sensor calibration (thesis Sec. 6.1 and Ch. 13): SO(3) helpers, F/T sensor, laser scanners."""
import numpy as np
import pytest

from drake_est.calibration import (
    assign_scans_to_planes, calibrate_ft, calibrate_laser, exp_se3, log_se3, log_so3, exp_so3,
    perturb_transform, project_to_so3, random_ft_poses, random_laser_problem, random_rotation, rotation_error,
    simulate_ft, tls, transform_error, transform_points,
)
from drake_est.calibration.so3 import cayley, make_pose, skew
from drake_est.calibration.simulate import laser_rays, scan_planes
from drake_est.errors import DataError, IdentifiabilityError


# ----------------------------------------------------------------------------- SO(3) / SE(3)
def test_project_to_so3_is_closest_rotation():
    rng = np.random.default_rng(0)
    R = random_rotation(rng)
    M = 2.5 * R + 0.05 * rng.standard_normal((3, 3))
    P = project_to_so3(M)
    assert np.allclose(P.T @ P, np.eye(3), atol=1e-12) and np.isclose(np.linalg.det(P), 1.0)
    assert rotation_error(P, R) < 0.05
    # no other rotation near P is closer to M in the Frobenius norm
    for _ in range(50):
        Q = P @ exp_so3(1e-2 * rng.standard_normal(3))
        assert np.linalg.norm(M - Q) >= np.linalg.norm(M - P) - 1e-12
    # a reflection is mapped to a proper rotation (det +1), Eq. (6.2)
    assert np.isclose(np.linalg.det(project_to_so3(np.diag([1.0, 1.0, -1.0]))), 1.0)
    with pytest.raises(DataError):
        project_to_so3(np.full((3, 3), np.nan))


def test_exp_log_roundtrip_and_cayley():
    rng = np.random.default_rng(1)
    for _ in range(20):
        xi = np.r_[rng.standard_normal(3), rng.uniform(-3, 3, 3) / np.sqrt(3)]
        T = exp_se3(xi)
        assert np.allclose(exp_se3(log_se3(T)), T, atol=1e-10)
    w = np.array([0.0, 0.0, np.pi])
    assert np.allclose(exp_so3(log_so3(exp_so3(w))), exp_so3(w), atol=1e-8)
    s = rng.standard_normal(3)
    R = cayley(s)
    assert np.allclose(R.T @ R, np.eye(3), atol=1e-12) and np.isclose(np.linalg.det(R), 1)
    assert np.allclose(skew([1, 2, 3]) @ [4, 5, 6], np.cross([1, 2, 3], [4, 5, 6]))


def test_tls_beats_ls_on_errors_in_variables():
    rng = np.random.default_rng(2)
    x_true = np.array([1.5, -0.7])
    A = rng.standard_normal((4000, 2))
    y = A @ x_true
    An = A + 0.4 * rng.standard_normal(A.shape)
    yn = y + 0.4 * rng.standard_normal(len(y))
    x_ls = np.linalg.lstsq(An, yn, rcond=None)[0]
    x_tls = tls(An, yn)
    assert np.linalg.norm(x_tls - x_true) < 0.3 * np.linalg.norm(x_ls - x_true)
    # mixed LS-TLS: an exact column of ones (offset) is recovered
    yb = y + 3.0
    x = tls(np.column_stack([An, np.ones(len(y))]), yb + 0.4 * rng.standard_normal(len(y)), exact_cols=[2])
    assert np.allclose(x, [1.5, -0.7, 3.0], atol=0.1)


# ----------------------------------------------------------------------------- F/T sensor
def _ft_problem(seed, noise_f=0.0, noise_t=0.0, n=100):
    rng = np.random.default_rng(seed)
    poses = random_ft_poses(rng, n)
    R = random_rotation(rng)
    m = rng.uniform(0.5, 3.0)
    com = rng.uniform(-0.05, 0.05, 3) + [0, 0, 0.08]
    fb, tb = rng.uniform(-2, 2, 3), rng.uniform(-0.1, 0.1, 3)
    W = simulate_ft(poses, R, m, com, fb, tb, noise_f, noise_t, rng=rng)
    return poses, W, R, m, com, fb, tb


def test_ft_relaxation_recovers_everything_with_unknown_mass():
    poses, W, R, m, com, fb, tb = _ft_problem(0, noise_f=0.01, noise_t=0.0005)
    res = calibrate_ft(poses, W, method="relaxation", m0=2 * m)
    assert rotation_error(res.R, R) < 1e-3
    assert abs(res.mass - m) < 0.01 * m
    assert np.linalg.norm(res.com - com) < 0.01 * np.linalg.norm(com)
    assert np.allclose(res.force_bias, fb, atol=0.01) and np.allclose(res.torque_bias, tb, atol=1e-3)
    # residuals at the noise level; compensation removes the payload's gravity
    assert abs(np.sqrt(np.mean(res.residuals[:, :3] ** 2)) - 0.01) < 0.003
    assert np.abs(res.compensate(poses, W)[:, :3]).max() < 0.06
    # the initial mass only scales the relaxed problem: the answer does not depend on it
    res2 = calibrate_ft(poses, W, method="relaxation", m0=0.1 * m)
    assert np.allclose(res2.R, res.R, atol=1e-12) and np.isclose(res2.mass, res.mass)


def test_ft_cayley_needs_mass_and_matches_with_true_mass():
    poses, W, R, m, com, fb, tb = _ft_problem(1, noise_f=0.01, noise_t=0.0005)
    res = calibrate_ft(poses, W, method="cayley", mass=m)
    assert rotation_error(res.R, R) < 2e-3
    assert np.allclose(res.force_bias, fb, atol=0.02)
    wrong = calibrate_ft(poses, W, method="cayley", mass=1.1 * m)
    assert rotation_error(wrong.R, R) > 5 * rotation_error(res.R, R)
    with pytest.raises(DataError, match="mass"):
        calibrate_ft(poses, W, method="cayley")
    with pytest.raises(DataError, match="method"):
        calibrate_ft(poses, W, method="euler")


def test_ft_relaxation_at_least_as_good_as_cayley_across_noise():
    """Fig. 13.1 left panel: relaxation (m0 = 2m) vs Cayley given the true mass, median of 10 trials."""
    for sigma in [1e-3, 1e-2, 1e-1, 1.0]:
        e_rel, e_cay = [], []
        for k in range(10):
            poses, W, R, m, *_ = _ft_problem(100 + k, noise_f=sigma)
            e_rel.append(rotation_error(calibrate_ft(poses, W, m0=2 * m, bias=False).R, R))
            e_cay.append(rotation_error(calibrate_ft(poses, W, method="cayley", mass=m, bias=False).R, R))
        assert np.median(e_rel) <= 1.05 * np.median(e_cay), sigma


def test_ft_bad_input_says_what_to_collect():
    poses, W, *_ = _ft_problem(2)
    same = np.repeat(poses[:1], 20, axis=0)
    same[:, :3, 3] += np.random.default_rng(0).uniform(size=(20, 3))  # positions vary, orientation does not
    with pytest.raises(IdentifiabilityError, match="same orientation"):
        calibrate_ft(same, W[:20])
    with pytest.raises(IdentifiabilityError, match="at least 4 poses"):
        calibrate_ft(poses[:3], W[:3])
    with pytest.raises(DataError, match="match"):
        calibrate_ft(poses[:10], W[:9])
    Wn = W.copy()
    Wn[3, 0] = np.nan
    with pytest.raises(DataError, match="NaN"):
        calibrate_ft(poses, Wn)
    # rotations only about the gravity axis: gravity seen along a single flange direction
    Rz = [make_pose(exp_so3([0, 0, a])) for a in np.linspace(0, 3, 10)]
    with pytest.raises(IdentifiabilityError):
        calibrate_ft(np.array(Rz), W[:10])


def test_ft_warns_about_weak_direction():
    rng = np.random.default_rng(3)
    # tool tilted at most 8 degrees: gravity stays near one flange direction
    poses = np.stack([make_pose(exp_so3(np.r_[rng.uniform(-0.14, 0.14, 2), rng.uniform(-3, 3)])) for _ in range(40)])
    W = simulate_ft(poses, np.eye(3), 1.0, [0, 0, 0.05], noise_force=1e-3, rng=rng)
    with pytest.warns(UserWarning, match="condition number"):
        res = calibrate_ft(poses, W)
    assert res.condition > 50 and abs(res.weak_direction[2]) > 0.9


# ----------------------------------------------------------------------------- laser scanner
def test_laser_converges_from_crude_guess():
    """Sec. 13.2 simulation (5 realizations here; 100 in `drake-est reproduce laser-calibration`)."""
    errs = []
    for k in range(5):
        rng = np.random.default_rng(k)
        pr = random_laser_problem(rng, n_rays=32, tilt_deg=45)
        T0 = perturb_transform(pr.T_true, rng, 0.2, 30.0)
        res = calibrate_laser(pr.poses, pr.points, pr.pose_index, labels=pr.labels, T0=T0, n_iter=30)
        et, er = transform_error(res.T, pr.T_true)
        errs.append((et, np.degrees(er)))
        assert abs(res.rms - 0.5e-3) < 0.1e-3  # converged to the noise level
        assert res.history_rms[0] > 10 * res.rms
    errs = np.array(errs)
    assert np.all(errs[:, 0] < 2e-3) and np.all(errs[:, 1] < 0.3)
    assert np.median(errs[:, 0]) < 0.7e-3 and np.median(errs[:, 1]) < 0.15


def test_laser_literal_thesis_step_converges_without_noise():
    rng = np.random.default_rng(7)
    pr = random_laser_problem(rng, noise=0.0, n_rays=16, tilt_deg=45)
    T0 = perturb_transform(pr.T_true, rng, 0.02, 3.0)
    res = calibrate_laser(pr.poses, pr.points, pr.pose_index, labels=pr.labels, T0=T0, n_iter=60,
                          joint_offsets=False)
    et0, _ = transform_error(T0, pr.T_true)
    et, er = transform_error(res.T, pr.T_true)
    assert et < 0.5 * et0 and np.all(np.diff(res.history_rms) <= 1e-12)


def test_laser_tls_refine_and_sensor_plane_axes():
    rng = np.random.default_rng(11)
    pr = random_laser_problem(rng, n_rays=32, tilt_deg=45, axes=(0, 2))  # points (x, 0, z), as real line scanners
    T0 = perturb_transform(pr.T_true, rng, 0.05, 10.0)
    assert np.all(pr.points[:, 1] == 0)
    for method in ("ls", "tls"):
        res = calibrate_laser(pr.poses, pr.points, pr.pose_index, labels=pr.labels, T0=T0, method=method,
                              refine=(method == "ls"))
        et, er = transform_error(res.T, pr.T_true)
        assert et < 1.5e-3 and np.degrees(er) < 0.3, (method, et, er)
        assert res.axes == (0, 2)


def test_point_laser_and_3d_scanner():
    rng = np.random.default_rng(12)
    # point laser (13.C): one point per pose on the sensor x axis; many poses per plane
    pr = random_laser_problem(rng, n_rays=1, fov_deg=0.0, axes=(0, 1), poses_per_plane=40, noise=1e-4)
    pts = np.column_stack([pr.points[:, 1], np.zeros((len(pr.points), 2))])  # range along the beam
    T_true = pr.T_true.copy()
    T_true[:3, 0] = pr.T_true[:3, 1]  # the beam is the sensor's y axis in the simulation: relabel as x
    T0 = perturb_transform(T_true, rng, 0.02, 5.0)
    res = calibrate_laser(pr.poses, pts, pr.pose_index, labels=pr.labels, T0=T0)
    assert res.kind == "point"
    assert np.linalg.norm(res.T[:3, 3] - T_true[:3, 3]) < 2e-3
    assert np.degrees(np.arccos(np.clip(res.T[:3, 0] @ T_true[:3, 0], -1, 1))) < 0.3
    # 3-D scanner (13.D): each pose also sees a second fan in the sensor's y-z plane, so points span 3-D
    pr3 = random_laser_problem(np.random.default_rng(13), n_rays=24, tilt_deg=45)
    rays2 = laser_rays(24, 40.0, axes=(2, 1))
    extra_p, extra_i, extra_l = [], [], []
    for i, Tf in enumerate(pr3.poses):
        p, lab = scan_planes(Tf @ pr3.T_true, pr3.planes, rays2)
        ok = lab >= 0
        extra_p.append(p[ok] + np.random.default_rng(i).normal(0, 0.5e-3, (ok.sum(), 3)) * [0, 1, 1])
        extra_i.append(np.full(ok.sum(), i))
        extra_l.append(lab[ok])
    pts3 = np.concatenate([pr3.points] + extra_p)
    idx3 = np.concatenate([pr3.pose_index] + extra_i)
    lab3 = np.concatenate([pr3.labels] + extra_l)
    T0 = perturb_transform(pr3.T_true, rng, 0.05, 10.0)
    res3 = calibrate_laser(pr3.poses, pts3, idx3, labels=lab3, T0=T0)
    assert res3.kind == "3d"
    et, er = transform_error(res3.T, pr3.T_true)
    assert et < 1.5e-3 and np.degrees(er) < 0.3


def test_automatic_plane_assignment():
    rng = np.random.default_rng(21)
    pr = random_laser_problem(rng, n_rays=32, tilt_deg=45)
    T0 = perturb_transform(pr.T_true, rng, 0.01, 2.0)
    res = calibrate_laser(pr.poses, pr.points, pr.pose_index, labels=None, T0=T0, assign_threshold=0.01)
    et, er = transform_error(res.T, pr.T_true)
    assert et < 1.5e-3 and np.degrees(er) < 0.3
    # the found partition equals the true one
    pairs = set(zip(res.labels.tolist(), pr.labels.tolist()))
    assert len(pairs) == 3
    lab = assign_scans_to_planes(transform_points(pr.poses, pr.T_true, pr.points, pr.pose_index), pr.pose_index,
                                 threshold=3e-3)
    assert len(set(zip(lab.tolist(), pr.labels.tolist()))) == 3


def test_laser_bad_input_says_what_to_collect():
    pr = random_laser_problem(np.random.default_rng(5), n_rays=16, tilt_deg=45)
    two = pr.labels < 2
    with pytest.raises(IdentifiabilityError, match="at least 3 non-parallel planes"):
        calibrate_laser(pr.poses, pr.points[two], pr.pose_index[two], labels=pr.labels[two], T0=pr.T_true)
    few = np.flatnonzero(pr.labels == 0)[:5].tolist() + np.flatnonzero(pr.labels == 1)[:3].tolist()
    with pytest.raises(IdentifiabilityError, match="at least 9 points"):
        calibrate_laser(pr.poses, pr.points[few], pr.pose_index[few], labels=pr.labels[few])
    # one pose per plane: each plane seen as a single line
    first = np.array([np.flatnonzero(pr.labels == j)[0] for j in range(3)])
    one = np.isin(pr.pose_index, pr.pose_index[first]) & np.isin(np.arange(len(pr.labels)), np.flatnonzero(
        np.isin(pr.pose_index, pr.pose_index[first])))
    with pytest.raises(IdentifiabilityError, match="at least 2 poses"):
        calibrate_laser(pr.poses, pr.points[one], pr.pose_index[one], labels=pr.labels[one], T0=pr.T_true)
    # three parallel planes
    n = np.array([0.0, 0.0, 1.0])
    planes = np.array([np.r_[n, 0.6], np.r_[n, 0.8], np.r_[n, 1.0]])
    prp = random_laser_problem(np.random.default_rng(6), planes=planes, n_rays=16, tilt_deg=10)
    with pytest.raises(IdentifiabilityError, match="parallel"):
        calibrate_laser(prp.poses, prp.points, prp.pose_index, labels=prp.labels, T0=prp.T_true)
    # the same planes scanned from strongly varied orientations determine T: the check judges the
    # problem actually solved (condition number of the joint T/offset regressor), not the normals alone
    prp = random_laser_problem(np.random.default_rng(6), planes=planes, n_rays=16, tilt_deg=45)
    res = calibrate_laser(prp.poses, prp.points, prp.pose_index, labels=prp.labels, T0=prp.T_true)
    et, er = transform_error(res.T, prp.T_true)
    assert et < 2e-3 and np.degrees(er) < 0.1
    with pytest.raises(DataError, match="pose_index"):
        calibrate_laser(pr.poses, pr.points, pr.pose_index.astype(float), labels=pr.labels)
