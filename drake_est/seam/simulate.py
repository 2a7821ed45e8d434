"""Seam-tracking simulation (thesis Sec. 14.2): the IRB 140 following a seam under friction-stir-welding
process forces, with joint compliance (the arm deflects by C_true J^T f), kinematic errors (joint offsets of
the true robot that the model does not know), encoders, laser stripes ahead of the tool, the seam-tracking
particle filter and a tracking controller that corrects the commanded path from the estimate.

:func:`make_scenario` builds the nominal path (inverse kinematics along the seam) and the process force;
:func:`run_loop` runs the whole loop step by step in numpy (the reference the Drake Diagram of
:mod:`drake_est.systems.seam` reproduces, and the engine of the Monte-Carlo studies); :func:`tracking_metrics`
computes the errors reported by ``drake-est track``.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from drake_est.errors import DataError
from drake_est.seam.filter import (SeamFilterConfig, deviation_to_pose, filter_step, make_seam_filter,
                                   pose_error, so3_log)
from drake_est.seam.seam import CompressedSeam, Seam, compress_seam

# the tool: 200 mm along the flange z axis; the reference orientation points it down (tool z = -world z) with
# the tool y axis along the travel direction (+y)
TOOL_LENGTH = 0.20
R_WT_REF = np.array([[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]])
Q_START = np.array([0.0, 0.6, 0.2, 0.0, 0.77, 0.0])
# joint stiffness of the simulated arm [N m/rad]: soft enough that kN process forces deflect it by mm
STIFFNESS_TRUE = np.array([3.0e5, 2.0e5, 2.0e5, 5.0e4, 5.0e4, 3.0e4])


def tool_offset() -> np.ndarray:
    X = np.eye(4)
    X[2, 3] = TOOL_LENGTH
    return X


@dataclass
class ScenarioConfig:
    """The simulated experiment.

    dt [s] filter/controller period; speed [m/s] along the seam; force_down/side/drag [N] process-force
    components on the tool (up, across, against the motion), side_amp [N] and side_period [s] a slow
    oscillation of the side force; force_noise [N]; encoder_noise [rad]; kinematic_error [rad] std of the
    joint offsets of the true robot; compliance_model_error: relative error of the filter's compliance
    model (0 = exact; None = no compliance model); laser_noise [m], angle_noise [rad]."""
    dt: float = 1e-3
    speed: float = 0.02
    force_down: float = 2000.0
    force_side: float = 600.0
    side_amp: float = 300.0
    side_period: float = 3.0
    force_drag: float = 400.0
    force_noise: float = 20.0
    encoder_noise: float = 2e-5
    kinematic_error: float = 2e-4
    compliance_model_error: float | None = 0.3
    laser_noise: float = 5e-5
    angle_noise: float = math.radians(0.1)
    stiffness: np.ndarray = field(default_factory=lambda: STIFFNESS_TRUE.copy())


@dataclass
class Scenario:
    seam: Seam
    compressed: CompressedSeam
    robot: object
    X_FT: np.ndarray
    q_ref: np.ndarray          # (T, 6) nominal joints
    X_ref: np.ndarray          # (T, 4, 4) reference tool poses on the seam
    cross: np.ndarray          # (T, 3) cross-seam directions at the reference points
    force: np.ndarray          # (T, 3) true process force [N]
    kin_offsets: np.ndarray    # (6,) joint offsets of the true robot [rad]
    config: ScenarioConfig

    @property
    def T(self) -> int:
        return self.q_ref.shape[0]


def ik_path(robot, X_FT, X_targets, q0=Q_START, tol=1e-9, iters=50, name="seam"):
    """Joint path reaching the tool poses ``X_targets`` (T, 4, 4) by damped Newton steps warm-started from
    the previous point; DataError naming the first unreachable point."""
    q = np.asarray(q0, float).copy()
    out = np.empty((len(X_targets), 6))
    lim = robot.position_limits
    off = X_FT[:3, 3]
    for k, Xt in enumerate(X_targets):
        for _ in range(iters):
            X = robot.forward_kinematics(q).GetAsMatrix4() @ X_FT
            e = np.concatenate([X[:3, :3] @ so3_log(X[:3, :3].T @ Xt[:3, :3]), Xt[:3, 3] - X[:3, 3]])
            if np.linalg.norm(e) < tol:
                break
            J = robot.jacobian(q, offset=off)
            dq = np.linalg.lstsq(J.T @ J + 1e-9 * np.eye(6), J.T @ e, rcond=None)[0]
            step = np.linalg.norm(dq)
            q = q + (dq if step < 0.3 else 0.3 * dq / step)
        else:
            raise DataError(f"{name} point {k + 1} at {np.round(Xt[:3, 3], 4).tolist()} m is out of the "
                            f"robot's reach (inverse kinematics residual {np.linalg.norm(e):.2g})")
        if np.any(q < lim[:, 0]) or np.any(q > lim[:, 1]):
            j = int(np.flatnonzero((q < lim[:, 0]) | (q > lim[:, 1]))[0])
            raise DataError(f"{name} point {k + 1} needs joint {j + 1} outside its limits")
        out[k] = q
    return out


def make_scenario(seam: Seam, config: ScenarioConfig | None = None, seed: int = 0, robot=None,
                  eps: float = 2e-4) -> Scenario:
    """Nominal path along ``seam`` at ``config.speed``, process force, kinematic errors (seeded)."""
    from drake_est.robots import RobotModel
    config = config or ScenarioConfig()
    robot = robot or RobotModel.irb140()
    rng = np.random.default_rng([seed, 77])
    pts = seam.points
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    # the tool follows the part of the seam that leaves the laser stripes something to see
    T = int(arc[-1] / config.speed / config.dt) + 1
    s = np.linspace(0.0, arc[-1], T)
    P = np.column_stack([np.interp(s, arc, pts[:, j]) for j in range(3)])
    crossd = seam.cross_directions()
    C = np.column_stack([np.interp(s, arc, crossd[:, j]) for j in range(3)])
    C /= np.linalg.norm(C, axis=1)[:, None]
    X_ref = np.tile(np.eye(4), (T, 1, 1))
    X_ref[:, :3, :3] = R_WT_REF
    X_ref[:, :3, 3] = P
    X_FT = tool_offset()
    # IK on a subsampled path (every 10 mm of travel at most 50 points), interpolated in joint space
    ks = np.unique(np.concatenate([np.arange(0, T, max(1, T // 200)), [T - 1]]))
    q_sub = ik_path(robot, X_FT, X_ref[ks], name=seam.name)
    q_ref = np.column_stack([np.interp(np.arange(T), ks, q_sub[:, j]) for j in range(6)])
    t = np.arange(T) * config.dt
    f = np.zeros((T, 3))
    f[:, 0] = config.force_side + config.side_amp * np.sin(2 * np.pi * t / config.side_period)
    f[:, 1] = -config.force_drag
    f[:, 2] = config.force_down
    ramp = np.clip(t / 0.5, 0.0, 1.0)[:, None]          # the process force builds up over 0.5 s
    f = f * ramp
    kin = config.kinematic_error * rng.standard_normal(6)
    compressed = compress_seam(seam, eps=eps)
    return Scenario(seam, compressed, robot, X_FT, q_ref, X_ref, C, f, kin, config)


# ---------------------------------------------------------------------------------------- the plant
def deflection(robot, X_FT, q, f, stiffness) -> np.ndarray:
    """Quasi-static joint deflection dq = K^-1 J_v(q)^T f of joint springs K under a force f at the TCP."""
    J = robot.jacobian(q, offset=X_FT[:3, 3])
    return (J[3:].T @ f) / stiffness


def compliance_model(scn: Scenario):
    """The filter's compliance model C_j (diagonal, rad/(N m)) or None."""
    e = scn.config.compliance_model_error
    if e is None:
        return None
    return (1.0 - e) / scn.config.stiffness


def tracking_correction(robot, X_FT, q_cmd, xi_hat, X_ref, gain: float) -> np.ndarray:
    """Joint correction of the tracking controller: gain J^+ e, with e the twist from the estimated tool pose
    F_k(q_cmd) X_FT Exp(xi_hat) to the reference (least-squares solve, no inverse)."""
    X_nom = robot.forward_kinematics(q_cmd).GetAsMatrix4() @ X_FT
    X_hat = deviation_to_pose(X_nom, xi_hat)
    e = np.concatenate([X_hat[:3, :3] @ so3_log(X_hat[:3, :3].T @ X_ref[:3, :3]), X_ref[:3, 3] - X_hat[:3, 3]])
    J = robot.jacobian(q_cmd, offset=X_FT[:3, 3])
    return gain * np.linalg.lstsq(J, e, rcond=None)[0]


@dataclass
class LoopResult:
    """Logs of a seam-tracking run: true and estimated tool poses (T, 4, 4), commanded joints, particle
    clouds every ``particle_every`` steps, ESS, degenerate steps, wall time of the filter [s]."""
    X_true: np.ndarray
    X_est: np.ndarray
    q_cmd: np.ndarray
    particles: np.ndarray
    particle_steps: np.ndarray
    ess: np.ndarray
    n_degenerate: int
    filter_time: float
    wall_time: float
    n_sensors: int
    closed_loop: bool


def true_tool_pose(scn: Scenario, q_cmd, f) -> tuple[np.ndarray, np.ndarray]:
    """(X_WT true (4x4), q_arm): the deflected arm q_cmd + K^-1 J^T f with the true kinematic offsets."""
    q_arm = q_cmd + deflection(scn.robot, scn.X_FT, q_cmd, f, scn.config.stiffness)
    return scn.robot.forward_kinematics(q_arm + scn.kin_offsets).GetAsMatrix4() @ scn.X_FT, q_arm


def reference_pose(scn: Scenario, k: int) -> np.ndarray:
    """The controller's target: F_k(q_ref,k) X_FT (the nominal tool pose on the seam)."""
    return scn.robot.forward_kinematics(scn.q_ref[k]).GetAsMatrix4() @ scn.X_FT


def step_noise(seed: int, k: int) -> np.ndarray:
    """The sensor noise draws of step k (15 standard normals: 6 encoders, 3 force, 2 x (2 laser + 1 angle)),
    a pure function of (seed, k) (drawn in chunks of 4096 steps) so that the Diagram and :func:`run_loop`
    see the same noise."""
    c = int(k) // 4096
    key = (int(seed), c)
    z = _NOISE.get(key)
    if z is None:
        if len(_NOISE) > 8:
            _NOISE.clear()
        z = _NOISE[key] = np.random.default_rng([int(seed), 99, c]).standard_normal((4096, 15))
    return z[int(k) % 4096]


_NOISE: dict = {}


def measure_all(scn: Scenario, model, X_true, q_cmd, f, seed: int, k: int) -> np.ndarray:
    """The measurement vector of step k: encoders (motor side, = commanded joints) + noise, force + noise,
    laser stripes on the dense true seam + noise."""
    sc = scn.config
    z = step_noise(seed, k)
    q_m = q_cmd + sc.encoder_noise * z[:6]
    f_m = f + sc.force_noise * z[6:9]
    y = model.measure(X_true, q_m, f_m, scn.seam.points, scn.seam.normals)
    for s in range(model.n_sensors):
        if y[9 + 4 * s] > 0.5:
            y[10 + 4 * s: 12 + 4 * s] += sc.laser_noise * z[9 + 3 * s: 11 + 3 * s]
            y[12 + 4 * s] += sc.angle_noise * z[11 + 3 * s]
    return y


def run_loop(scn: Scenario, filter_config: SeamFilterConfig | None = None, closed_loop: bool = True,
             seed: int = 0, gain: float = 0.02, particle_every: int = 20, steps: int | None = None) -> LoopResult:
    """Simulate the seam-tracking loop step by step (numpy reference of the Diagram).

    Per step k: the plant deflects under f_k; encoders, force sensor and laser stripes measure; the
    controller updates its correction from the previous estimate xi_{k-1|k-1} (closed loop); the filter
    corrects with y_k (u_k = [q_cmd,k, f_meas,k]) and predicts.  Noise comes from ``seed``."""
    cfg = filter_config or SeamFilterConfig(compliance=compliance_model(scn))
    sc = scn.config
    pf, model = make_seam_filter(scn.robot, scn.X_FT, scn.compressed, cfg, seed=seed)
    T = scn.T if steps is None else min(int(steps), scn.T)
    X_true = np.empty((T, 4, 4)); X_est = np.empty((T, 4, 4)); Q = np.empty((T, 6))
    ess = np.empty(T)
    pk = np.arange(0, T, particle_every)
    parts = np.empty((pk.size, pf.N, 6))
    x, logw = pf.initial_belief()
    c = np.zeros(6)
    xi_hat = np.zeros(6)          # the controller uses the estimate of the previous step (no feedthrough)
    n_deg = 0
    tf = 0.0
    t0 = time.perf_counter()
    for k in range(T):
        q_cmd = scn.q_ref[k] + c
        f = scn.force[k]
        Xt, _ = true_tool_pose(scn, q_cmd, f)
        y = measure_all(scn, model, Xt, q_cmd, f, seed, k)
        u = np.concatenate([q_cmd, y[6:9]])
        if k % particle_every == 0:
            parts[k // particle_every] = x
        if closed_loop:
            c = c + tracking_correction(scn.robot, scn.X_FT, q_cmd, xi_hat, reference_pose(scn, k), gain)
        t1 = time.perf_counter()
        x, logw, xi_hat, ess[k], deg = filter_step(pf, x, logw, y, u, k)
        tf += time.perf_counter() - t1
        n_deg += deg
        X_true[k] = Xt
        X_est[k] = deviation_to_pose(model.tool_pose(q_cmd), xi_hat)
        Q[k] = q_cmd
    return LoopResult(X_true, X_est, Q, parts, pk, ess, int(n_deg), tf, time.perf_counter() - t0,
                      len(cfg.sensor_distances), closed_loop)


def tracking_metrics(scn: Scenario, res: LoopResult, skip: float = 0.5) -> dict:
    """Errors of a run (after the first ``skip`` seconds, while the process force builds up):
    cross-seam / along-seam / vertical tool errors w.r.t. the reference [mm], estimate errors [mm, deg]."""
    T = res.X_true.shape[0]
    k0 = min(int(skip / scn.config.dt), T - 1)
    sl = slice(k0, T)
    ref = scn.X_ref[:T]
    d = res.X_true[:, :3, 3] - ref[:, :3, 3]
    tang = np.gradient(ref[:, :3, 3], axis=0)
    tang /= np.maximum(np.linalg.norm(tang, axis=1), 1e-300)[:, None]
    cross = (d * scn.cross[:T]).sum(1)
    along = (d * tang).sum(1)
    est_p = np.empty((T, 3)); est_r = np.empty((T, 3))
    for k in range(T):
        est_p[k], est_r[k] = pose_error(res.X_est[k], res.X_true[k])
    est_cross = (est_p * scn.cross[:T]).sum(1)
    est_along = (est_p * tang).sum(1)
    rms = lambda a: float(np.sqrt(np.mean(a[sl] ** 2)))
    return {
        "cross_seam_rmse_mm": 1e3 * rms(cross),
        "along_seam_rmse_mm": 1e3 * rms(along),
        "estimate_cross_seam_rmse_mm": 1e3 * rms(est_cross),
        "estimate_along_seam_rmse_mm": 1e3 * rms(est_along),
        "estimate_position_rmse_mm": 1e3 * float(np.sqrt(np.mean((est_p[sl] ** 2).sum(1)))),
        "orientation_rmse_deg": math.degrees(float(np.sqrt(np.mean((est_r[sl] ** 2).sum(1))))),
        "orientation_rmse_deg_xyz": [math.degrees(rms(est_r[:, j])) for j in range(3)],
        "n_degenerate": int(res.n_degenerate),
        "steps": int(T),
    }
