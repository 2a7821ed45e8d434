"""Nominal seams for seam tracking (thesis Ch. 14): the Fig. 14.9 test seams, CSV seams, validation, the
laser-plane / seam intersection of Eq. (14.7) and the trend-filter compression of Eq. (14.8).

A :class:`Seam` is a polyline of points (M, 3) [m] in the robot base frame with a unit surface normal per
point (the normal of the workpiece surface at the seam, used by the surface-angle measurement).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from drake_est.errors import DataError


@dataclass
class Seam:
    """A seam polyline: ``points`` (M, 3) [m] and unit surface ``normals`` (M, 3)."""
    points: np.ndarray
    normals: np.ndarray
    name: str = "seam"

    def __post_init__(self):
        self.points = validate_seam_points(self.points, name=self.name)
        n = np.asarray(self.normals, float)
        if n.shape != self.points.shape:
            raise DataError(f"seam '{self.name}': normals have shape {n.shape}, points {self.points.shape}")
        nn = np.linalg.norm(n, axis=1)
        if not np.all(np.isfinite(n)) or nn.min() < 1e-9:
            raise DataError(f"seam '{self.name}': surface normals must be finite and non-zero")
        self.normals = n / nn[:, None]

    @property
    def tangents(self) -> np.ndarray:
        """Unit tangents (M, 3) by central differences (one-sided at the ends)."""
        t = np.gradient(self.points, axis=0)
        return t / np.linalg.norm(t, axis=1)[:, None]

    def cross_directions(self) -> np.ndarray:
        """Unit cross-seam directions n x t (M, 3): in the surface, perpendicular to the seam."""
        c = np.cross(self.normals, self.tangents)
        return c / np.linalg.norm(c, axis=1)[:, None]

    @property
    def length(self) -> float:
        return float(np.linalg.norm(np.diff(self.points, axis=0), axis=1).sum())


def validate_seam_points(points, name: str = "seam") -> np.ndarray:
    """(M, 3) finite points, M >= 2, no two consecutive points equal; one-line DataError otherwise."""
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise DataError(f"seam '{name}' must be an (M, 3) array of x, y, z points [m], got shape {p.shape}")
    if p.shape[0] < 2:
        raise DataError(f"seam '{name}' needs at least 2 points, got {p.shape[0]}")
    if not np.all(np.isfinite(p)):
        bad = int(np.flatnonzero(~np.isfinite(p).all(axis=1))[0])
        raise DataError(f"seam '{name}' point {bad + 1} contains NaN/Inf")
    step = np.linalg.norm(np.diff(p, axis=0), axis=1)
    dup = np.flatnonzero(step < 1e-9)
    if dup.size:
        raise DataError(f"seam '{name}' has {dup.size} duplicate consecutive point(s), first at point {dup[0] + 2}")
    return p


# ------------------------------------------------------------------------------------------ test seams
def triangle_wave(s, period: float, amplitude: float, smooth: float = 0.15):
    """A triangle wave of ``amplitude`` and ``period`` in s, corners rounded over a fraction ``smooth``."""
    ph = np.mod(np.asarray(s, float) / period, 1.0)
    tri = 4.0 * np.abs(ph - 0.5) - 1.0                          # +1 .. -1 .. +1
    if smooth <= 0:
        return amplitude * tri
    # round the corners by a moving average (a smooth triangle wave, as in Fig. 14.9)
    k = np.linspace(-smooth / 2, smooth / 2, 41)
    ph2 = np.mod(ph[:, None] + k[None, :], 1.0)
    return amplitude * (4.0 * np.abs(ph2 - 0.5) - 1.0).mean(axis=1)


def thesis_seam(kind: str, n_points: int = 401, origin=(0.55, -0.10, 0.30), length: float = 0.20,
                amplitude: float = 0.02) -> Seam:
    """The seams of Fig. 14.9: ``xy`` (200 mm along y, smooth 20 mm triangle wave in x, flat surface with
    normal +z) and ``yz`` (200 mm along y, 20 mm sine in z; the surface contains the seam and the x axis)."""
    o = np.asarray(origin, float)
    s = np.linspace(0.0, length, int(n_points))
    pts = np.zeros((s.size, 3))
    pts[:, 1] = s
    if kind == "xy":
        pts[:, 0] = triangle_wave(s, length / 2, amplitude) - triangle_wave(np.zeros(1), length / 2, amplitude)[0]
        normals = np.tile([0.0, 0.0, 1.0], (s.size, 1))
    elif kind == "yz":
        pts[:, 2] = amplitude * np.sin(2 * np.pi * s / length)
        t = np.gradient(pts, axis=0)
        t /= np.linalg.norm(t, axis=1)[:, None]
        normals = np.cross(np.array([1.0, 0.0, 0.0]), t)         # x x t: in the yz plane, perpendicular to t
    else:
        raise DataError(f"seam must be 'xy', 'yz' or a CSV file, got '{kind}'")
    return Seam(pts + o, normals, name=kind)


def load_seam_csv(path) -> Seam:
    """A seam from a CSV of points: columns x, y, z [m] (a header line is allowed), optionally nx, ny, nz
    (surface normal; default +z)."""
    path = Path(path)
    if not path.is_file():
        raise DataError(f"seam file '{path}' does not exist")
    try:
        a = np.genfromtxt(path, delimiter=",", dtype=float)
    except ValueError as e:
        raise DataError(f"seam file '{path}' is not a numeric CSV: {str(e).splitlines()[0]}") from None
    a = np.atleast_2d(a)
    if a.size and np.isnan(a[0]).all():
        a = a[1:]
    if a.ndim != 2 or a.shape[1] not in (3, 6):
        raise DataError(f"seam file '{path}' must have 3 columns (x, y, z) or 6 (x, y, z, nx, ny, nz), "
                        f"got {a.shape[1] if a.ndim == 2 else a.shape}")
    normals = a[:, 3:6] if a.shape[1] == 6 else np.tile([0.0, 0.0, 1.0], (a.shape[0], 1))
    return Seam(a[:, :3], normals, name=path.name)


# ------------------------------------------------------------------------------ plane intersection
def plane_intersection(points, plane_point, plane_normal):
    """Intersection of the polyline ``points`` (M, 3) with the plane through ``plane_point`` with normal
    ``plane_normal``: the crossing closest to ``plane_point``.

    Returns (p_i (3,), segment index, gamma) or (None, -1, nan) when the plane never meets the seam. This is
    the projection of Eq. (14.7): p_i = p_1 + gamma v with gamma = n^T (m - p_1) / n^T v."""
    s = (np.asarray(points) - plane_point) @ plane_normal
    cross = np.flatnonzero((s[:-1] <= 0) != (s[1:] <= 0))
    if cross.size == 0:
        return None, -1, np.nan
    a, b = points[cross], points[cross + 1]
    g = s[cross] / (s[cross] - s[cross + 1])
    pi = a + g[:, None] * (b - a)
    j = int(np.argmin(np.linalg.norm(pi - plane_point, axis=1)))
    return pi[j], int(cross[j]), float(g[j])


# ------------------------------------------------------------------------------ compression (14.8)
@dataclass
class CompressedSeam:
    """Piecewise-affine approximation of a seam: ``knots`` (K, 3), their surface ``normals`` and the indices
    of the knots in the original points; ``max_error`` [m] is the largest distance of an original point
    from the approximation z of (14.8)."""
    knots: np.ndarray
    normals: np.ndarray
    indices: np.ndarray
    max_error: float


def compress_seam(seam: Seam, eps: float = 2e-4, lam: float | None = None, tol: float = 1e-9) -> CompressedSeam:
    """Compress a seam by the multivariable trend-filtering problem Eq. (14.8), written in Drake's
    ``MathematicalProgram`` and solved by Clarabel:

        minimize ||y - z||_F^2 + lam sum_t sum_j |w_tj|   s.t. ||y - z||_inf <= eps,
                 w_t = z_t - 2 z_{t+1} + z_{t+2}

    Knots are the points where w is non-zero (|w| above a fraction of max |w| and above ``tol``), plus both
    ends; the fraction is the largest that keeps the polyline within 1.5 eps of every point.  ``lam`` defaults to a value that
    makes the l1 term dominate (few knots).  Points in metres."""
    from pydrake.solvers import ClarabelSolver, MathematicalProgram

    y = seam.points
    N = y.shape[0]
    if N < 3:
        return CompressedSeam(y.copy(), seam.normals.copy(), np.arange(N), 0.0)
    if not eps > 0:
        raise DataError(f"eps must be > 0 [m], got {eps}")
    lam = float(lam) if lam is not None else 10.0 * eps
    prog = MathematicalProgram()
    z = prog.NewContinuousVariables(N, 3, "z")
    s = prog.NewContinuousVariables(N - 2, 3, "s")        # s >= |w|
    # ||y - z||_F^2 as a quadratic cost (identity Hessian)
    zf = z.reshape(-1)
    prog.AddQuadraticCost(2.0 * np.eye(3 * N), -2.0 * y.reshape(-1), float((y ** 2).sum()), zf, is_convex=True)
    prog.AddLinearCost(lam * np.ones(3 * (N - 2)), 0.0, s.reshape(-1))
    prog.AddBoundingBoxConstraint((y - eps).reshape(-1), (y + eps).reshape(-1), zf)
    # w = D z with D the second difference; -s <= w <= s
    for j in range(3):
        for t in range(N - 2):
            w = z[t, j] - 2 * z[t + 1, j] + z[t + 2, j]
            prog.AddLinearConstraint(w - s[t, j] <= 0)
            prog.AddLinearConstraint(w + s[t, j] >= 0)
    res = ClarabelSolver().Solve(prog)
    if not res.is_success():
        raise DataError(f"seam compression (14.8) failed: {res.get_solution_result()}")
    zs = res.GetSolution(z)
    w = np.abs(zs[:-2] - 2 * zs[1:-1] + zs[2:]).max(axis=1)
    # an interior-point solution has tiny non-zero w everywhere: a knot is where |w| exceeds a fraction of
    # its largest value; take the largest fraction whose polyline stays within 1.5 eps of every point
    wmax = max(float(w.max()), 1e-300)
    idx = None
    for frac in (0.1, 0.03, 0.01):
        kink = np.flatnonzero(w > max(frac * wmax, tol)) + 1
        cand = np.unique(np.concatenate([[0], kink, [N - 1]]))
        if _polyline_distance(y, zs[cand]) <= 1.5 * eps:
            idx = cand
            break
    dp = _simplify(zs, 0.5 * eps)
    if idx is None or dp.size < idx.size:
        # w is not sparse (a smoothly curved seam: the l1 optimum of (14.8) is not unique and the quadratic
        # term spreads the curvature): choose the knots on z greedily (Douglas-Peucker, tolerance eps/2)
        idx = dp
    knots = zs[idx]
    err = _polyline_distance(y, knots)
    keep = np.concatenate([[True], np.linalg.norm(np.diff(knots, axis=0), axis=1) > 1e-9])
    return CompressedSeam(knots[keep], seam.normals[idx][keep], idx[keep], float(err))


def _simplify(z, tol: float) -> np.ndarray:
    """Douglas-Peucker: indices of a sub-polyline of ``z`` within ``tol`` of every point."""
    keep = np.zeros(len(z), bool)
    keep[[0, -1]] = True
    stack = [(0, len(z) - 1)]
    while stack:
        i, j = stack.pop()
        if j <= i + 1:
            continue
        a, b = z[i], z[j]
        v = b - a
        d = z[i + 1:j] - a
        g = np.clip(d @ v / max(v @ v, 1e-300), 0, 1)
        dist = np.linalg.norm(d - g[:, None] * v, axis=1)
        k = int(np.argmax(dist))
        if dist[k] > tol:
            m = i + 1 + k
            keep[m] = True
            stack += [(i, m), (m, j)]
    return np.flatnonzero(keep)


def _polyline_distance(points, knots) -> float:
    """Largest distance from ``points`` to the polyline through ``knots``."""
    a, b = knots[:-1], knots[1:]
    v = b - a
    vv = np.maximum((v * v).sum(1), 1e-300)
    d = points[:, None, :] - a[None]
    g = np.clip((d * v[None]).sum(-1) / vv[None], 0.0, 1.0)
    dist = np.linalg.norm(d - g[..., None] * v[None], axis=-1).min(axis=1)
    return float(dist.max())
