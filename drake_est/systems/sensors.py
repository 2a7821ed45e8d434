"""Simulated wrist sensors for planning and testing calibrations (thesis Ch. 13) as Drake ``LeafSystem``s.

* :class:`ForceTorqueSensor`: quasi-static wrench of a payload (unknown mass and centre of mass) at a
  sensor mounted on the robot flange, with constant offsets and white noise.
* :class:`LaserStripeScanner`: a 2-D laser stripe / line scanner on the flange that intersects its laser
  fan with planar surfaces (and a seam line), in sensor coordinates, with noise.

Both read the plant state on the input port ``robot_state`` = [q (rad); v (rad/s)] (connect
``plant.get_state_output_port()``) and evaluate the flange pose with a private scratch plant context
(a computation cache, re-written from the input on every evaluation; the systems keep no state).

Noise is a deterministic function of (``seed``, sample index k = floor(t / sample_period)): the same
simulation gives the same noise, and it is held constant between samples like a sampled sensor.
"""
from __future__ import annotations

import numpy as np
from pydrake.math import RigidTransform
from pydrake.systems.framework import BasicVector, LeafSystem

from drake_est.calibration.simulate import laser_rays, scan_planes
from drake_est.calibration.so3 import as_matrix
from drake_est.errors import DataError


def _noise(seed, t, period, size):
    k = int(np.floor(t / period + 1e-9)) if period > 0 else 0
    return np.random.default_rng([int(seed), k]).standard_normal(size)


class _FlangeSensor(LeafSystem):
    def __init__(self, plant, X_FS, flange_frame: str = "tool0"):
        super().__init__()
        if not plant.is_finalized():
            raise DataError("the plant must be finalized before adding a sensor")
        self._plant = plant
        self._plant_context = plant.CreateDefaultContext()  # scratch (cache), see module docstring
        try:
            self._flange = plant.GetFrameByName(flange_frame)
        except RuntimeError:
            raise DataError(f"the plant has no frame named {flange_frame!r}") from None
        self._X_FS = as_matrix(X_FS)
        nx = plant.num_positions() + plant.num_velocities()
        self._nq = plant.num_positions()
        self._robot_state = self.DeclareVectorInputPort("robot_state", BasicVector(nx))

    def get_robot_state_input_port(self):
        return self._robot_state

    def sensor_pose(self, context) -> np.ndarray:
        """4x4 pose of the sensor in the world, T_W^F T_F^S."""
        x = self._robot_state.Eval(context)
        self._plant.SetPositions(self._plant_context, x[: self._nq])
        X_WF = self._flange.CalcPoseInWorld(self._plant_context).GetAsMatrix4()
        return X_WF @ self._X_FS

    def flange_pose(self, context) -> RigidTransform:
        x = self._robot_state.Eval(context)
        self._plant.SetPositions(self._plant_context, x[: self._nq])
        return self._flange.CalcPoseInWorld(self._plant_context)


class ForceTorqueSensor(_FlangeSensor):
    """Wrist force/torque sensor holding a payload at rest (quasi-static: gravity only).

    Ports: input ``robot_state`` [q rad; v rad/s]; output ``wrench`` (6) = [f (N); tau (N m)] in the
    sensor frame: f = m R_S^W g + b_f, tau = r x (m R_S^W g) + b_tau (thesis (13.1)-(13.2)).

    Parameters: ``X_FS`` sensor pose in the flange frame (RigidTransform or 4x4; its rotation is
    (R_S^TF)^T), ``mass`` [kg], ``com`` [m, sensor frame], offsets, noise standard deviations, ``gravity``
    [m/s^2, world frame], ``sample_period`` [s] for the noise hold, ``seed``.
    """

    def __init__(self, plant, X_FS=None, mass: float = 1.0, com=(0.0, 0.0, 0.05), force_bias=(0, 0, 0),
                 torque_bias=(0, 0, 0), noise_force: float = 0.0, noise_torque: float = 0.0,
                 gravity=(0.0, 0.0, -9.81), sample_period: float = 0.001, seed: int = 0,
                 flange_frame: str = "tool0"):
        super().__init__(plant, np.eye(4) if X_FS is None else X_FS, flange_frame)
        if mass < 0:
            raise DataError(f"payload mass must be >= 0, got {mass}")
        self.mass, self.com = float(mass), np.asarray(com, float)
        self.force_bias, self.torque_bias = np.asarray(force_bias, float), np.asarray(torque_bias, float)
        self.noise_force, self.noise_torque = float(noise_force), float(noise_torque)
        self.gravity = np.asarray(gravity, float)
        self.sample_period, self.seed = float(sample_period), int(seed)
        self._wrench = self.DeclareVectorOutputPort("wrench", BasicVector(6), self._calc_wrench)

    def get_wrench_output_port(self):
        return self._wrench

    @property
    def R_S_TF(self) -> np.ndarray:
        """True rotation flange -> sensor (what :func:`calibrate_ft` estimates)."""
        return self._X_FS[:3, :3].T

    def _calc_wrench(self, context, output):
        T = self.sensor_pose(context)
        f = self.mass * T[:3, :3].T @ self.gravity
        tau = np.cross(self.com, f)
        n = _noise(self.seed, context.get_time(), self.sample_period, 6)
        w = np.r_[f + self.force_bias + self.noise_force * n[:3], tau + self.torque_bias + self.noise_torque * n[3:]]
        output.SetFromVector(w)


class LaserStripeScanner(_FlangeSensor):
    """2-D laser stripe scanner: a fan of ``n_rays`` rays in the sensor plane spanned by ``axes``
    (default x-y, viewing along y; z = 0 is the laser plane as in Sec. 13.2).

    Ports: input ``robot_state`` [q rad; v rad/s]; outputs ``points`` (3 n_rays) [m], the hit points
    in sensor coordinates (x0, y0, z0, x1, ...; NaN where no surface is within ``max_range``),
    ``plane_labels`` (n_rays) [index] of the surface hit (-1: none), and ``seam_point`` (3) [m], the
    intersection of the laser plane with the seam line in sensor coordinates (NaN when outside the
    field of view or when no seam is given).

    ``planes``: (K, 4) rows [n, d] of surfaces n^T p = d in the world [m]; ``seam``: (point, direction)
    of a line in the world; ``noise``: standard deviation [m] added to the two in-plane coordinates.
    """

    def __init__(self, plant, X_FS, planes, seam=None, n_rays: int = 64, fov_deg: float = 40.0,
                 max_range: float = 1.0, noise: float = 0.0, sample_period: float = 0.01, seed: int = 0,
                 axes=(0, 1), flange_frame: str = "tool0"):
        super().__init__(plant, X_FS, flange_frame)
        planes = np.atleast_2d(np.asarray(planes, float))
        if planes.shape[1] != 4:
            raise DataError(f"planes must be rows [nx, ny, nz, d], got shape {planes.shape}")
        nn = np.linalg.norm(planes[:, :3], axis=1)
        if np.any(nn == 0):
            raise DataError("a plane has a zero normal")
        self.planes = np.column_stack([planes[:, :3] / nn[:, None], planes[:, 3] / nn])
        self.seam = None if seam is None else (np.asarray(seam[0], float), np.asarray(seam[1], float))
        self.axes = tuple(axes)
        self.rays = laser_rays(n_rays, fov_deg, self.axes)
        self.fov = np.radians(fov_deg)
        self.max_range, self.noise = float(max_range), float(noise)
        self.sample_period, self.seed = float(sample_period), int(seed)
        self.n_rays = int(n_rays)
        self._points = self.DeclareVectorOutputPort("points", BasicVector(3 * n_rays), self._calc_points)
        self._labels = self.DeclareVectorOutputPort("plane_labels", BasicVector(n_rays), self._calc_labels)
        self._seam_point = self.DeclareVectorOutputPort("seam_point", BasicVector(3), self._calc_seam)

    def get_points_output_port(self):
        return self._points

    def get_plane_labels_output_port(self):
        return self._labels

    def get_seam_point_output_port(self):
        return self._seam_point

    def _scan(self, context):
        T = self.sensor_pose(context)
        pts, lab = scan_planes(T, self.planes, self.rays, self.max_range)
        if self.noise > 0:
            n = _noise(self.seed, context.get_time(), self.sample_period, (self.n_rays, 2))
            for i, a in enumerate(self.axes):
                pts[:, a] += self.noise * n[:, i]
        return pts, lab

    def _calc_points(self, context, output):
        output.SetFromVector(self._scan(context)[0].ravel())

    def _calc_labels(self, context, output):
        output.SetFromVector(self._scan(context)[1].astype(float))

    def _calc_seam(self, context, output):
        out = np.full(3, np.nan)
        if self.seam is not None:
            T = self.sensor_pose(context)
            R, o = T[:3, :3], T[:3, 3]
            c = 3 - self.axes[0] - self.axes[1]
            nl = R[:, c]  # laser-plane normal in the world
            c0, u = self.seam
            den = nl @ u
            if abs(den) > 1e-12:
                p = c0 + (nl @ (o - c0)) / den * u
                ps = R.T @ (p - o)
                ang = np.arctan2(ps[self.axes[0]], ps[self.axes[1]])
                if abs(ang) <= self.fov / 2 and 0 < np.linalg.norm(ps) <= self.max_range and ps[self.axes[1]] > 0:
                    ps[c] = 0.0
                    if self.noise > 0:
                        n = _noise(self.seed + 1, context.get_time(), self.sample_period, 2)
                        ps[self.axes[0]] += self.noise * n[0]
                        ps[self.axes[1]] += self.noise * n[1]
                    out = ps
        output.SetFromVector(out)


def collect_laser_scans(diagram_or_system, scanner: LaserStripeScanner, plant, q_list, root_context=None):
    """Evaluate the scanner at joint configurations ``q_list`` (static poses).

    Returns ``poses`` (M, 4, 4) flange poses, ``points`` (N, 3), ``pose_index`` (N,), ``labels`` (N,) for
    the rays that hit a surface: exactly the input of :func:`drake_est.calibration.calibrate_laser`.
    """
    ctx = root_context or diagram_or_system.CreateDefaultContext()
    plant_ctx = plant.GetMyMutableContextFromRoot(ctx)
    sctx = scanner.GetMyContextFromRoot(ctx)
    poses, pts, idx, labs = [], [], [], []
    for i, q in enumerate(q_list):
        plant.SetPositions(plant_ctx, np.asarray(q, float))
        ctx.SetTime(i * scanner.sample_period)
        P = scanner.get_points_output_port().Eval(sctx).reshape(-1, 3)
        L = scanner.get_plane_labels_output_port().Eval(sctx).astype(int)
        poses.append(scanner.flange_pose(sctx).GetAsMatrix4())
        ok = L >= 0
        pts.append(P[ok])
        idx.append(np.full(ok.sum(), i))
        labs.append(L[ok])
    return np.array(poses), np.concatenate(pts), np.concatenate(idx), np.concatenate(labs)


def collect_wrenches(diagram_or_system, sensor: ForceTorqueSensor, plant, q_list, root_context=None):
    """Evaluate the F/T sensor at joint configurations ``q_list``: (flange poses (M, 4, 4), wrenches (M, 6))."""
    ctx = root_context or diagram_or_system.CreateDefaultContext()
    plant_ctx = plant.GetMyMutableContextFromRoot(ctx)
    sctx = sensor.GetMyContextFromRoot(ctx)
    poses, W = [], []
    for i, q in enumerate(q_list):
        plant.SetPositions(plant_ctx, np.asarray(q, float))
        ctx.SetTime(i * sensor.sample_period)
        W.append(sensor.get_wrench_output_port().Eval(sctx).copy())
        poses.append(sensor.flange_pose(sctx).GetAsMatrix4())
    return np.array(poses), np.array(W)


def contract_cases():
    """One F/T sensor and one laser scanner on the IRB 140 at a fixed configuration, noise-free; the expected
    outputs come from the plain functions (:func:`drake_est.calibration.ft.simulate_ft`,
    :func:`drake_est.calibration.simulate.scan_planes`) at the flange pose of :class:`drake_est.robots.RobotModel`."""
    from pydrake.math import RollPitchYaw
    from pydrake.systems.framework import DiagramBuilder

    from drake_est.calibration.ft import simulate_ft
    from drake_est.robots import RobotModel
    from drake_est.systems.builders import AddIrb140Plant
    from drake_est.systems.contract import ContractCase

    plant = AddIrb140Plant(DiagramBuilder())
    q = np.array([0.3, -0.2, 0.4, 0.5, 0.7, -0.3])
    x = np.r_[q, np.zeros(6)]
    X_FS = RigidTransform(RollPitchYaw(0.1, -0.2, 0.3), [0.01, 0.02, 0.05]).GetAsMatrix4()
    T_WF = RobotModel.irb140().forward_kinematics(q).GetAsMatrix4()
    T_WS = T_WF @ X_FS
    planes = np.array([[0.0, 0.0, 1.0, 0.1], [1.0, 0.0, 0.0, 0.9]])
    ft = dict(mass=1.3, com=(0.01, -0.02, 0.06), force_bias=(0.5, -0.2, 0.1), torque_bias=(0.01, 0.02, -0.03))

    def ft_expected(s):
        return {"wrench": simulate_ft(T_WF[None], s.R_S_TF, ft["mass"], ft["com"], ft["force_bias"],
                                      ft["torque_bias"], gravity=s.gravity)[0]}

    def laser_expected(s):
        pts, lab = scan_planes(T_WS, s.planes, s.rays, s.max_range)
        return {"points": pts.ravel(), "plane_labels": lab.astype(float)}

    return [
        ContractCase(make=lambda: ForceTorqueSensor(plant, X_FS, **ft), inputs={"robot_state": x},
                     expected=ft_expected, atol=1e-9, label="IRB 140, payload 1.3 kg, noise-free"),
        ContractCase(make=lambda: LaserStripeScanner(plant, X_FS, planes, n_rays=16, max_range=3.0),
                     inputs={"robot_state": x}, expected=laser_expected, atol=1e-9,
                     label="IRB 140, two planes, 16 rays, noise-free"),
        ContractCase(make=lambda: LaserStripeScanner(plant, X_FS, planes, n_rays=8, max_range=3.0, noise=1e-3,
                                                     seed=3),
                     inputs={"robot_state": x}, label="with noise: names and hidden state only"),
    ]
