"""Automatic assignment of laser points to calibration planes (the missing step named in Sec. 13.2).

Sequential RANSAC [Fischler & Bolles, 1981] over whole scans: a 2-D scan of one flat surface is a
line, two non-parallel lines from different poses span a plane hypothesis, and a scan belongs to the
hypothesis when the median distance of its points is below ``threshold``.  For 3-D scanners (one scan
may see several planes) :func:`ransac_planes` works on individual points.
"""
from __future__ import annotations

import numpy as np

from drake_est.errors import IdentifiabilityError


def fit_plane(points):
    """PCA plane fit (13.14)-(13.15): unit normal n, distance d (n^T p = d), singular values."""
    mu = points.mean(axis=0)
    _, s, Vt = np.linalg.svd(points - mu, full_matrices=False)
    n = Vt[-1]
    d = float(n @ mu)
    if d < 0:
        n, d = -n, -d
    return n, d, s


def ransac_planes(points, threshold: float, n_planes: int | None = None, min_inliers: int = 10,
                  n_trials: int = 500, seed: int = 0) -> np.ndarray:
    """Sequential RANSAC plane detection on individual points (N, 3). Returns labels (-1: none)."""
    rng = np.random.default_rng(seed)
    P = np.asarray(points, float)
    labels = np.full(len(P), -1)
    free = np.flatnonzero(np.all(np.isfinite(P), axis=1))
    k = 0
    while len(free) >= max(3, min_inliers) and (n_planes is None or k < n_planes):
        best, best_cost = None, np.inf
        for _ in range(n_trials):
            s = rng.choice(free, 3, replace=False)
            n = np.cross(P[s[1]] - P[s[0]], P[s[2]] - P[s[0]])
            nn = np.linalg.norm(n)
            if nn < 1e-12:
                continue
            n /= nn
            dist = np.abs((P[free] - P[s[0]]) @ n)
            inl = dist < threshold
            cost = np.minimum(dist, threshold).sum()  # MSAC score
            if inl.sum() >= min_inliers and cost < best_cost:
                best, best_cost = free[inl], cost
        if best is None:
            break
        n, d, _ = fit_plane(P[best])
        inl = free[np.abs(P[free] @ n - d) < threshold]
        labels[inl] = k
        free = np.setdiff1d(free, inl)
        k += 1
    return labels


def assign_scans_to_planes(points_base, scan_index, threshold: float, n_planes: int | None = None,
                           min_scans: int = 2, n_trials: int = 300, seed: int = 0) -> np.ndarray:
    """Label each point with a plane index by sequential RANSAC over whole scans.

    ``points_base`` (N, 3) are the points in the robot base frame under the current estimate of the
    sensor transform, ``scan_index`` (N,) the pose/scan each point came from.  Scans not assigned to any
    plane get -1 (and are excluded by the caller, which reports how many).
    """
    rng = np.random.default_rng(seed)
    P = np.asarray(points_base, float)
    sidx = np.asarray(scan_index)
    scans = [np.flatnonzero(sidx == s) for s in np.unique(sidx)]
    scans = [s for s in scans if len(s) >= 2]
    labels = np.full(len(P), -1)
    free = list(range(len(scans)))
    # scans padded into one (S, L, 3) array (NaN padding) so a hypothesis is tested on all scans at once
    L = max((len(s) for s in scans), default=0)
    pad = np.full((len(scans), L, 3), np.nan)
    for i, s in enumerate(scans):
        pad[i, :len(s)] = P[s]
    equal = all(len(s) == L for s in scans)

    def scan_median(n, d, which):
        r = np.abs(pad[which] @ n - d)
        return np.median(r, axis=1) if equal else np.nanmedian(r, axis=1)

    k = 0
    while len(free) >= min_scans and (n_planes is None or k < n_planes):
        best, best_cost = None, np.inf
        for _ in range(n_trials):
            a, b = rng.choice(free, 2, replace=False)
            pts = P[np.concatenate([scans[a], scans[b]])]
            n, d, s = fit_plane(pts)
            if s[1] < 1e-6 * s[0]:
                continue  # two (nearly) collinear scans: no plane hypothesis
            med = scan_median(n, d, free)
            inl = med < threshold
            cost = np.minimum(med, threshold).sum()
            if inl.sum() >= min_scans and cost < best_cost:
                best, best_cost = [f for f, i in zip(free, inl) if i], cost
        if best is None:
            break
        # refit on all inlier scans, re-test
        pts = P[np.concatenate([scans[f] for f in best])]
        n, d, _ = fit_plane(pts)
        med = scan_median(n, d, free)
        best = [f for f, m in zip(free, med) if m < threshold] or best
        for f in best:
            labels[scans[f]] = k
        free = [f for f in free if f not in best]
        k += 1
    if k == 0:
        raise IdentifiabilityError("could not find any plane shared by two scans; pass plane labels or a "
                                   "better initial guess (or a larger assign_threshold)")
    return labels
