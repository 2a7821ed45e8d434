"""SO(3) / SE(3) helpers used by the calibration methods (thesis Sec. 6.1).

All functions work on plain numpy arrays; :func:`as_matrix` accepts Drake's
``RigidTransform`` / ``RotationMatrix`` as well, so poses can be passed either way.
"""
from __future__ import annotations

import numpy as np

from drake_est.errors import DataError


def skew(v) -> np.ndarray:
    """The cross-product matrix <v>, so that ``skew(a) @ b == np.cross(a, b)``."""
    v = np.asarray(v, dtype=float)
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def unskew(S) -> np.ndarray:
    """Inverse of :func:`skew` (uses the skew-symmetric part of S)."""
    S = np.asarray(S, dtype=float)
    return 0.5 * np.array([S[2, 1] - S[1, 2], S[0, 2] - S[2, 0], S[1, 0] - S[0, 1]])


def project_to_so3(M) -> np.ndarray:
    """Closest rotation matrix to M in the Frobenius norm, Eqs. (6.1)-(6.2).

    ``M = U S V^T``, ``R = U diag(1, 1, det(U V^T)) V^T``.
    """
    M = np.asarray(M, dtype=float)
    if M.shape != (3, 3) or not np.all(np.isfinite(M)):
        raise DataError(f"project_to_so3 needs a finite 3x3 matrix, got shape {M.shape}")
    U, _, Vt = np.linalg.svd(M)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt)) or 1.0])
    return U @ D @ Vt


def as_matrix(T) -> np.ndarray:
    """A 4x4 homogeneous matrix from a RigidTransform, a 4x4 or 3x4 array."""
    if hasattr(T, "GetAsMatrix4"):
        return np.asarray(T.GetAsMatrix4(), dtype=float)
    if hasattr(T, "matrix") and callable(T.matrix):  # RotationMatrix
        out = np.eye(4)
        out[:3, :3] = np.asarray(T.matrix())
        return out
    T = np.asarray(T, dtype=float)
    if T.shape == (4, 4):
        return T
    if T.shape == (3, 4):
        out = np.eye(4)
        out[:3] = T
        return out
    raise DataError(f"expected a 4x4 pose (or RigidTransform), got shape {T.shape}")


def as_pose_stack(poses, check_rigid: bool = True, tol: float = 1e-3) -> np.ndarray:
    """(N, 4, 4) array from a list of RigidTransforms / 4x4 arrays or an (N, 4, 4) array.

    With ``check_rigid`` every finite pose must be a rigid transform (rotation block orthonormal with
    determinant +1 within ``tol``, last row [0 0 0 1]); otherwise a DataError names the first bad pose.
    Poses with NaN/inf are left to the caller (which reports them with its own row numbers)."""
    if isinstance(poses, np.ndarray) and poses.ndim == 3:
        if poses.shape[1:] != (4, 4):
            raise DataError(f"poses must have shape (N, 4, 4), got {poses.shape}")
        P = poses.astype(float)
    elif isinstance(poses, np.ndarray) and poses.ndim != 3 and not (poses.ndim == 1 and poses.dtype == object):
        raise DataError(f"poses must have shape (N, 4, 4), got {poses.shape}")
    else:
        P = np.stack([as_matrix(T) for T in poses]) if len(poses) else np.zeros((0, 4, 4))
    if check_rigid and len(P):
        fin = np.all(np.isfinite(P.reshape(len(P), -1)), axis=1)
        R = P[:, :3, :3]
        err = np.abs(np.einsum("nji,njk->nik", R, R) - np.eye(3)).max(axis=(1, 2))
        det = np.linalg.det(np.where(fin[:, None, None], R, np.eye(3)))
        row = np.abs(P[:, 3, :] - [0.0, 0.0, 0.0, 1.0]).max(axis=1)
        bad = fin & ((err > tol) | (det < 0) | (row > tol))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            why = ("its last row is not [0 0 0 1]" if row[i] > tol else "its rotation is a reflection (det -1)"
                   if det[i] < 0 else f"its rotation block is not orthonormal (|R^T R - I| = {err[i]:.2g})")
            raise DataError(f"pose {i} is not a rigid transform: {why} ({int(bad.sum())} bad poses in all)")
    return P


def to_rigid_transform(T):
    """A pydrake ``RigidTransform`` from a 4x4 matrix (rotation re-projected onto SO(3))."""
    from pydrake.math import RigidTransform, RotationMatrix

    T = as_matrix(T)
    return RigidTransform(RotationMatrix(project_to_so3(T[:3, :3])), T[:3, 3])


def make_pose(R=None, p=None) -> np.ndarray:
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    if p is not None:
        T[:3, 3] = p
    return T


def inv_pose(T) -> np.ndarray:
    """Inverse of a rigid transform using R^T (no general matrix inverse)."""
    T = as_matrix(T)
    R, p = T[:3, :3], T[:3, 3]
    return make_pose(R.T, -R.T @ p)


def exp_so3(w) -> np.ndarray:
    """Rodrigues' formula: rotation by angle |w| about w/|w|."""
    w = np.asarray(w, dtype=float)
    th = np.linalg.norm(w)
    K = skew(w)
    if th < 1e-8:
        return np.eye(3) + K + 0.5 * K @ K
    return np.eye(3) + np.sin(th) / th * K + (1 - np.cos(th)) / th**2 * K @ K


def log_so3(R) -> np.ndarray:
    """Rotation vector w with ``exp_so3(w) == R`` (angle in [0, pi])."""
    R = np.asarray(R, dtype=float)
    c = np.clip(0.5 * (np.trace(R) - 1.0), -1.0, 1.0)
    th = np.arccos(c)
    if th < 1e-8:
        return unskew(R)
    if np.pi - th < 1e-6:
        # axis from the symmetric part: R = 2 a a^T - I
        B = 0.5 * (R + np.eye(3))
        i = int(np.argmax(np.diag(B)))
        a = B[:, i] / np.sqrt(max(B[i, i], 1e-300))
        a /= np.linalg.norm(a)
        return th * a
    return th / (2 * np.sin(th)) * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])


def _V(w):
    th = np.linalg.norm(w)
    K = skew(w)
    if th < 1e-8:
        return np.eye(3) + 0.5 * K + K @ K / 6.0
    return np.eye(3) + (1 - np.cos(th)) / th**2 * K + (th - np.sin(th)) / th**3 * K @ K


def exp_se3(xi) -> np.ndarray:
    """4x4 transform from twist coordinates xi = [v, w] (translation part first)."""
    xi = np.asarray(xi, dtype=float)
    v, w = xi[:3], xi[3:]
    return make_pose(exp_so3(w), _V(w) @ v)


def log_se3(T) -> np.ndarray:
    """Twist coordinates [v, w] with ``exp_se3(log_se3(T)) == T``."""
    T = as_matrix(T)
    w = log_so3(T[:3, :3])
    v = np.linalg.solve(_V(w), T[:3, 3])
    return np.concatenate([v, w])


def rotation_angle(R) -> float:
    """Geodesic angle (rad) of a rotation matrix (of R_est^T R_true for an error)."""
    R = np.asarray(R, dtype=float)
    return float(np.arccos(np.clip(0.5 * (np.trace(R) - 1.0), -1.0, 1.0)))


def rotation_error(R_est, R_true) -> float:
    """Angle (rad) between two rotations."""
    return rotation_angle(np.asarray(R_est).T @ np.asarray(R_true))


def rpy_to_matrix(rpy) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll) (Drake's RollPitchYaw convention)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def random_rotation(rng) -> np.ndarray:
    """Uniformly distributed rotation (from a uniform unit quaternion)."""
    q = rng.standard_normal(4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def cayley(s) -> np.ndarray:
    """Cayley transform R = (I + <s>)^{-1} (I - <s>), Eq. (13.6), computed with a solve."""
    S = skew(s)
    return np.linalg.solve(np.eye(3) + S, np.eye(3) - S)
