"""Force/torque sensor calibration from free-air poses (thesis Sec. 13.1).

Model (gravity only, sensor at rest), for pose i with flange orientation R_RB^TF_i:

    g_TF,i = (R_RB^TF_i)^T g                       gravity in the flange frame
    f_S,i  = m R g_TF,i + b_f                      (13.1) with a force offset b_f
    tau_S,i = r x (m R g_TF,i) + b_tau             (13.2) with a torque offset b_tau

where ``R = R_S^TF`` rotates flange-frame vectors into the sensor frame, ``m`` is the mass held by
the sensor and ``r`` the centre of mass in sensor coordinates (``R^T r`` in flange coordinates).

Two estimators:

* :func:`calibrate_ft` with ``method="relaxation"``: least squares for the 9 entries of mR (the
  convex relaxation of (13.3); here written with the measured force as the dependent variable,
  which keeps the noisy measurement out of the regressor), projection onto SO(3) (6.1)-(6.2),
  mass (and offset) re-estimated given R, then r from the linear torque relation (13.5).
* ``method="cayley"``: needs the mass; Cayley-Gibbs-Rodrigues parameters from the linear relation
  (13.11) by total least squares (errors in variables), Eqs. (13.6)-(13.11).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from drake_est.calibration.linalg import lstsq, tls
from drake_est.calibration.so3 import as_pose_stack, cayley, project_to_so3, skew
from drake_est.errors import DataError, IdentifiabilityError

GRAVITY = np.array([0.0, 0.0, -9.81])


@dataclass
class FTCalibration:
    """Result of a force/torque-sensor calibration (SI units: kg, m, N, N m)."""

    R: np.ndarray                  # R_S^TF: flange-frame vector -> sensor frame
    mass: float
    com: np.ndarray                # centre of mass in sensor coordinates [m]
    force_bias: np.ndarray         # [N]
    torque_bias: np.ndarray        # [N m]
    method: str
    gravity: np.ndarray = field(default_factory=lambda: GRAVITY.copy())
    residuals: np.ndarray | None = None      # (N, 6) measured - predicted
    raw_residuals: np.ndarray | None = None  # (N, 6) measured - mean(measured): before calibration
    condition: float = float("nan")          # condition number of the normalized gravity regressor
    weak_direction: np.ndarray | None = None  # gravity direction (flange frame) least excited

    @property
    def com_flange(self) -> np.ndarray:
        """Centre of mass in tool-flange coordinates [m]."""
        return self.R.T @ self.com

    def predict(self, poses) -> np.ndarray:
        """Predicted (N, 6) wrench [N, N m] in the sensor frame for flange poses (N, 4, 4)."""
        P = as_pose_stack(poses)
        g_tf = np.einsum("nji,j->ni", P[:, :3, :3], self.gravity)
        f = self.mass * g_tf @ self.R.T
        tau = np.cross(self.com, f)
        return np.column_stack([f + self.force_bias, tau + self.torque_bias])

    def compensate(self, poses, wrench) -> np.ndarray:
        """External (contact) wrench: measurement minus the payload's gravity and sensor offsets."""
        return np.asarray(wrench, dtype=float) - self.predict(poses)

    def summary(self) -> dict:
        out = {
            "method": self.method,
            "R_S_TF": self.R.tolist(),
            "mass_kg": float(self.mass),
            # without torque measurements the centre of mass is not determined: null, not NaN
            "com_sensor_m": self.com.tolist() if np.all(np.isfinite(self.com)) else None,
            "com_flange_m": self.com_flange.tolist() if np.all(np.isfinite(self.com)) else None,
            "force_bias_N": self.force_bias.tolist(),
            "torque_bias_Nm": self.torque_bias.tolist(),
            "condition_number": float(self.condition),
        }
        if self.residuals is not None:
            out["residual_rms_force_N"] = _rms(self.residuals[:, :3])
            out["residual_rms_torque_Nm"] = _rms(self.residuals[:, 3:])
        if self.raw_residuals is not None:
            out["before_rms_force_N"] = _rms(self.raw_residuals[:, :3])
            out["before_rms_torque_Nm"] = _rms(self.raw_residuals[:, 3:])
        if not np.isfinite(out["condition_number"]):
            out["condition_number"] = None
        if self.weak_direction is not None:
            out["weak_gravity_direction_flange"] = self.weak_direction.tolist()
        return out


def _rms(a):
    """RMS of the finite entries, None when there are none (e.g. torques of a force-only sensor)."""
    a = np.asarray(a, float)
    a = a[np.isfinite(a)]
    return float(np.sqrt(np.mean(a**2))) if a.size else None


def _check_inputs(poses, wrench):
    P = as_pose_stack(poses)
    W = np.asarray(wrench, dtype=float)
    if len(P) == 0:
        raise DataError("poses is empty: F/T calibration needs poses with different orientations")
    if W.ndim != 2 or W.shape[1] not in (3, 6):
        raise DataError(f"wrench must have shape (N, 6) [fx fy fz tx ty tz] or (N, 3), got {W.shape}")
    if len(P) != len(W):
        raise DataError(f"{len(P)} poses but {len(W)} wrench samples; they must match row by row")
    bad = ~np.all(np.isfinite(W), axis=1) | ~np.all(np.isfinite(P.reshape(len(P), -1)), axis=1)
    if bad.any():
        raise DataError(f"{int(bad.sum())} samples contain NaN/inf (first at row {int(np.flatnonzero(bad)[0])}); "
                        "remove them before calibrating")
    return P, W


def gravity_excitation(g_tf, bias: bool):
    """Condition number of the normalized gravity regressor and its least excited direction.

    The force relation (13.3) is identifiable when the gravity directions seen in the flange frame
    span 3-D (and, with an offset, are not all on one circle of the sphere, i.e. [g^T 1] has rank 4).
    """
    u = g_tf / np.linalg.norm(g_tf, axis=1, keepdims=True)
    G = np.column_stack([u, np.ones(len(u))]) if bias else u
    s, Vt = np.linalg.svd(G, full_matrices=False)[1:]
    cond = float(s[0] / s[-1]) if s[-1] > 0 else float("inf")
    weak = Vt[-1][:3]
    nw = np.linalg.norm(weak)
    weak = weak / nw if nw > 1e-12 else np.array([0.0, 0.0, 1.0])
    return cond, weak


def calibrate_ft(poses, wrench, method: str = "relaxation", bias: bool = True, mass: float | None = None,
                 m0: float = 1.0, gravity=GRAVITY, max_condition: float = 1e6,
                 warn_condition: float = 50.0) -> FTCalibration:
    """Calibrate a wrist force/torque sensor from free-air poses (Sec. 13.1).

    Parameters
    ----------
    poses : (N, 4, 4) flange poses T_RB^TF (or RigidTransforms), metres.
    wrench : (N, 6) sensor readings [fx, fy, fz, tx, ty, tz] in N and N m (or (N, 3) forces only;
        then no centre of mass is estimated).
    method : "relaxation" (mass estimated) or "cayley" (needs ``mass``; uses total least squares).
    bias : also estimate constant force and torque offsets.
    mass : mass for the Cayley method [kg].
    m0 : initial mass guess for the relaxation; it only scales the right-hand side of the
        relaxed problem, so the result does not depend on it (kept for parity with the thesis).
    """
    P, W = _check_inputs(poses, wrench)
    N = len(P)
    need = 4 if bias else 3
    if N < need:
        raise IdentifiabilityError(f"F/T calibration needs at least {need} poses with different orientations "
                                   f"(got {N}); collect more free-air poses")
    gravity = np.asarray(gravity, dtype=float)
    g_tf = np.einsum("nji,j->ni", P[:, :3, :3], gravity)  # R^T g per pose
    cond, weak = gravity_excitation(g_tf, bias)
    if not np.isfinite(cond) or cond > max_condition:
        u = g_tf / np.linalg.norm(g_tf, axis=1, keepdims=True)
        ang = np.degrees(np.arccos(np.clip(np.min(u @ u[0]), -1.0, 1.0)))
        if ang < 1.0:
            raise IdentifiabilityError(
                "all poses have the same orientation relative to gravity; collect poses with the tool "
                "tilted so gravity points along at least 3 different flange directions"
                + (" (4 not on one cone, for the offset)" if bias else ""))
        raise IdentifiabilityError(
            f"poses do not excite all gravity directions (condition number {cond:.3g}); collect poses with "
            f"gravity along flange direction {np.round(weak, 2).tolist()}")
    if cond > warn_condition:
        warnings.warn(f"F/T calibration poses are poorly spread (condition number {cond:.3g}); weakest "
                      f"gravity direction in the flange frame: {np.round(weak, 2).tolist()}", stacklevel=2)
    f = W[:, :3]
    ones = np.tile(np.eye(3), (N, 1))
    if method == "relaxation":
        if m0 <= 0:
            raise DataError(f"m0 must be positive, got {m0}")
        # f_i = X (m0 g_i) + b,  X = (m/m0) R: linear in vec(X) (column-major) and b
        A = np.kron(m0 * g_tf, np.eye(3))  # (3N, 9): f_i = (g_i^T kron I3) vec(X)
        if bias:
            A = np.column_stack([A, ones])
        x, _ = lstsq(A, f.reshape(-1))
        X = x[:9].reshape(3, 3, order="F")
        R = project_to_so3(X)
        # mass (and offset) given R: f_i = m (R g_i) + b
        u = g_tf @ R.T
        B = u.reshape(-1, 1)
        if bias:
            B = np.column_stack([B, ones])
        mb, _ = lstsq(B, f.reshape(-1))
        m = float(mb[0])
        bf = mb[1:4] if bias else np.zeros(3)
    elif method == "cayley":
        if mass is None or not mass > 0:
            raise DataError("the Cayley method needs the payload mass (mass=... > 0); use method='relaxation' "
                            "to estimate it")
        m = float(mass)
        u = m * g_tf
        A = np.concatenate([skew(fi + ui) for fi, ui in zip(f, u)])  # <f + u> s (+ beta) = f - u
        y = (f - u).reshape(-1)
        if bias:
            x = tls(np.column_stack([A, ones]), y, exact_cols=[3, 4, 5])
            s, beta = x[:3], x[3:6]
            bf = np.linalg.solve(np.eye(3) + skew(s), beta)
        else:
            s = tls(A, y)
            bf = np.zeros(3)
        R = cayley(s)
    else:
        raise DataError(f"unknown F/T calibration method {method!r}; use 'relaxation' or 'cayley'")

    fg = m * g_tf @ R.T  # gravity force of the payload in the sensor frame
    if W.shape[1] == 6:
        tau = W[:, 3:]
        # tau_i = r x fg_i + b  =  -<fg_i> r + b   (13.5)
        C = np.concatenate([-skew(v) for v in fg])
        if bias:
            C = np.column_stack([C, ones])
        x, sv = lstsq(C, tau.reshape(-1))
        if sv[-1] <= 1e-9 * sv[0]:
            raise IdentifiabilityError("the torque relation does not determine the centre of mass; collect poses "
                                       "with gravity along more flange directions")
        r = x[:3]
        bt = x[3:6] if bias else np.zeros(3)
    else:
        r = np.full(3, np.nan)
        bt = np.zeros(3)
    res = FTCalibration(R=R, mass=m, com=r, force_bias=np.asarray(bf, float), torque_bias=np.asarray(bt, float),
                        method=method, gravity=gravity, condition=cond, weak_direction=weak)
    if W.shape[1] == 6:
        res.residuals = W - res.predict(P)
        res.raw_residuals = W - W.mean(axis=0)
    else:
        res.residuals = np.column_stack([f - fg - res.force_bias, np.zeros_like(f)])
        res.raw_residuals = np.column_stack([f - f.mean(axis=0), np.zeros_like(f)])
    return res


def simulate_ft(poses, R, mass, com, force_bias=(0, 0, 0), torque_bias=(0, 0, 0), noise_force=0.0,
                noise_torque=0.0, gravity=GRAVITY, rng=None) -> np.ndarray:
    """(N, 6) synthetic wrench readings from the model above (for tests and reproductions)."""
    rng = np.random.default_rng(rng)
    truth = FTCalibration(R=np.asarray(R, float), mass=float(mass), com=np.asarray(com, float),
                          force_bias=np.asarray(force_bias, float), torque_bias=np.asarray(torque_bias, float),
                          method="truth", gravity=np.asarray(gravity, float))
    W = truth.predict(poses)
    W[:, :3] += noise_force * rng.standard_normal((len(W), 3))
    W[:, 3:] += noise_torque * rng.standard_normal((len(W), 3))
    return W


def calibrate_ft_unknown_gravity(poses, wrench, bias: bool = True, n_iter: int = 30, g: float = 9.81,
                                 n_grid: int = 84) -> tuple[FTCalibration, np.ndarray]:
    """F/T calibration when the gravity direction in the robot base frame is unknown (tilted or
    unknown base mounting, e.g. the arms of a YuMi on its torso).

    The force relation f = m R R_RB^TF^T g + b is bilinear in (mR, g): a grid of directions picks the
    start, then the relaxation of :func:`calibrate_ft` (g fixed) and a least-squares update of g (R, m,
    b fixed, |g| kept) alternate.  g is identifiable when the first joint(s) rotate the flange about an
    axis not parallel to gravity.  Returns (calibration, gravity vector in the base frame).
    """
    P, W = _check_inputs(poses, wrench)
    Rf = P[:, :3, :3]
    # Fibonacci sphere of start directions
    k = np.arange(n_grid) + 0.5
    th = np.arccos(1 - 2 * k / n_grid)
    ph = np.pi * (1 + 5**0.5) * k
    dirs = np.column_stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])
    best = None
    Wf = W[:, :3]  # the gravity direction comes from the forces; torques only enter the final fit
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for d in dirs:
            try:
                r = calibrate_ft(P, Wf, bias=bias, gravity=g * d, warn_condition=np.inf)
            except IdentifiabilityError:
                continue
            rms = float(np.sqrt(np.mean(r.residuals[:, :3] ** 2)))
            if best is None or rms < best[0]:
                best = (rms, g * d, r)
        if best is None:
            raise IdentifiabilityError("no gravity direction makes the poses identifiable; collect poses with "
                                       "more varied tool orientations")
        _, gv, r = best
        for _ in range(n_iter):
            A = np.einsum("ij,njk->nik", r.mass * r.R, np.transpose(Rf, (0, 2, 1))).reshape(-1, 3)
            y = (Wf - r.force_bias).reshape(-1)
            gv, _ = lstsq(A, y)
            gv = g * gv / np.linalg.norm(gv)
            r = calibrate_ft(P, Wf, bias=bias, gravity=gv, warn_condition=np.inf)
        r = calibrate_ft(P, W, bias=bias, gravity=gv, warn_condition=np.inf)
    return r, gv
