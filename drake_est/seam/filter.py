"""The seam-tracking particle filter over SE(3) of thesis Sec. 14.1, built on the generic
:class:`drake_est.estimation.pf.ParticleFilter` (this module only supplies its model callables).

State (no velocities, Sec. 14.1): the tool pose X in SE(3), stored per particle as its deviation from the
nominal pose F_k(q_nom) X_FT in the tool frame, xi = [dp (3) [m], dtheta (3) [rad]]:

    X = (R_nom Exp(dtheta),  p_nom + R_nom dp).

With this chart the transition mean of Sec. 14.1, T+ = F_k(q_nom+) F_k(q_nom)^-1 X, is exactly xi+ = xi, so
the transition is xi+ = xi + v with v ~ N(0, diag(s_p(f)^2 I3, s_r(f)^2 I3)), s(f) = s0 + k ||f||: a
covariance that grows with the process force f.

Measurement y (ny = 9 + 4 n_sensors): joint encoders q_m (6) [rad], measured process force f (3) [N], and
per laser stripe [valid (1 or 0), m (2) [m] seam point in the laser plane (sensor x, y), surface angle
[rad]].  Control u (9): the nominal (commanded) joints q_nom (6) [rad] and the force f (3) [N].

* Robot measurement, Eqs. (14.3), (14.5)-(14.6): mean F_k(q_m + C_j(tau)) X_FT, tau = J^T f, C_j a diagonal
  joint compliance; the position part (and, as an extension, the rotation part) has the hybrid
  uniform-Gaussian density with radius d(f) = d0 + k_d ||f||.
* Laser measurement, Eq. (14.7): m_hat = X T_S [m; 0], projected onto the nominal (compressed, Eq. (14.8))
  seam along the particle's laser plane z_S = 0 (p_i = p_1 + gamma v); e = m_hat - p_i ~ N(0, s_l^2 I);
  optionally the surface angle around the plane normal, compared with the particle's hypothesis.

With numba the likelihood, the step's weighting/resampling/prediction (:func:`filter_step`) and the simulated
laser stripes run as compiled loops; ``DRAKE_EST_NO_NUMBA=1`` selects the numpy paths (same numbers, tested to
1e-10).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from drake_est.errors import DataError

try:
    import numba
except ImportError:   # pragma: no cover
    numba = None


from pydrake.multibody.tree import JacobianWrtVariable as _JWV  # noqa: E402

_KV = _JWV.kV


def use_numba() -> bool:
    return numba is not None and not os.environ.get("DRAKE_EST_NO_NUMBA")


# ------------------------------------------------------------------------------------------ geometry
def so3_exp(w):
    """Rotation matrices Exp(w) (Rodrigues) for rotation vectors w (..., 3)."""
    w = np.asarray(w, float)
    if w.shape == (3,):
        th = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
        a, b = (1.0 - th * th / 6, 0.5 - th * th / 24) if th < 1e-8 else (math.sin(th) / th, (1 - math.cos(th)) / th ** 2)
        K = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
        return np.eye(3) + a * K + b * (K @ K)
    th = np.linalg.norm(w, axis=-1)[..., None, None]
    K = np.zeros(w.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -w[..., 2], w[..., 1], -w[..., 0]
    K[..., 1, 0], K[..., 2, 0], K[..., 2, 1] = w[..., 2], -w[..., 1], w[..., 0]
    small = th < 1e-8
    ths = np.where(small, 1.0, th)
    a = np.where(small, 1.0 - th ** 2 / 6, np.sin(ths) / ths)
    b = np.where(small, 0.5 - th ** 2 / 24, (1 - np.cos(ths)) / ths ** 2)
    return np.eye(3) + a * K + b * (K @ K)


def so3_log(R) -> np.ndarray:
    """Rotation vector of a rotation matrix (angle < pi)."""
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = np.asarray(R, float).tolist()
    c = min(max((r00 + r11 + r22 - 1) / 2, -1.0), 1.0)
    th = math.acos(c)
    f = 0.5 if th < 1e-8 else th / (2 * math.sin(th))
    return np.array([f * (r21 - r12), f * (r02 - r20), f * (r10 - r01)])


def sensor_mount(distance: float) -> np.ndarray:
    """Pose T_S (4x4) of a laser sensor in the tool frame: origin ``distance`` [m] ahead of the TCP along the
    tool y axis (travel direction), laser plane z_S = 0 perpendicular to it, x_S along the tool z axis."""
    T = np.eye(4)
    T[:3, 0] = [0.0, 0.0, 1.0]       # x_S = tool z
    T[:3, 1] = [1.0, 0.0, 0.0]       # y_S = tool x
    T[:3, 2] = [0.0, 1.0, 0.0]       # z_S = tool y (plane normal)
    T[:3, 3] = [0.0, float(distance), 0.0]
    return T


def surface_angle(R_WS, normal_W) -> float:
    """The surface angle a laser stripe measures: rotation of the surface line around the laser-plane normal
    z_S, atan2(n_S,y, -n_S,x) with n_S the surface normal in the sensor frame (0 when x_S is anti-parallel to
    the normal)."""
    n = np.asarray(R_WS).T @ np.asarray(normal_W)
    return math.atan2(n[1], -n[0])


def _laser_point(X_WS, knots, normals, out):
    """Loop version of :func:`laser_measurement` for a sensor pose X_WS (compiled by numba): writes
    [m_x, m_y, surface angle] to ``out``; returns False when the laser plane does not meet the seam."""
    K = knots.shape[0]
    sp = 0.0
    best, bi, bg = np.inf, -1, 0.0
    for k in range(K):
        s = ((knots[k, 0] - X_WS[0, 3]) * X_WS[0, 2] + (knots[k, 1] - X_WS[1, 3]) * X_WS[1, 2]
             + (knots[k, 2] - X_WS[2, 3]) * X_WS[2, 2])
        if k > 0 and (sp <= 0) != (s <= 0):
            g = sp / (sp - s)
            dd = 0.0
            for r in range(3):
                e = knots[k - 1, r] + g * (knots[k, r] - knots[k - 1, r]) - X_WS[r, 3]
                dd += e * e
            if dd < best:
                best, bi, bg = dd, k - 1, g
        sp = s
    if bi < 0:
        return False
    m0 = 0.0
    m1 = 0.0
    n0 = 0.0
    n1 = 0.0
    nn = 0.0
    for r in range(3):
        e = knots[bi, r] + bg * (knots[bi + 1, r] - knots[bi, r]) - X_WS[r, 3]
        m0 += X_WS[r, 0] * e
        m1 += X_WS[r, 1] * e
        nr = (1 - bg) * normals[bi, r] + bg * normals[bi + 1, r]
        nn += nr * nr
        n0 += X_WS[r, 0] * nr
        n1 += X_WS[r, 1] * nr
    nn = math.sqrt(nn)
    out[0], out[1], out[2] = m0, m1, math.atan2(n1 / nn, -(n0 / nn))
    return True


_laser_kernel = None


def laser_measurement(X_WT, T_S, knots, normals):
    """What a laser stripe mounted at T_S on a tool at pose X_WT (4x4) measures on the polyline ``knots``:
    (m (2) [m], surface angle [rad]) or None when the laser plane does not meet the seam.  Compiled loop
    (:func:`_laser_point`) unless ``DRAKE_EST_NO_NUMBA=1``."""
    global _laser_kernel
    X_WS = X_WT @ T_S
    if use_numba():
        if _laser_kernel is None:
            _laser_kernel = numba.njit(cache=True)(_laser_point)
        out = np.empty(3)
        if not _laser_kernel(X_WS, np.ascontiguousarray(knots, dtype=float),
                             np.ascontiguousarray(normals, dtype=float), out):
            return None
        return out[:2], float(out[2])
    R, o = X_WS[:3, :3], X_WS[:3, 3]
    n = R[:, 2]
    s = (knots - o) @ n
    cr = np.flatnonzero((s[:-1] <= 0) != (s[1:] <= 0))
    if cr.size == 0:
        return None
    g = s[cr] / (s[cr] - s[cr + 1])
    pi = knots[cr] + g[:, None] * (knots[cr + 1] - knots[cr])
    j = int(np.argmin(np.linalg.norm(pi - o, axis=1)))
    i, gj = cr[j], g[j]
    m = R.T @ (pi[j] - o)
    nrm = (1 - gj) * normals[i] + gj * normals[i + 1]
    return m[:2], surface_angle(R, nrm / np.linalg.norm(nrm))


# ------------------------------------------------------------------------------------------- config
@dataclass
class SeamFilterConfig:
    """Parameters of the seam-tracking filter (SI units: m, rad, N).

    sensor_distances: distances [m] of the laser stripes ahead of the TCP (0, 1 or 2 entries).
    sigma_laser [m], sigma_angle [rad], use_angle: laser noise and whether the surface angle is used.
    d0, k_d [m/N], sigma_robot [m]: robot position density (14.6), d(f) = d0 + k_d ||f||.
    d0_rot [rad], k_d_rot [rad/N], sigma_robot_rot [rad]: the same for the orientation.
    sigma_p0 [m], k_p [m/N], sigma_r0 [rad], k_r [rad/N]: transition noise per step, s = s0 + k ||f||.
    init_p [m], init_r [rad]: spread of the initial particles around the nominal pose.
    search_radius [m]: seam segments farther than this from the nominal measurement point are not searched.
    compliance: diagonal joint compliance model C_j [rad/(N m)] (6) or None (no compliance model).
    """
    sensor_distances: tuple = (0.04, 0.08)
    sigma_laser: float = 1e-4
    sigma_angle: float = math.radians(0.3)
    use_angle: bool = True
    d0: float = 5e-4
    k_d: float = 5e-7
    sigma_robot: float = 2e-4
    d0_rot: float = 2e-3
    k_d_rot: float = 1e-6
    sigma_robot_rot: float = 1e-3
    sigma_p0: float = 2e-5
    k_p: float = 2e-8
    sigma_r0: float = 3e-5
    k_r: float = 3e-8
    init_p: float = 1e-3
    init_r: float = 2e-3
    compliance: np.ndarray | None = None
    n_particles: int = 500
    resample_threshold: float = 0.5
    search_radius: float = 0.01

    def __post_init__(self):
        self.sensor_distances = tuple(float(d) for d in self.sensor_distances)
        if len(self.sensor_distances) > 2:
            raise DataError(f"sensor_distances: at most 2 laser stripes are supported, got {len(self.sensor_distances)}")
        for name in ("sigma_laser", "sigma_angle", "sigma_robot", "sigma_robot_rot", "sigma_p0", "sigma_r0",
                     "init_p", "init_r"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise DataError(f"SeamFilterConfig.{name} must be finite and > 0, got {v}")
        for name in ("d0", "k_d", "d0_rot", "k_d_rot", "k_p", "k_r"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise DataError(f"SeamFilterConfig.{name} must be finite and >= 0, got {v}")


def measurement_size(n_sensors: int) -> int:
    return 9 + 4 * int(n_sensors)


# --------------------------------------------------------------------------------- densities (14.6)
def _hybrid_logD(d: float, sigma: float, k: int) -> float:
    V = math.pi ** (k / 2) / math.gamma(k / 2 + 1) * d ** k
    return -math.log((2 * math.pi) ** (k / 2) * sigma ** k + V)


def hybrid_logpdf(dx, d: float, sigma: float):
    """log of the hybrid uniform-Gaussian density Eq. (14.6) with Sigma = sigma^2 I for rows dx (N, k):
    log D inside the ball ||dx|| <= d, log D - (||dx|| - d)^2 / (2 sigma^2) outside;
    D = 1 / ((2 pi)^(k/2) sigma^k + V(d, k)) -- the thesis' constant, exact for d = 0 or k = 1; for k > 1
    and d > 0 it under-counts the Gaussian shell, which only shifts the log-likelihood by a constant per step
    (the weights are unaffected)."""
    dx = np.asarray(dx, float)
    logD = _hybrid_logD(d, sigma, dx.shape[-1])
    r = np.sqrt((dx * dx).sum(-1))
    out = np.maximum(r - d, 0.0)
    return logD - 0.5 * (out / sigma) ** 2


def _laser_loglik_numpy(x, R_nom, p_nom, T_S, meas, knots, normals, sigma, sigma_ang, use_angle, segments=None):
    """log p(m | X) of Eq. (14.7) for all particles (numpy path); ``segments``: indices of the seam segments
    searched (default all)."""
    R = R_nom @ so3_exp(x[:, 3:])                                 # (N, 3, 3)
    p = p_nom + x[:, :3] @ R_nom.T
    RS = R @ T_S[:3, :3]
    o = p + R @ T_S[:3, 3]
    mh = o + RS[:, :, 0] * meas[0] + RS[:, :, 1] * meas[1]
    n = RS[:, :, 2]
    s = np.einsum("nkd,nd->nk", knots[None, :, :] - mh[:, None, :], n)
    seg = np.arange(knots.shape[0] - 1) if segments is None else np.asarray(segments, np.int64)
    s0, s1 = s[:, seg], s[:, seg + 1]
    cr = (s0 <= 0) != (s1 <= 0)
    den = s0 - s1
    g = np.where(cr, s0 / np.where(cr, den, 1.0), 0.0)
    a = knots[seg]
    v = knots[seg + 1] - knots[seg]
    pi = a[None] + g[..., None] * v[None]
    dist2 = ((pi - mh[:, None, :]) ** 2).sum(-1)
    dist2 = np.where(cr, dist2, np.inf)
    jj = np.argmin(dist2, axis=1)
    e2 = dist2[np.arange(x.shape[0]), jj]
    j = seg[jj]
    ll = -math.log(2 * math.pi * sigma ** 2) - 0.5 * e2 / sigma ** 2
    if use_angle:
        gj = g[np.arange(x.shape[0]), jj]
        nrm = (1 - gj)[:, None] * normals[j] + gj[:, None] * normals[j + 1]
        nS = np.einsum("nji,nj->ni", RS, nrm)
        ang = np.arctan2(nS[:, 1], -nS[:, 0])
        da = np.mod(ang - meas[2] + np.pi, 2 * np.pi) - np.pi
        ll = ll - 0.5 * math.log(2 * math.pi * sigma_ang ** 2) - 0.5 * (da / sigma_ang) ** 2
    return np.where(np.isfinite(e2), ll, -np.inf)


def _candidates_point(R_nom, p_nom, T_S, meas, knots, radius, segs, nseg):
    """Seam segments within ``radius`` of each stripe's nominal measurement point (loop version of
    :meth:`SeamTrackingModel.candidate_segments`; all segments when none is that close)."""
    K = knots.shape[0] - 1
    for s in range(T_S.shape[0]):
        mh = np.empty(3)
        for r in range(3):
            acc = p_nom[r]
            for c in range(3):
                RSc0 = R_nom[r, 0] * T_S[s, 0, 0] + R_nom[r, 1] * T_S[s, 1, 0] + R_nom[r, 2] * T_S[s, 2, 0]
                RSc1 = R_nom[r, 0] * T_S[s, 0, 1] + R_nom[r, 1] * T_S[s, 1, 1] + R_nom[r, 2] * T_S[s, 2, 1]
                if c == 0:
                    acc += RSc0 * meas[s, 0] + RSc1 * meas[s, 1]
                acc += R_nom[r, c] * T_S[s, c, 3]
            mh[r] = acc
        n = 0
        for k in range(K):
            vv = 0.0
            dv = 0.0
            for r in range(3):
                v = knots[k + 1, r] - knots[k, r]
                vv += v * v
                dv += (mh[r] - knots[k, r]) * v
            g = min(max(dv / max(vv, 1e-300), 0.0), 1.0)
            dd = 0.0
            for r in range(3):
                e = knots[k, r] + g * (knots[k + 1, r] - knots[k, r]) - mh[r]
                dd += e * e
            if math.sqrt(dd) < radius:
                segs[s, n] = k
                n += 1
        if n == 0:
            for k in range(K):
                segs[s, k] = k
            n = K
        nseg[s] = n


def _seam_loglik_point(x, R_nom, p_nom, dp_r, dth_r, rob, T_S, meas, valid, radius, knots, normals,
                       sigma, sigma_ang, use_angle, out):
    """Per-particle loop of the whole measurement log-likelihood (robot density (14.6) for position and
    orientation + every valid laser stripe (14.7)); compiled by numba.  Same numbers as the numpy path."""
    N = x.shape[0]
    S = T_S.shape[0]
    segs = np.zeros((S, max(1, knots.shape[0] - 1)), np.int64)
    nseg = np.zeros(S, np.int64)
    _cand(R_nom, p_nom, T_S, meas, knots, radius, segs, nseg)
    c0 = -math.log(2 * math.pi * sigma * sigma)
    c1 = -0.5 * math.log(2 * math.pi * sigma_ang * sigma_ang)
    ca = np.empty(S)
    sa = np.empty(S)
    for s in range(S):
        ca[s] = math.cos(meas[s, 2])
        sa[s] = math.sin(meas[s, 2])
    Rl = np.empty((3, 3))
    R = np.empty((3, 3))
    RS = np.empty((3, 3))
    for i in range(N):
        # robot measurement, hybrid density (14.6) on position and rotation deviations
        e0, e1, e2 = x[i, 0] - dp_r[0], x[i, 1] - dp_r[1], x[i, 2] - dp_r[2]
        r = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        o = max(r - rob[0], 0.0) / rob[1]
        ll = rob[2] - 0.5 * o * o
        e0, e1, e2 = x[i, 3] - dth_r[0], x[i, 4] - dth_r[1], x[i, 5] - dth_r[2]
        r = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        o = max(r - rob[3], 0.0) / rob[4]
        ll += rob[5] - 0.5 * o * o
        if S == 0:
            out[i] = ll
            continue
        w0, w1, w2 = x[i, 3], x[i, 4], x[i, 5]
        th2 = w0 * w0 + w1 * w1 + w2 * w2
        th = math.sqrt(th2)
        if th < 1e-8:
            a = 1.0 - th2 / 6
            b = 0.5 - th2 / 24
        else:
            a = math.sin(th) / th
            b = (1 - math.cos(th)) / th2
        # Exp(w) = I + a K + b K^2
        Rl[0, 0] = 1 + b * (-w2 * w2 - w1 * w1)
        Rl[0, 1] = -a * w2 + b * (w0 * w1)
        Rl[0, 2] = a * w1 + b * (w0 * w2)
        Rl[1, 0] = a * w2 + b * (w0 * w1)
        Rl[1, 1] = 1 + b * (-w2 * w2 - w0 * w0)
        Rl[1, 2] = -a * w0 + b * (w1 * w2)
        Rl[2, 0] = -a * w1 + b * (w0 * w2)
        Rl[2, 1] = a * w0 + b * (w1 * w2)
        Rl[2, 2] = 1 + b * (-w1 * w1 - w0 * w0)
        for rr in range(3):
            for cc in range(3):
                R[rr, cc] = R_nom[rr, 0] * Rl[0, cc] + R_nom[rr, 1] * Rl[1, cc] + R_nom[rr, 2] * Rl[2, cc]
        px = p_nom[0] + R_nom[0, 0] * x[i, 0] + R_nom[0, 1] * x[i, 1] + R_nom[0, 2] * x[i, 2]
        py = p_nom[1] + R_nom[1, 0] * x[i, 0] + R_nom[1, 1] * x[i, 1] + R_nom[1, 2] * x[i, 2]
        pz = p_nom[2] + R_nom[2, 0] * x[i, 0] + R_nom[2, 1] * x[i, 1] + R_nom[2, 2] * x[i, 2]
        for s in range(S):
            if valid[s] == 0:
                continue
            for rr in range(3):
                for cc in range(3):
                    RS[rr, cc] = R[rr, 0] * T_S[s, 0, cc] + R[rr, 1] * T_S[s, 1, cc] + R[rr, 2] * T_S[s, 2, cc]
            mh0 = px + R[0, 0] * T_S[s, 0, 3] + R[0, 1] * T_S[s, 1, 3] + R[0, 2] * T_S[s, 2, 3]
            mh1 = py + R[1, 0] * T_S[s, 0, 3] + R[1, 1] * T_S[s, 1, 3] + R[1, 2] * T_S[s, 2, 3]
            mh2 = pz + R[2, 0] * T_S[s, 0, 3] + R[2, 1] * T_S[s, 1, 3] + R[2, 2] * T_S[s, 2, 3]
            mh0 += RS[0, 0] * meas[s, 0] + RS[0, 1] * meas[s, 1]
            mh1 += RS[1, 0] * meas[s, 0] + RS[1, 1] * meas[s, 1]
            mh2 += RS[2, 0] * meas[s, 0] + RS[2, 1] * meas[s, 1]
            n0, n1, n2 = RS[0, 2], RS[1, 2], RS[2, 2]
            best = np.inf
            bj = -1
            bg = 0.0
            for kk in range(nseg[s]):
                k = segs[s, kk]
                sp = (knots[k, 0] - mh0) * n0 + (knots[k, 1] - mh1) * n1 + (knots[k, 2] - mh2) * n2
                sn = (knots[k + 1, 0] - mh0) * n0 + (knots[k + 1, 1] - mh1) * n1 + (knots[k + 1, 2] - mh2) * n2
                if (sp <= 0) != (sn <= 0):
                    g = sp / (sp - sn)
                    d0 = knots[k, 0] + g * (knots[k + 1, 0] - knots[k, 0]) - mh0
                    d1 = knots[k, 1] + g * (knots[k + 1, 1] - knots[k, 1]) - mh1
                    d2 = knots[k, 2] + g * (knots[k + 1, 2] - knots[k, 2]) - mh2
                    dd = d0 * d0 + d1 * d1 + d2 * d2
                    if dd < best:
                        best = dd
                        bj = k
                        bg = g
            if bj < 0:
                ll = -np.inf
                break
            ll += c0 - 0.5 * best / (sigma * sigma)
            if use_angle:
                m0 = (1 - bg) * normals[bj, 0] + bg * normals[bj + 1, 0]
                m1 = (1 - bg) * normals[bj, 1] + bg * normals[bj + 1, 1]
                m2 = (1 - bg) * normals[bj, 2] + bg * normals[bj + 1, 2]
                nS0 = RS[0, 0] * m0 + RS[1, 0] * m1 + RS[2, 0] * m2
                nS1 = RS[0, 1] * m0 + RS[1, 1] * m1 + RS[2, 1] * m2
                # wrapped difference atan2(nS1, -nS0) - angle as one atan2 of the rotated vector
                da = math.atan2(nS1 * ca[s] + nS0 * sa[s], nS1 * sa[s] - nS0 * ca[s])
                ll += c1 - 0.5 * (da / sigma_ang) ** 2
        out[i] = ll


_kernel = None
# the compiled kernel calls the compiled candidate search (numba resolves this global at compile time)
_cand = numba.njit(cache=True)(_candidates_point) if numba is not None else _candidates_point


def candidate_segments(X_WS, m, knots, radius) -> np.ndarray:
    """Seam segments within ``radius`` [m] of the nominal measurement point X_WS [m; 0] (the search of the
    closest seam points is restricted to them once per step, for all particles); all when none is close."""
    mh = X_WS[:3, 3] + X_WS[:3, 0] * m[0] + X_WS[:3, 1] * m[1]
    a, v = knots[:-1], np.diff(knots, axis=0)
    g = np.clip(((mh - a) * v).sum(1) / np.maximum((v * v).sum(1), 1e-300), 0.0, 1.0)
    dist = np.linalg.norm(a + g[:, None] * v - mh, axis=1)
    cand = np.flatnonzero(dist < radius)
    return cand if cand.size else np.arange(a.shape[0])


def seam_loglik(x, R_nom, p_nom, dp_r, dth_r, rob, T_S, meas, valid, radius, knots, normals, sigma,
                sigma_ang, use_angle, numba_ok=None):
    """The full measurement log-likelihood of every particle: robot density (14.6) (``rob`` = [d, sigma,
    log D, d_rot, sigma_rot, log D_rot]) plus the laser density (14.7) of each valid stripe s (T_S (S, 4, 4),
    meas (S, 3) = [m, angle], valid (S,)), searching the seam segments within ``radius`` of the nominal
    measurement point.  Compiled loop unless ``DRAKE_EST_NO_NUMBA=1`` / ``numba_ok=False``."""
    global _kernel
    if numba_ok is None:
        numba_ok = use_numba()
    if numba_ok:
        if _kernel is None:
            _kernel = numba.njit(cache=True, fastmath=False)(_seam_loglik_point)
        out = np.empty(x.shape[0])
        _kernel(x if (x.dtype == np.float64 and x.flags.c_contiguous) else np.ascontiguousarray(x, dtype=float), R_nom, p_nom, dp_r, dth_r, rob, T_S, meas, valid,
                float(radius), knots, normals, float(sigma), float(sigma_ang), bool(use_angle), out)
        return out
    ll = (rob[2] - 0.5 * (np.maximum(np.linalg.norm(x[:, :3] - dp_r, axis=1) - rob[0], 0.0) / rob[1]) ** 2
          + rob[5] - 0.5 * (np.maximum(np.linalg.norm(x[:, 3:] - dth_r, axis=1) - rob[3], 0.0) / rob[4]) ** 2)
    X_nom = np.eye(4)
    X_nom[:3, :3], X_nom[:3, 3] = R_nom, p_nom
    for s in range(T_S.shape[0]):
        if valid[s]:
            seg = candidate_segments(X_nom @ T_S[s], meas[s, :2], knots, radius)
            ll = ll + _laser_loglik_numpy(x, R_nom, p_nom, T_S[s], meas[s], knots, normals, sigma, sigma_ang,
                                          use_angle, seg)
    return ll


def laser_loglik(x, R_nom, p_nom, T_S, meas, knots, normals, sigma, sigma_ang, use_angle, segments=None):
    """log p(m | X) (Eq. 14.7) of one laser stripe for every particle (numpy; searching ``segments``, default
    all seam segments)."""
    return _laser_loglik_numpy(np.asarray(x, float), R_nom, p_nom, np.asarray(T_S, float), np.asarray(meas, float),
                               knots, normals, sigma, sigma_ang, use_angle, segments)


# ------------------------------------------------------------------------------------------- model
class SeamTrackingModel:
    """The model callables of the seam-tracking filter (given to the generic ParticleFilter).

    robot:   a :class:`drake_est.robots.RobotModel` (forward kinematics F_k and Jacobian of the flange);
    X_FT:    (4, 4) tool pose in the flange frame; knots/normals: the compressed nominal seam (14.8)."""

    def __init__(self, robot, X_FT, knots, normals, config: SeamFilterConfig):
        self.robot = robot
        self.X_FT = np.asarray(X_FT, float)
        self.knots = np.ascontiguousarray(knots, float)
        self.normals = np.ascontiguousarray(normals, float)
        self.config = config
        self.T_S = [sensor_mount(d) for d in config.sensor_distances]
        self.n_sensors = len(self.T_S)
        self.ny = measurement_size(self.n_sensors)
        self.T_S_arr = np.array(self.T_S, float).reshape(self.n_sensors, 4, 4)
        self._pf = None
        self._cache = {}

    # -- kinematics (one call per step, shared by all particles) ----------------------------------
    def tool_pose(self, q) -> np.ndarray:
        """F_k(q) X_FT as a 4x4 matrix."""
        q = np.asarray(q, float)
        key = q.tobytes()
        hit = self._cache.get(key)
        if hit is None:
            r = self.robot
            r.plant.SetPositions(r.context, q)
            hit = r.flange.CalcPoseInWorld(r.context).GetAsMatrix4() @ self.X_FT
            if len(self._cache) > 64:
                self._cache.clear()
            self._cache[key] = hit
        return hit

    def joint_torque(self, q, f) -> np.ndarray:
        """tau = J_v(q)^T f of a force f [N] at the TCP."""
        r = self.robot
        r.plant.SetPositions(r.context, np.asarray(q, float))
        W = self._cache.get("world")
        if W is None:
            W = self._cache["world"] = r.plant.world_frame()
        Jv = r.plant.CalcJacobianTranslationalVelocity(r.context, _KV, r.flange, self.X_FT[:3, 3], W, W)
        return Jv.T @ np.asarray(f, float)

    def robot_measurement_pose(self, q_m, f) -> np.ndarray:
        """Mean of the robot measurement, Eq. (14.3): F_k(q_m + C_j(tau)) X_FT."""
        c = self.config.compliance
        q = np.asarray(q_m, float)
        if c is not None:
            q = q + np.asarray(c, float) * self.joint_torque(q, f)
        return self.tool_pose(q)

    # -- the callables of ParticleFilter ------------------------------------------------------------
    def noise_scale(self, u) -> np.ndarray:
        """Standard deviations (6) of the transition noise, s = s0 + k ||f|| [m, rad]."""
        cfg = self.config
        fn = math.sqrt(u[6] * u[6] + u[7] * u[7] + u[8] * u[8]) if u is not None else 0.0
        sp, sr = cfg.sigma_p0 + cfg.k_p * fn, cfg.sigma_r0 + cfg.k_r * fn
        return np.array([sp, sp, sp, sr, sr, sr])

    def _buffers(self):
        b = self._cache.get("buffers")
        if b is None:
            b = self._cache["buffers"] = (np.empty(6), np.empty(3))
        return b

    def transition(self, x, u, t, rng):
        """xi+ = xi + v, v ~ N(0, diag(s_p(f)^2, s_r(f)^2)): the mean F_k(q+) F_k(q)^-1 X in this chart."""
        s = self.noise_scale(u)
        z = self._pf.normals(t) if self._pf is not None else rng.standard_normal(x.shape)
        return x + z * s

    def measurement_logpdf(self, x, y, u, t):
        cfg = self.config
        y = np.asarray(y, float)
        X_nom = self.tool_pose(u[:6])
        R_nom, p_nom = X_nom[:3, :3], X_nom[:3, 3]
        q_m, f = y[:6], y[6:9]
        fn = float(np.linalg.norm(f))
        # robot measurement (14.6): position and orientation deviation from F_k(q_m + C tau) X_FT
        X_r = self.robot_measurement_pose(q_m, f)
        dp_r = R_nom.T @ (X_r[:3, 3] - p_nom)
        dth_r = so3_log(R_nom.T @ X_r[:3, :3])
        d, dr = cfg.d0 + cfg.k_d * fn, cfg.d0_rot + cfg.k_d_rot * fn
        rob = np.array([d, cfg.sigma_robot, _hybrid_logD(d, cfg.sigma_robot, 3),
                        dr, cfg.sigma_robot_rot, _hybrid_logD(dr, cfg.sigma_robot_rot, 3)])
        S = self.n_sensors
        ms = y[9:9 + 4 * S].reshape(S, 4)
        valid = (ms[:, 0] > 0.5).astype(np.int64)
        meas = np.where(valid[:, None] > 0, ms[:, 1:], 0.0)
        return seam_loglik(x, R_nom, p_nom, dp_r, dth_r, rob, self.T_S_arr, meas, valid, cfg.search_radius,
                           self.knots, self.normals, cfg.sigma_laser, cfg.sigma_angle, cfg.use_angle)

    def initial(self, rng, N):
        cfg = self.config
        s = np.array([cfg.init_p] * 3 + [cfg.init_r] * 3)
        return rng.standard_normal((N, 6)) * s

    def measure(self, X_WT, q_m, f, seam_knots, seam_normals, rng=None, noise=None) -> np.ndarray:
        """The measurement vector y this model expects, from the true tool pose X_WT, encoder readings q_m
        and force f, the laser stripes on ``seam_knots`` (the true seam), with optional noise
        ``(sigma_laser [m], sigma_angle [rad])`` drawn from ``rng``."""
        y = np.zeros(self.ny)
        y[:6], y[6:9] = q_m, f
        for s, T_S in enumerate(self.T_S):
            r = laser_measurement(X_WT, T_S, seam_knots, seam_normals)
            if r is None:
                continue
            m, a = r
            if noise is not None:
                m = m + noise[0] * rng.standard_normal(2)
                a = a + noise[1] * rng.standard_normal()
            y[9 + 4 * s: 13 + 4 * s] = [1.0, m[0], m[1], a]
        return y


def make_seam_filter(robot, X_FT, compressed, config: SeamFilterConfig | None = None, seed: int = 0):
    """The seam-tracking filter: a generic :class:`ParticleFilter` (Algorithm 1) with the
    :class:`SeamTrackingModel` callables.  Returns (pf, model); nx = 6, nu = 9, ny = 9 + 4 n_sensors."""
    from drake_est.estimation.pf import ParticleFilter
    config = config or SeamFilterConfig()
    model = SeamTrackingModel(robot, X_FT, compressed.knots, compressed.normals, config)
    pf = ParticleFilter(model.transition, model.measurement_logpdf, model.initial, config.n_particles, nx=6,
                        seed=seed, resample_threshold=config.resample_threshold, nu=9, ny=model.ny)
    model._pf = pf
    pf._seam_model = model
    return pf, model


def _weight_predict_point(x, logw, g, u0, thr, z, s, xo, lwo, xi, info):
    """Fused weighting, systematic resampling and prediction of one step for all particles (compiled by
    numba): the same arithmetic as the generic filter's ``_weight`` (Algorithm 1: w ~ w p(y|x), normalise,
    ESS, weighted mean, resample when ESS < thr N) followed by the transition xi+ = xi + s * z.
    Writes x+ to ``xo``, log-weights to ``lwo``, the weighted mean to ``xi`` and [log p(y), ESS, resampled]
    to ``info``.  Returns 0, or 1 when the caller must use the generic path (NaN/+inf likelihoods, every
    weight zero, or a non-finite predicted particle)."""
    N, nx = x.shape
    m = -np.inf
    for i in range(N):
        a = logw[i] + g[i]
        if math.isnan(a) or a == np.inf:
            return 1
        lwo[i] = a
        if a > m:
            m = a
    if m == -np.inf:
        return 1
    acc = 0.0
    for i in range(N):
        acc += math.exp(lwo[i] - m)
    ll = m + math.log(acc)
    ss = 0.0
    for j in range(nx):
        xi[j] = 0.0
    for i in range(N):
        lwo[i] = lwo[i] - ll
        w = math.exp(lwo[i])
        ss += w * w
        for j in range(nx):
            xi[j] += w * x[i, j]
    ess = 1.0 / ss
    info[0], info[1], info[2] = ll, ess, 0.0
    if ess < thr * N:
        info[2] = 1.0
        i = 0
        c = math.exp(lwo[0])                 # running cumulative weight (numpy's cumsum order)
        for j in range(N):
            pos = (u0 + j) / N
            while c < pos and i < N - 1:
                i += 1
                c += math.exp(lwo[i])
            for d in range(nx):
                xo[j, d] = x[i, d] + z[j, d] * s[d]
        lN = -math.log(N)
        for j in range(N):
            lwo[j] = lN
    else:
        for j in range(N):
            for d in range(nx):
                xo[j, d] = x[j, d] + z[j, d] * s[d]
    for j in range(N):
        for d in range(nx):
            if not math.isfinite(xo[j, d]):
                return 1
    return 0


_wp_kernel = None


def filter_step(pf, x, logw, y, u, k: int):
    """One step of the seam-tracking filter (Algorithm 1 through the generic filter's public protocol):
    correct with y_k, take the weighted mean xi_k|k, predict with u_k.  Returns
    (x+, logw+, xi_hat (6), ess, degenerate) -- degenerate when every weight was zero (the filter then keeps
    the predicted particles instead of returning NaN).

    With numba (the default) the weighting, resampling and prediction run in one compiled kernel on the
    generic filter's random numbers (``pf.normals``, ``pf.uniform``), giving the generic path's numbers;
    any non-finite case (and ``DRAKE_EST_NO_NUMBA=1``) takes the generic path."""
    global _wp_kernel
    model = getattr(pf, "_seam_model", None)
    if model is not None and use_numba():
        if _wp_kernel is None:
            _wp_kernel = numba.njit(cache=True)(_weight_predict_point)
        x = np.ascontiguousarray(x, dtype=float)
        logw = np.ascontiguousarray(logw, dtype=float)
        g = np.asarray(model.measurement_logpdf(x, y, u, k), dtype=float)
        buf = model._buffers()
        xo, lwo, xi, info = np.empty_like(x), np.empty_like(logw), buf[0], buf[1]
        if g.shape == (pf.N,) and _wp_kernel(x, logw, g, pf.uniform(k), float(pf.resample_threshold),
                                             pf.normals(k), model.noise_scale(u), xo, lwo, xi, info) == 0:
            return xo, lwo, xi.copy(), float(info[1]), False
    # the generic filter's correction step, which also returns the weighted mean and ESS it computes
    x, logw, ll, (ess, _res, degenerate, xi, _P) = pf._correct(x, logw, y, u, k)
    x, logw = pf.predict(x, logw, u=u, t=k)
    return x, logw, xi, ess, bool(degenerate)


def pose_error(X_est, X_true) -> tuple[np.ndarray, np.ndarray]:
    """(position error (3) [m] in the world, rotation error vector (3) [rad] in the tool frame) of X_est."""
    X_est, X_true = np.asarray(X_est), np.asarray(X_true)
    return X_est[:3, 3] - X_true[:3, 3], so3_log(X_true[:3, :3].T @ X_est[:3, :3])


def deviation_to_pose(X_nom, xi) -> np.ndarray:
    """The tool pose X = (R_nom Exp(dtheta), p_nom + R_nom dp) of a deviation xi = [dp, dtheta]."""
    X = np.eye(4)
    X[:3, :3] = X_nom[:3, :3] @ so3_exp(np.asarray(xi[3:6], float))
    X[:3, 3] = X_nom[:3, 3] + X_nom[:3, :3] @ np.asarray(xi[:3], float)
    return X


def pose_to_deviation(X_nom, X) -> np.ndarray:
    """Inverse of :func:`deviation_to_pose`."""
    R = X_nom[:3, :3]
    return np.concatenate([R.T @ (X[:3, 3] - X_nom[:3, 3]), so3_log(R.T @ X[:3, :3])])
