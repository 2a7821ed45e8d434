"""Laser-scanner calibration from scans of a few flat surfaces (thesis Sec. 13.2, App. 13.B-13.D).

Notation: ``poses[i] = T_RB^TF_i`` (flange in robot base, 4x4, metres), ``T = T_TF^S`` (sensor in
flange), points ``p_S`` in sensor coordinates.  A point in the robot base frame is (13.13)

    p_RB = T_RB^TF_i T_TF^S p_S .

The iterative two-step method alternates
1. planes: transform all points with the current T, fit each plane by PCA (13.14)-(13.15);
2. transform: with the planes fixed, the plane equations n^T p_RB = d are linear in the identifiable
   columns of T (13.20)-(13.24); solve by LS (or TLS, 13.B), complete/orthogonalize the rotation by
   projection onto SO(3) (13.25, 6.1), re-estimate the translation (13.27)-(13.28).
Optionally a final nonlinear refinement of the point-to-plane distances (13.29) follows.

Sensor kinds (which columns of R_TF^S are identifiable):
* ``"2d"`` laser stripe / 2-D line scanner: points lie in a coordinate plane of the sensor (one
  coordinate identically zero); the missing column follows from the cross product (13.25);
* ``"3d"`` 3-D scanner / LIDAR (13.D): all three columns;
* ``"point"`` point laser (13.C): points on the sensor x axis; only the beam direction (first column)
  and origin are identifiable, the other two columns of the returned T are an arbitrary completion.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drake_est.calibration.assignment import assign_scans_to_planes, fit_plane  # noqa: F401 (fit_plane: public here too)
from drake_est.calibration.linalg import lstsq, tls
from drake_est.calibration.so3 import as_matrix, as_pose_stack, exp_se3, project_to_so3, rotation_error
from drake_est.errors import DataError, IdentifiabilityError


@dataclass
class LaserCalibration:
    """Result of :func:`calibrate_laser`."""

    T: np.ndarray                      # T_TF^S, 4x4 [m]
    planes: np.ndarray                 # (K, 4): unit normal n and distance d, n^T p = d, base frame
    labels: np.ndarray                 # (N,) plane index per point (-1: not used)
    residuals: np.ndarray              # (N,) signed point-to-plane distances [m] (NaN for unused)
    kind: str
    axes: tuple
    history_T: list = field(default_factory=list)     # estimate after each iteration
    history_rms: list = field(default_factory=list)   # RMS point-to-plane distance per iteration [m]
    history_plane_rms: list = field(default_factory=list)  # (K,) per-plane RMS per iteration [m]
    condition: float = float("nan")    # condition number of the column-scaled regressor (13.23)
    weak_direction: np.ndarray | None = None  # parameter combination least determined
    weak_parameter: str = ""
    n_excluded: int = 0
    iterations: int = 0

    @property
    def rms(self) -> float:
        r = self.residuals[np.isfinite(self.residuals)]
        return float(np.sqrt(np.mean(r**2)))

    def points_in_base(self, poses, points, pose_index) -> np.ndarray:
        return transform_points(as_pose_stack(poses), self.T, np.asarray(points, float), np.asarray(pose_index))

    def summary(self) -> dict:
        return {
            "kind": self.kind,
            "T_TF_S": self.T.tolist(),
            "rms_m": self.rms,
            "iterations": self.iterations,
            "n_planes": int(len(self.planes)),
            "condition_number": float(self.condition),
            "weak_parameter": self.weak_parameter,
            "n_points_excluded": int(self.n_excluded),
        }


def transform_points(poses, T, points, pose_index) -> np.ndarray:
    """Points (N, 3) in sensor coordinates -> robot base frame (13.13)."""
    Tf = poses[pose_index]  # (N, 4, 4)
    ps = points @ T[:3, :3].T + T[:3, 3]
    return np.einsum("nij,nj->ni", Tf[:, :3, :3], ps) + Tf[:, :3, 3]


def detect_kind(points, tol: float = 1e-12):
    """Which sensor coordinates carry information: ('2d', (a, b)), ('3d', (0, 1, 2)) or ('point', (0,))."""
    zero = [bool(np.all(np.abs(points[:, j]) <= tol)) for j in range(3)]
    if sum(zero) == 0:
        return "3d", (0, 1, 2)
    if sum(zero) == 1:
        return "2d", tuple(j for j in range(3) if not zero[j])
    if zero == [False, True, True]:
        return "point", (0,)
    raise DataError("laser points must vary in at least two sensor coordinates (2-D scanner), all three "
                    "(3-D scanner), or lie on the sensor x axis (point laser)")


_NAMES = ["R[:,0]x", "R[:,0]y", "R[:,0]z", "R[:,1]x", "R[:,1]y", "R[:,1]z", "R[:,2]x", "R[:,2]y", "R[:,2]z"]


def _regressor(poses, points, pose_index, planes, labels, axes):
    """Stack A k = Y of (13.20)-(13.23) for the identifiable columns ``axes`` of R and p."""
    n = planes[labels, :3]                     # (N, 3)
    d = planes[labels, 3]
    Rf = poses[pose_index, :3, :3]
    pf = poses[pose_index, :3, 3]
    nR = np.einsum("ni,nij->nj", n, Rf)        # n^T R_RB^TF  (N, 3)
    cols = [points[:, [a]] * nR for a in axes] + [nR]
    A = np.concatenate(cols, axis=1)
    Y = d - np.einsum("ni,ni->n", n, pf)       # ||n|| - q  with a unit normal and distance d
    return A, Y


def _complete_rotation(cols: dict, axes) -> np.ndarray:
    """Rotation from the estimated columns: cross product for the missing one (13.25), SO(3) projection."""
    M = np.zeros((3, 3))
    for a, c in cols.items():
        M[:, a] = c
    if len(axes) == 2:
        a, b = axes
        c = 3 - a - b
        # right-handed: e_c = e_a x e_b when (a, b, c) is a cyclic order of (0, 1, 2)
        if (a, b, c) in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
            M[:, c] = np.cross(M[:, a], M[:, b])
        else:
            M[:, c] = np.cross(M[:, b], M[:, a])
        return project_to_so3(M)
    if len(axes) == 3:
        return project_to_so3(M)
    # point laser: normalize the beam direction, complete with an arbitrary orthonormal pair
    u = M[:, 0] / np.linalg.norm(M[:, 0])
    h = np.array([0.0, 0.0, 1.0]) if abs(u[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    v = np.cross(h, u)
    v /= np.linalg.norm(v)
    return np.column_stack([u, v, np.cross(u, v)])


def solve_transform(poses, points, pose_index, planes, labels, axes, method: str = "ls",
                    joint_offsets: bool = True):
    """One 'solve for T_TF^S' step: (13.20)-(13.28). Returns (T, A, Y).

    With ``joint_offsets`` the plane distances d_j are unknowns of the same linear problem (only the
    normals are held fixed), which removes the slow trade-off between the sensor translation and
    the plane offsets that the pure alternation has; ``False`` gives the thesis' literal step.
    """
    A, Y = _regressor(poses, points, pose_index, planes, labels, axes)
    na = len(axes)
    if joint_offsets:
        K = len(planes)
        D = np.zeros((len(Y), K))
        D[np.arange(len(Y)), labels] = -1.0
        AD = np.column_stack([A, D])
        YD = Y - planes[labels, 3]  # right-hand side without the offsets: -n^T p_f
        if method == "ls":
            kd, _ = lstsq(AD, YD)
        elif method == "tls":
            kd = tls(AD, YD, exact_cols=list(range(A.shape[1], A.shape[1] + K)))
        else:
            raise DataError(f"unknown solver {method!r}; use 'ls' or 'tls'")
        k = kd[:A.shape[1]]
        planes = planes.copy()
        planes[:, 3] = kd[A.shape[1]:]
        A, Y = _regressor(poses, points, pose_index, planes, labels, axes)
    elif method == "ls":
        k, _ = lstsq(A, Y)
    elif method == "tls":
        k = tls(A, Y)
    else:
        raise DataError(f"unknown solver {method!r}; use 'ls' or 'tls'")
    cols = {a: k[3 * i:3 * i + 3] for i, a in enumerate(axes)}
    R = _complete_rotation(cols, axes)
    # (13.27)-(13.28): translation given the orthonormal rotation
    Ytil = Y - A[:, :3 * na] @ np.concatenate([R[:, a] for a in axes])
    p, _ = lstsq(A[:, 3 * na:], Ytil)
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p
    return T, A, Y


def _fit_planes(P_rb, labels, K):
    planes = np.zeros((K, 4))
    for j in range(K):
        n, d, _ = fit_plane(P_rb[labels == j])
        planes[j, :3], planes[j, 3] = n, d
    return planes


def _validate(poses, points, pose_index, labels, min_planes, min_points):
    P = as_pose_stack(poses)
    if not np.all(np.isfinite(P)):
        i = int(np.flatnonzero(~np.all(np.isfinite(P.reshape(len(P), -1)), axis=1))[0])
        raise DataError(f"pose {i} contains NaN/inf; remove it (and its points)")
    try:
        pts = np.asarray(points, dtype=float)
    except (TypeError, ValueError):
        raise DataError("laser points must be numeric, shape (N, 3)") from None
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise DataError(f"laser points must have shape (N, 3) (or (N, 2) in the laser plane), got {pts.shape}")
    if pts.shape[1] == 2:
        pts = np.column_stack([pts, np.zeros(len(pts))])
    idx = np.asarray(pose_index)
    if idx.shape != (len(pts),) or not np.issubdtype(idx.dtype, np.integer):
        raise DataError(f"pose_index must be an integer array with one entry per point ({len(pts)}), got "
                        f"shape {idx.shape}")
    if len(pts) and (idx.min() < 0 or idx.max() >= len(P)):
        raise DataError(f"pose_index refers to pose {int(idx.max())} but only {len(P)} poses were given")
    good = np.all(np.isfinite(pts), axis=1)
    if len(pts) < min_points:
        raise IdentifiabilityError(f"laser calibration needs at least {min_points} points (got {len(pts)}); "
                                   "collect scans of 3 non-parallel planes from several poses each")
    lab = None
    if labels is not None:
        lab = np.asarray(labels)
        if lab.shape != (len(pts),):
            raise DataError(f"plane labels must have one entry per point ({len(pts)}), got shape {lab.shape}")
    return P, pts, idx, lab, good


def _plane_checks(P_rb, labels, K, min_planes, idx, kind="2d"):
    if K < min_planes:
        raise IdentifiabilityError(
            f"laser calibration needs scans of at least {min_planes} non-parallel planes (got {K}); "
            "scan more flat surfaces (e.g. a table and two walls) from several poses each")
    normals = []
    for j in range(K):
        m = labels == j
        if m.sum() < 3 or len(np.unique(idx[m])) < (1 if kind == "3d" else 2):
            raise IdentifiabilityError(
                f"plane {j} has {int(m.sum())} points from {len(np.unique(idx[m]))} pose(s); scan each plane "
                "from at least 2 poses with different orientations")
        n, _, s = fit_plane(P_rb[m])
        if s[1] <= 1e-9 * max(s[0], 1e-300):
            raise IdentifiabilityError(f"plane {j}: all points lie on one line; scan it from at least 2 poses "
                                       "with different orientations")
        normals.append(n)


_PARALLEL_CONDITION = 300.0   # column-scaled condition number above which (nearly) parallel planes refuse


def _parallel_check(planes, min_planes, cond=float("inf")):
    """Planes whose normals do not span 3-D leave the translation along the common direction to the
    variation of the flange orientations.  Refuse only when the problem actually solved (its condition
    number ``cond``) is poorly determined as well: parallel planes scanned from strongly varied
    orientations still determine T."""
    Nn = planes[:, :3]
    if min_planes >= 3:
        s = np.linalg.svd(Nn, compute_uv=False)
        if (len(s) < 3 or s[-1] < 0.05 * s[0]) and not cond <= _PARALLEL_CONDITION:
            raise IdentifiabilityError(
                f"the scanned planes are (nearly) parallel or share a common direction and the poses do not "
                f"make up for it (condition number {cond:.3g}), so the translation along it is not determined; "
                "add a plane whose normal is roughly perpendicular to the others")


def _excitation(A):
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    _, s, Vt = np.linalg.svd(A / scale, full_matrices=False)
    cond = float(s[0] / s[-1]) if s[-1] > 0 else float("inf")
    return cond, Vt[-1]


def calibrate_laser(poses, points, pose_index, labels=None, T0=None, n_iter: int = 30, method: str = "ls",
                    refine: bool = False, kind: str | None = None, tol: float = 0.0, min_planes: int = 3,
                    n_planes: int | None = None, assign_threshold: float = 0.02, seed: int = 0,
                    max_condition: float = 1e8, joint_offsets: bool = True) -> LaserCalibration:
    """Calibrate T_TF^S of a wrist-mounted laser scanner by the iterative two-step method (Sec. 13.2).

    Parameters
    ----------
    poses : (M, 4, 4) flange poses T_RB^TF [m] (or RigidTransforms).
    points : (N, 3) points in sensor coordinates [m]; for a 2-D scanner one coordinate is zero
        (points with NaN are excluded and counted).
    pose_index : (N,) index into ``poses`` of the pose each point was measured in.
    labels : (N,) plane label per point, or None to assign points to planes automatically
        (RANSAC over whole scans, re-run with the improved estimate, see ``assignment.py``).
    T0 : initial guess of T_TF^S (identity if None).
    n_iter : number of two-step iterations (the thesis uses 30); ``tol`` > 0 stops early when the
        change in T (Frobenius norm) falls below it.
    method : "ls" (13.24) or "tls" (13.B).
    refine : run the final nonlinear refinement (13.29) afterwards.
    min_planes : require at least this many non-parallel planes (3 in the thesis); lower it only when
        the flange orientations vary enough to excite all directions (the condition number is checked).
    joint_offsets : estimate the plane distances together with T in the linear step (default); with
        False the step is the thesis' literal (13.20)-(13.24) with both normal and distance from PCA,
        which converges much more slowly when the poses look at each plane from similar directions.
    """
    P, pts, idx, lab, good = _validate(poses, points, pose_index, labels, min_planes, 9)
    n_excluded = int((~good).sum())
    pts_all, idx_all = pts, idx
    pts, idx = pts[good], idx[good]
    if len(pts) < 9:
        raise IdentifiabilityError(f"laser calibration needs at least 9 valid points (got {len(pts)})")
    if kind is None:
        kind, axes = detect_kind(pts)
    else:
        axes = {"2d": (0, 1), "3d": (0, 1, 2), "point": (0,)}.get(kind)
        if axes is None:
            raise DataError(f"unknown scanner kind {kind!r}; use '2d', '3d' or 'point'")
        if kind == "2d":
            axes = detect_kind(pts)[1] if detect_kind(pts)[0] == "2d" else (0, 1)
    T = np.eye(4) if T0 is None else as_matrix(T0).copy()
    if not np.all(np.isfinite(T)):
        raise DataError("T0 (initial guess of the sensor transform) contains NaN/inf")
    T[:3, :3] = project_to_so3(T[:3, :3])

    if lab is None:
        result, labels_good = _auto_assign_checked(P, pts, idx, T, n_iter, method, axes, kind, tol, min_planes,
                                                   max_condition, joint_offsets, n_planes, assign_threshold, seed)
    else:
        labs = lab[good]
        uniq = [u for u in np.unique(labs) if not (isinstance(u, (int, np.integer)) and u < 0)]
        labels_good = np.full(len(labs), -1)
        for j, u in enumerate(uniq):
            labels_good[labs == u] = j
        keep = labels_good >= 0
        result = _iterate(P, pts[keep], idx[keep], labels_good[keep], T, n_iter, method, axes, kind, tol,
                          min_planes, max_condition, joint_offsets)
    if refine:
        keep = labels_good >= 0
        result.T = refine_transform(P, pts[keep], idx[keep], labels_good[keep], result.T, axes)
        result.planes = _fit_planes(transform_points(P, result.T, pts[keep], idx[keep]), labels_good[keep],
                                    len(result.planes))
    # residuals for every input point (NaN where excluded)
    lab_full = np.full(len(pts_all), -1)
    lab_full[good] = labels_good
    res = np.full(len(pts_all), np.nan)
    m = lab_full >= 0
    P_rb = transform_points(P, result.T, np.nan_to_num(pts_all), idx_all)
    res[m] = np.einsum("ni,ni->n", P_rb[m], result.planes[lab_full[m], :3]) - result.planes[lab_full[m], 3]
    result.residuals = res
    result.labels = lab_full
    result.n_excluded = int((~m).sum())
    return result


def scan_noise_level(points, pose_index, axes) -> float:
    """Measurement noise [m] estimated inside the scans, independent of T: the median over scans of the
    RMS distance of a scan's points to the line (2-D scanner) or plane (3-D scanner) fitted to them in
    sensor coordinates.  NaN for a point laser (a scan is one point) or when no scan has enough points."""
    pts = np.asarray(points, float)
    idx = np.asarray(pose_index)
    axes = tuple(axes)
    if len(axes) < 2:
        return float("nan")
    dof = 2 if len(axes) == 2 else 3   # line: 2 parameters, plane: 3
    rms = []
    for s in np.unique(idx):
        q = pts[idx == s][:, axes]
        if len(q) < dof + 3:
            continue
        sv = np.linalg.svd(q - q.mean(axis=0), compute_uv=False)
        rms.append(float(sv[-1]) / np.sqrt(len(q) - dof))
    return float(np.median(rms)) if rms else float("nan")


def _plane_rms(result) -> np.ndarray:
    K = len(result.planes)
    return np.array([np.sqrt(np.mean(result.residuals[result.labels == j] ** 2)) for j in range(K)])


def _split_by_offset(P, pts, idx, labels, result, sigma):
    """Split planes whose residual is far above the noise into two by the signed offsets of their scans
    (parallel planes at different offsets merged into one). Returns new labels or None."""
    res = np.einsum("ni,ni->n", transform_points(P, result.T, pts, idx), result.planes[labels, :3]) \
        - result.planes[labels, 3]
    new = labels.copy()
    K = int(labels.max()) + 1
    changed = False
    for j in range(K):
        m = labels == j
        scans = np.unique(idx[m])
        if len(scans) < 4:
            continue
        # per-scan median offsets: robust to a scan that also hits a neighbouring surface at a corner
        off = np.array([np.median(res[m & (idx == s)]) for s in scans])
        if np.sqrt(np.mean((off - np.median(off)) ** 2)) <= 4.0 * sigma:
            continue
        o = np.sort(off)
        gaps = np.diff(o)
        # the largest gap with at least 2 scans on each side
        if len(gaps) < 3:
            continue
        g = 1 + int(np.argmax(gaps[1:-1]))
        cut = 0.5 * (o[g] + o[g + 1])
        hi = scans[off > cut]
        new[m & np.isin(idx, hi)] = K
        K += 1
        changed = True
    return new if changed else None


def _auto_assign(P, pts, idx, T, n_iter, method, axes, kind, tol, min_planes, max_condition, joint_offsets,
                 n_planes, threshold, seed, sigma):
    """Plane assignment by sequential RANSAC over scans, refined with the improving estimate: calibrate,
    split planes whose residual is far above the noise by offset, re-assign with a threshold from the
    residual; repeat until the partition is stable."""
    labels_used = assign_scans_to_planes(transform_points(P, T, pts, idx), idx, threshold=threshold,
                                         n_planes=n_planes, seed=seed)
    result = None
    for _round in range(8):
        keep = labels_used >= 0
        result = _iterate(P, pts[keep], idx[keep], labels_used[keep], T, n_iter, method, axes, kind, tol,
                          min_planes, max_condition, joint_offsets)
        result_labels = labels_used   # the partition this result was computed with
        T = result.T
        if np.isfinite(sigma) and n_planes is None:
            split = _split_by_offset(P, pts[keep], idx[keep], labels_used[keep], result, sigma)
            if split is not None:
                labels_used = labels_used.copy()
                labels_used[keep] = split
                continue
        floor = 4.0 * sigma if np.isfinite(sigma) else 1e-4
        thr = max(5.0 * result.rms, floor, 1e-4)
        new = assign_scans_to_planes(transform_points(P, T, pts, idx), idx, threshold=thr, n_planes=n_planes,
                                     seed=seed)
        if _same_partition(new, labels_used):
            break
        labels_used = new
    return result, result_labels


_RESIDUAL_FACTOR = 1.5   # accepted per-plane RMS / noise level measured inside the scans
_OUTLIER_FRACTION = 0.1  # at most this fraction of a plane's points may lie off it (a scan across a corner)


def _drop_outlier_points(P, pts, idx, res, lab, sigma, T0, n_iter, method, axes, kind, tol, min_planes,
                         max_condition, joint_offsets):
    """Points of an assigned scan lying more than 5 noise levels off its plane (a scan that also hits a
    neighbouring surface) are excluded (counted in ``n_excluded``) and T is re-solved without them; a
    plane with more than 10 % such points is not one plane (message returned instead)."""
    keep = lab >= 0
    r = np.full(len(lab), np.nan)
    P_rb = transform_points(P, res.T, pts[keep], idx[keep])
    r[keep] = np.einsum("ni,ni->n", P_rb, res.planes[lab[keep], :3]) - res.planes[lab[keep], 3]
    out = keep & (np.abs(np.nan_to_num(r)) > 5.0 * sigma)
    if not out.any():
        return res, lab
    for j in range(len(res.planes)):
        m = lab == j
        frac = out[m].mean() if m.any() else 0.0
        if frac > _OUTLIER_FRACTION:
            return (f"plane {j} has {100 * frac:.0f} % of its points more than 5 noise levels "
                    f"({5e3 * sigma:.2g} mm) off it")
    lab = lab.copy()
    lab[out] = -1
    keep = lab >= 0
    res = _iterate(P, pts[keep], idx[keep], lab[keep], res.T, n_iter, method, axes, kind, tol, min_planes,
                   max_condition, joint_offsets)
    return res, lab


def _auto_assign_checked(P, pts, idx, T0, n_iter, method, axes, kind, tol, min_planes, max_condition,
                         joint_offsets, n_planes, threshold, seed):
    """Automatic assignment that checks its own answer.

    Restarts with coarser RANSAC thresholds (x1, x2.5, x5: a far initial guess scatters the scans of one
    plane) and other seeds.  A restart's answer is accepted only when every plane's residual is at the
    noise level measured inside the scans (:func:`scan_noise_level`); accepted answers must agree with
    each other.  Otherwise an IdentifiabilityError asks for labels instead of guessing.
    """
    sigma = scan_noise_level(pts, idx, axes)
    ask = "pass plane labels (one per point) or a closer initial guess T0"
    sols, errors = [], []
    for r, factor in enumerate((1.0, 2.5, 5.0)):
        try:
            res, lab = _auto_assign(P, pts, idx, T0, n_iter, method, axes, kind, tol, min_planes, max_condition,
                                    joint_offsets, n_planes, threshold * factor, seed + 1000 * r, sigma)
        except IdentifiabilityError as e:
            errors.append(str(e).split(";")[0])
            continue
        if np.isfinite(sigma):
            cleaned = _drop_outlier_points(P, pts, idx, res, lab, sigma, T0, n_iter, method, axes, kind, tol,
                                           min_planes, max_condition, joint_offsets)
            if isinstance(cleaned, str):
                errors.append(cleaned)
                continue
            res, lab = cleaned
        prms = _plane_rms(res)
        # at the right answer every plane fits to the noise level (RMS/sigma ~ 1 within a few %, planes
        # hold >= tens of points); a merged or mixed plane, or a wrong local minimum, does not
        if np.isfinite(sigma) and np.max(prms) > max(_RESIDUAL_FACTOR * sigma, 2e-5):
            j = int(np.argmax(prms))
            errors.append(f"plane {j} fits to {prms[j] * 1e3:.3g} mm RMS, noise level {sigma * 1e3:.3g} mm")
            continue
        for other, _ in sols:
            et, er = transform_error(res.T, other.T)
            tol_t = max(3.0 * sigma, 2e-4) if np.isfinite(sigma) else 1e-3
            if et > tol_t or er > np.radians(0.1):
                raise IdentifiabilityError(
                    f"automatic plane assignment is ambiguous (restarts disagree by {et * 1e3:.3g} mm, "
                    f"{np.degrees(er):.3g} deg); {ask}")
        sols.append((res, lab))
        if len(sols) == 2:
            break
    if not sols:
        raise IdentifiabilityError(
            f"automatic plane assignment failed its own check ({errors[0] if errors else 'no solution'}); {ask}")
    res, lab = sols[0]
    # the two-step iteration can stop at different fixed points depending on where the rounds left it;
    # finish at the least-squares optimum (13.29) for the found partition, so the answer does not
    # depend on the path taken
    keep = lab >= 0
    res.T = refine_transform(P, pts[keep], idx[keep], lab[keep], res.T, axes)
    P_rb = transform_points(P, res.T, pts[keep], idx[keep])
    res.planes = _fit_planes(P_rb, lab[keep], len(res.planes))
    return res, lab


def _same_partition(a, b) -> bool:
    if a.shape != b.shape:
        return False
    pairs = set(zip(a.tolist(), b.tolist()))
    return len(pairs) == len(set(a.tolist())) == len(set(b.tolist()))


def _iterate(P, pts, idx, labels, T, n_iter, method, axes, kind, tol, min_planes, max_condition, joint_offsets=True):
    K = int(labels.max()) + 1 if len(labels) else 0
    P_rb = transform_points(P, T, pts, idx)
    _plane_checks(P_rb, labels, K, min_planes, idx, kind)
    hist_T, hist_rms, hist_prms = [T.copy()], [], []
    planes = _fit_planes(P_rb, labels, K)
    r = np.einsum("ni,ni->n", P_rb, planes[labels, :3]) - planes[labels, 3]
    hist_rms.append(float(np.sqrt(np.mean(r**2))))
    hist_prms.append([float(np.sqrt(np.mean(r[labels == j] ** 2))) for j in range(K)])
    cond, weak = float("nan"), None
    it = 0
    for it in range(1, n_iter + 1):
        T_new, A, _ = solve_transform(P, pts, idx, planes, labels, axes, method, joint_offsets)
        if it == 1:
            # judge the problem actually solved: with joint offsets the plane distances are unknowns too
            if joint_offsets:
                D = np.zeros((len(A), K))
                D[np.arange(len(A)), labels] = -1.0
                cond, weak = _excitation(np.column_stack([A, D]))
                weak = weak[:A.shape[1]]
            else:
                cond, weak = _excitation(A)
            if not np.isfinite(cond) or cond > max_condition:
                names = [_NAMES[3 * a + j] for a in axes for j in range(3)] + ["p_x", "p_y", "p_z"]
                worst = names[int(np.argmax(np.abs(weak)))]
                raise IdentifiabilityError(
                    f"the scans do not determine the sensor transform (condition number {cond:.3g}, weakest "
                    f"parameter {worst}); scan the planes from more varied orientations")
        step = float(np.linalg.norm(T_new - T))
        T = T_new
        P_rb = transform_points(P, T, pts, idx)
        planes = _fit_planes(P_rb, labels, K)
        r = np.einsum("ni,ni->n", P_rb, planes[labels, :3]) - planes[labels, 3]
        hist_T.append(T.copy())
        hist_rms.append(float(np.sqrt(np.mean(r**2))))
        hist_prms.append([float(np.sqrt(np.mean(r[labels == j] ** 2))) for j in range(K)])
        if tol > 0 and step < tol:
            break
    _parallel_check(planes, min_planes, cond)
    names = [_NAMES[3 * a + j] for a in axes for j in range(3)] + ["p_x", "p_y", "p_z"]
    weak_name = names[int(np.argmax(np.abs(weak)))] if weak is not None else ""
    return LaserCalibration(T=T, planes=planes, labels=labels, residuals=r, kind=kind, axes=tuple(axes),
                            history_T=hist_T, history_rms=hist_rms, history_plane_rms=hist_prms, condition=cond,
                            weak_direction=weak, weak_parameter=weak_name, iterations=it)


def plane_residuals(P, pts, idx, labels, T):
    """Point-to-plane distances with planes re-fitted by PCA for the given T (variable projection)."""
    P_rb = transform_points(P, T, pts, idx)
    K = int(labels.max()) + 1
    out = np.empty(len(pts))
    for j in range(K):
        m = labels == j
        n, d, _ = fit_plane(P_rb[m])
        out[m] = P_rb[m] @ n - d
    return out


def refine_transform(poses, points, pose_index, labels, T0, axes=(0, 1, 2), max_nfev: int = 200):
    """Nonlinear least squares on the point-to-plane distances (13.29), planes re-fitted for each T.

    Uses ``scipy.optimize.least_squares`` over a local twist parameterization T = T0 exp(xi).
    Also serves as the generic baseline started from a crude guess in the benchmark.
    """
    from scipy.optimize import least_squares

    P = as_pose_stack(poses)
    pts = np.asarray(points, float)
    idx = np.asarray(pose_index)
    labels = np.asarray(labels)
    T0 = as_matrix(T0)

    def fun(xi):
        return plane_residuals(P, pts, idx, labels, T0 @ exp_se3(xi))

    sol = least_squares(fun, np.zeros(6), method="lm", max_nfev=max_nfev * 7, x_scale=np.r_[0.1, 0.1, 0.1, 1, 1, 1])
    return T0 @ exp_se3(sol.x)


def transform_error(T_est, T_true):
    """(translation error [m], rotation error [rad]) between two 4x4 transforms."""
    T_est, T_true = as_matrix(T_est), as_matrix(T_true)
    return float(np.linalg.norm(T_est[:3, 3] - T_true[:3, 3])), rotation_error(T_est[:3, :3], T_true[:3, :3])
