"""Loader for the 2-D laser line-scanner data set (``linescanner/`` in the shared data folder).

Source: GilbertPan97/RobCalibrator, data/ScanData (MIT).  ``board/N_3C_line.yml``: one profile of 2048
points (x, 0, z) [mm] in sensor coordinates, NaN where invalid, scanning a flat board with grooves;
``board/rob2board.txt``: one robot pose per profile, x y z [mm] and three angles [deg] whose convention
is not documented (:func:`pose_matrices` builds the candidates, the case study picks one from the data).

Units returned: metres and radians.  The profile of file ``N_3C_line.yml`` belongs to row N of the
pose file (checked in the case study: this order gives the flattest board).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from drake_est.datasets.paths import data_file
from drake_est.errors import DataError

# Euler-angle conventions tried for the robot poses: name -> (axes, intrinsic?)
CONVENTIONS = {
    "rpy_xyz_fixed": "R = Rz(c) Ry(b) Rx(a) (fixed-axis x-y-z, roll-pitch-yaw; Fanuc W P R)",
    "zyx_abc": "R = Rz(a) Ry(b) Rx(c) (KUKA A B C)",
    "xyz_intrinsic": "R = Rx(a) Ry(b) Rz(c)",
    "zyz": "R = Rz(a) Ry(b) Rz(c)",
}


def _R(axis, ang):
    c, s = np.cos(ang), np.sin(ang)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def euler_to_matrix(angles_rad, convention: str) -> np.ndarray:
    a, b, c = angles_rad
    if convention == "rpy_xyz_fixed":
        return _R("z", c) @ _R("y", b) @ _R("x", a)
    if convention == "zyx_abc":
        return _R("z", a) @ _R("y", b) @ _R("x", c)
    if convention == "xyz_intrinsic":
        return _R("x", a) @ _R("y", b) @ _R("z", c)
    if convention == "zyz":
        return _R("z", a) @ _R("y", b) @ _R("z", c)
    raise DataError(f"unknown angle convention {convention!r}; choose one of {sorted(CONVENTIONS)}")


def parse_scan_yaml(path) -> np.ndarray:
    """(n, 3) points of an OpenCV-YAML ``scan_line`` list (NaN kept)."""
    txt = Path(path).read_text()
    if "scan_line" not in txt:
        raise DataError(f"{path}: no 'scan_line' entry")
    body = txt[txt.index("scan_line"):]
    try:
        body = body[body.index("[") + 1: body.index("]")]
    except ValueError:
        raise DataError(f"{path}: malformed scan_line list") from None
    vals = []
    for v in body.replace("\n", " ").split(","):
        v = v.strip()
        if not v:
            continue
        vals.append(float("nan") if v.lower() in (".nan", "nan") else float(v))
    if len(vals) % 3:
        raise DataError(f"{path}: scan_line has {len(vals)} numbers, not a multiple of 3")
    return np.array(vals).reshape(-1, 3)


@dataclass
class LineScannerData:
    profiles: list            # list of (n_i, 3) arrays [m], sensor coordinates (x, 0, z), NaN removed
    raw_poses: np.ndarray     # (M, 6): x y z [m], three angles [rad] as logged
    files: list
    n_invalid: list           # NaN points removed per profile

    def pose_matrices(self, convention: str = "rpy_xyz_fixed") -> np.ndarray:
        """(M, 4, 4) flange poses T_RB^TF under an angle convention (see ``CONVENTIONS``)."""
        P = np.tile(np.eye(4), (len(self.raw_poses), 1, 1))
        for i, r in enumerate(self.raw_poses):
            P[i, :3, :3] = euler_to_matrix(r[3:], convention)
            P[i, :3, 3] = r[:3]
        return P

    def stacked(self):
        """(points (N, 3), pose_index (N,)) over all profiles."""
        pts = np.concatenate(self.profiles)
        idx = np.concatenate([np.full(len(p), i) for i, p in enumerate(self.profiles)])
        return pts, idx


def _load_scans(pose_file) -> LineScannerData:
    """Poses (x y z mm, 3 angles deg per row) and the ``N_3C_line.yml`` profiles beside them, in SI units;
    invalid (NaN) profile points are dropped and counted per profile."""
    raw = np.loadtxt(pose_file, ndmin=2)
    if raw.shape[1] != 6:
        raise DataError(f"{pose_file}: expected 6 columns (x y z mm, 3 angles deg), got {raw.shape[1]}")
    folder = pose_file.parent
    files = sorted(folder.glob("*_3C_line.yml"), key=lambda f: int(f.name.split("_")[0]))
    if len(files) != len(raw):
        raise DataError(f"{folder}: {len(files)} profiles but {len(raw)} poses")
    profiles, n_bad = [], []
    for f in files:
        p = parse_scan_yaml(f)
        ok = np.all(np.isfinite(p), axis=1)
        n_bad.append(int((~ok).sum()))
        profiles.append(p[ok] * 1e-3)
    raw_si = np.column_stack([raw[:, :3] * 1e-3, np.radians(raw[:, 3:])])
    return LineScannerData(profiles, raw_si, [f.name for f in files], n_bad)


def load_board(path=None) -> LineScannerData:
    """The flat-board profiles and robot poses (``linescanner/board``)."""
    return _load_scans(data_file("linescanner/board/rob2board.txt", path))


def load_ball(path=None) -> LineScannerData:
    """The sphere profiles and poses (``linescanner/ball``), same layout."""
    return _load_scans(data_file("linescanner/ball/robpose.txt", path))


def surface_points(profile, threshold: float = 0.4e-3, n_trials: int = 300, seed: int = 0):
    """Boolean mask of the points on the main (top) surface of a grooved-board profile.

    2-D RANSAC line fit in the (x, z) sensor coordinates; groove bottoms, walls and stray points lie
    more than ``threshold`` [m] from it.  Returns (mask, line residual RMS [m]).
    """
    rng = np.random.default_rng(seed)
    xz = profile[:, [0, 2]]
    best, best_n = None, -1
    for _ in range(n_trials):
        i, j = rng.choice(len(xz), 2, replace=False)
        d = xz[j] - xz[i]
        nd = np.hypot(*d)
        if nd < 1e-3:
            continue
        nrm = np.array([-d[1], d[0]]) / nd
        m = np.abs((xz - xz[i]) @ nrm) < threshold
        if m.sum() > best_n:
            best, best_n = m, m.sum()
    # refine with a least-squares line on the inliers
    c = xz[best].mean(axis=0)
    _, _, Vt = np.linalg.svd(xz[best] - c, full_matrices=False)
    r = (xz - c) @ Vt[-1]
    mask = np.abs(r) < threshold
    return mask, float(np.sqrt(np.mean(r[mask] ** 2)))
