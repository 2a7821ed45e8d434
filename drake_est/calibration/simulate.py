"""Synthetic calibration data: laser scans of planes and F/T poses (used by tests, reproductions, the
Drake sensor systems and the tutorial).  Geometry only; no plant needed."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_est.calibration.so3 import inv_pose, make_pose, random_rotation, rpy_to_matrix


def laser_rays(n_rays: int = 16, fov_deg: float = 40.0, axes=(0, 1)) -> np.ndarray:
    """Unit ray directions (n_rays, 3) of a fan in the sensor plane spanned by ``axes``; the
    viewing direction is ``axes[1]`` and the fan spreads along ``axes[0]``."""
    a = np.radians(np.linspace(-fov_deg / 2, fov_deg / 2, n_rays))
    U = np.zeros((n_rays, 3))
    U[:, axes[0]] = np.sin(a)
    U[:, axes[1]] = np.cos(a)
    return U


def scan_planes(T_rb_s, planes, rays, max_range: float = 1.0, min_range: float = 0.0):
    """Intersect sensor rays with planes n^T p = d (base frame).

    Returns ``points`` (n_rays, 3) in sensor coordinates (NaN where no plane is hit within range) and
    ``labels`` (n_rays,) the index of the plane hit (-1: none).  The first plane along each ray wins.
    """
    R, o = T_rb_s[:3, :3], T_rb_s[:3, 3]
    U = rays @ R.T  # world directions
    planes = np.atleast_2d(planes)
    den = U @ planes[:, :3].T                      # (n_rays, K)
    num = planes[:, 3] - planes[:, :3] @ o         # (K,)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = num[None, :] / den
    t[~np.isfinite(t) | (t <= min_range) | (t > max_range)] = np.inf
    j = np.argmin(t, axis=1)
    tt = t[np.arange(len(rays)), j]
    hit = np.isfinite(tt)
    pts = np.full((len(rays), 3), np.nan)
    pts[hit] = rays[hit] * tt[hit, None]
    labels = np.where(hit, j, -1)
    return pts, labels


def random_sensor_transform(rng, max_offset: float = 0.1) -> np.ndarray:
    """Random T_TF^S: uniform rotation, translation uniform in +-max_offset per axis [m]."""
    return make_pose(random_rotation(rng), rng.uniform(-max_offset, max_offset, 3))


def perturb_transform(T, rng, trans: float = 0.2, angle_deg: float = 30.0) -> np.ndarray:
    """Initial guess as in Sec. 13.2: x, y, z ~ U(-trans, trans), roll, pitch, yaw ~ U(-angle, angle)."""
    rpy = np.radians(rng.uniform(-angle_deg, angle_deg, 3))
    return make_pose(T[:3, :3] @ rpy_to_matrix(rpy), T[:3, 3] + rng.uniform(-trans, trans, 3))


@dataclass
class LaserProblem:
    poses: np.ndarray       # (M, 4, 4) flange poses
    points: np.ndarray      # (N, 3) sensor coordinates, noisy
    pose_index: np.ndarray  # (N,)
    labels: np.ndarray      # (N,) plane index
    T_true: np.ndarray      # T_TF^S
    planes: np.ndarray      # (K, 4) n, d


def orthogonal_planes(rng, n_planes: int = 3, distance=(0.6, 1.0)) -> np.ndarray:
    """Planes n^T p = d with (nearly) orthogonal normals (the first 3 are exactly orthogonal)."""
    Q = random_rotation(rng)
    normals = [Q[:, i] for i in range(min(n_planes, 3))]
    while len(normals) < n_planes:
        v = rng.standard_normal(3)
        normals.append(v / np.linalg.norm(v))
    return np.array([np.r_[n, rng.uniform(*distance)] for n in normals])


def random_laser_problem(rng, n_planes: int = 3, poses_per_plane: int = 10, noise: float = 0.5e-3,
                         n_rays: int = 16, fov_deg: float = 40.0, standoff=(0.15, 0.35), tilt_deg: float = 30.0,
                         T_true=None, planes=None, axes=(0, 1), occlusion: bool = True) -> LaserProblem:
    """Scans of ``n_planes`` planes, ``poses_per_plane`` random sensor poses each (Sec. 13.2 simulation).

    Each pose looks at its plane from a random standoff, tilted up to ``tilt_deg`` from the normal and
    spun randomly about the viewing direction; Gaussian noise (std ``noise`` m) is added to the two
    in-plane sensor coordinates.  Points on other planes hit first are kept with their true label;
    with ``occlusion=False`` each pose sees only its own plane (finite patches, e.g. a step and a wall
    facing the same way, where an infinite plane in front would otherwise hide the one behind).
    """
    rng = np.random.default_rng(rng)
    T_true = random_sensor_transform(rng) if T_true is None else T_true
    planes = orthogonal_planes(rng, n_planes) if planes is None else np.atleast_2d(planes)
    rays = laser_rays(n_rays, fov_deg, axes)
    view = axes[1]
    poses, pts, idx, labs = [], [], [], []
    for j, pl in enumerate(planes):
        n, d = pl[:3], pl[3]
        c = n * d
        # in-plane basis
        h = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
        e1 = np.cross(n, h)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(n, e1)
        got = 0
        while got < poses_per_plane:
            o = c + rng.uniform(-0.2, 0.2) * e1 + rng.uniform(-0.2, 0.2) * e2 - n * rng.uniform(*standoff)
            # viewing direction towards the plane (+n), tilted, spun
            tilt = np.radians(rng.uniform(0, tilt_deg))
            az = rng.uniform(0, 2 * np.pi)
            v = np.cos(tilt) * n + np.sin(tilt) * (np.cos(az) * e1 + np.sin(az) * e2)
            w = np.cross(v, rng.standard_normal(3))
            w /= np.linalg.norm(w)
            R_s = np.zeros((3, 3))
            R_s[:, view] = v
            R_s[:, axes[0]] = w
            c3 = 3 - view - axes[0]
            R_s[:, c3] = np.cross(R_s[:, (c3 + 1) % 3], R_s[:, (c3 + 2) % 3])
            T_s = make_pose(R_s, o)
            if occlusion:
                P_s, L = scan_planes(T_s, planes, rays)
            else:
                P_s, L = scan_planes(T_s, planes[j:j + 1], rays)
                L = np.where(L >= 0, j, -1)
            ok = L >= 0
            if ok.sum() < min(3, n_rays):
                continue
            noisy = P_s[ok].copy()
            for a in axes:
                noisy[:, a] += noise * rng.standard_normal(ok.sum())
            poses.append(T_s @ inv_pose(T_true))
            pts.append(noisy)
            idx.append(np.full(ok.sum(), len(poses) - 1))
            labs.append(L[ok])
            got += 1
    return LaserProblem(np.array(poses), np.concatenate(pts), np.concatenate(idx), np.concatenate(labs), T_true,
                        planes)


def cell_planes(rng, n_planes: int = 4, n_near_parallel: int = 1, max_angle_deg: float = 15.0,
                min_offset: float = 0.05, distance=(0.6, 1.0)) -> np.ndarray:
    """Planes of a robot cell: ``n_planes`` - ``n_near_parallel`` (nearly) orthogonal ones plus
    ``n_near_parallel`` planes within ``max_angle_deg`` of parallel to one of them, whose offset differs
    from that plane's by at least ``min_offset`` [m] (a step, two walls facing the same way)."""
    rng = np.random.default_rng(rng)
    base = list(orthogonal_planes(rng, 3, distance))
    cos_min = np.cos(np.radians(max_angle_deg))
    while len(base) < n_planes - n_near_parallel:   # further planes: not within max_angle of any other
        v = rng.standard_normal(3)
        v /= np.linalg.norm(v)
        if all(abs(v @ b[:3]) < cos_min for b in base):
            base.append(np.r_[v, rng.uniform(*distance)])
    base = np.array(base)
    extra = []
    for k in range(n_near_parallel):
        n0, d0 = base[k % len(base), :3], base[k % len(base), 3]
        axis = np.cross(n0, rng.standard_normal(3))
        axis /= np.linalg.norm(axis)
        from drake_est.calibration.so3 import exp_so3

        n = exp_so3(axis * np.radians(rng.uniform(0.0, max_angle_deg))) @ n0
        off = rng.uniform(min_offset, 2 * min_offset + 0.1) * rng.choice([-1.0, 1.0])
        extra.append(np.r_[n, d0 + off])
    return np.vstack([base] + ([np.array(extra)] if extra else []))


def random_ft_poses(rng, n: int = 100) -> np.ndarray:
    """Random flange poses with uniformly distributed orientations (Sec. 13.1 simulation)."""
    rng = np.random.default_rng(rng)
    return np.stack([make_pose(random_rotation(rng), rng.uniform(-0.5, 0.5, 3) + [0.5, 0, 0.5]) for _ in range(n)])
