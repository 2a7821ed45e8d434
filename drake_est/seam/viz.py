"""Meshcat drawing of a seam-tracking run (thesis Ch. 14): seam, laser stripes, true and estimated tool,
particle cloud -- shared by the live Meshcat of the Diagram (:class:`drake_est.systems.seam.SeamMeshcatOverlay`)
and the self-contained replay ``seam.html`` (:func:`drake_est.seam.analysis.write_meshcat_html`).

Scene paths (under ``/drake/<PREFIX>``)::

    seam                 the seam polyline [m], world frame (red)
    laser/<s>            laser stripe s: a fan in the laser plane, drawn in the sensor frame; its transform is
                         the sensor pose X_WT T_S of the true tool (green)
    laser_hit/<s>        where stripe s meets the seam (transform = the world point; hidden when it misses)
    tool                 the true tool pose (small white sphere)
    estimate             the estimated tool pose F_k(q_cmd) X_FT Exp(xi) (yellow sphere)
    particles            frame at the nominal tool pose F_k(q_cmd) X_FT; its children are point clouds of the
                         particles' translations dp [m] in that frame (blue), ``live`` for the live view or
                         ``<i>`` snapshots shown one at a time in the replay

The numbers are plain numpy (:func:`frame_poses`); the functions here only send them to Meshcat.
"""
from __future__ import annotations

import numpy as np

from drake_est.seam.filter import deviation_to_pose, laser_measurement, sensor_mount

PREFIX = "seam_tracking"
STRIPE_HALF_WIDTH = 0.02     # [m] half length of the drawn laser stripe


def stripe_depth(X_WT, distance: float, knots, normals, default: float = 0.03) -> float:
    """Distance [m] from the laser to the seam along the sensor x axis at tool pose X_WT (``default`` when
    the stripe misses) -- where the drawn stripe is put."""
    m = laser_measurement(np.asarray(X_WT, float), sensor_mount(distance), knots, normals)
    return float(m[0][0]) if m is not None else float(default)


def laser_fan(depth: float, half_width: float = STRIPE_HALF_WIDTH) -> np.ndarray:
    """Line segments (start 3 x 3, end 3 x 3) of a laser fan in the sensor frame: the emitter at the origin,
    the stripe at x_S = ``depth`` from y_S = -half_width to +half_width, in the laser plane z_S = 0."""
    a = np.array([depth, -half_width, 0.0])
    b = np.array([depth, half_width, 0.0])
    o = np.zeros(3)
    return np.column_stack([o, o, a]), np.column_stack([a, b, b])


def frame_poses(X_true, X_nom, X_est, distances, knots, normals) -> dict:
    """The poses (4x4) one frame of the picture needs: ``tool`` (true, X_true), ``estimate`` (X_est),
    ``nominal`` (X_nom = F_k(q_cmd) X_FT, the particles' frame), ``laser`` (list of sensor poses X_true T_S)
    and ``hit`` (list of world points [m] where each stripe meets the seam, None on a miss)."""
    X_true = np.asarray(X_true, float)
    lasers, hits = [], []
    for d in distances:
        T_S = sensor_mount(d)
        X_WS = X_true @ T_S
        lasers.append(X_WS)
        m = laser_measurement(X_true, T_S, knots, normals)
        hits.append(None if m is None else X_WS[:3, :3] @ np.array([m[0][0], m[0][1], 0.0]) + X_WS[:3, 3])
    return {"tool": X_true, "nominal": np.asarray(X_nom, float), "estimate": np.asarray(X_est, float),
            "laser": lasers, "hit": hits}


def estimate_pose(X_nom, xi) -> np.ndarray:
    """The estimated tool pose X_nom Exp(xi) (:func:`drake_est.seam.filter.deviation_to_pose`)."""
    return deviation_to_pose(np.asarray(X_nom, float), np.asarray(xi, float))


def point_cloud(points_3xn):
    """A pydrake ``PointCloud`` of the columns of ``points_3xn`` [m]."""
    from pydrake.perception import BaseField, Fields, PointCloud
    pts = np.asarray(points_3xn, float)
    cloud = PointCloud(pts.shape[1], Fields(BaseField.kXYZs))
    cloud.mutable_xyzs()[:] = pts.astype(np.float32)
    return cloud


def draw_static(meshcat, seam_points, distances, depths, X_FT=None, prefix: str = PREFIX) -> None:
    """The parts that do not move: the seam line, the laser fans (in their sensor frames), the tool and
    estimate markers, and (given the flange-to-tool transform ``X_FT``) the tool as a line from the TCP to
    the flange."""
    from pydrake.geometry import Rgba, Sphere
    if X_FT is not None:
        X_FT = np.asarray(X_FT, float)
        p_TF = -X_FT[:3, :3].T @ X_FT[:3, 3]          # flange origin in the tool frame
        meshcat.SetLineSegments(f"{prefix}/tool/spindle", np.zeros((3, 1)), p_TF.reshape(3, 1), 6.0,
                                Rgba(0.55, 0.55, 0.6, 1))
    meshcat.SetLine(f"{prefix}/seam", np.asarray(seam_points, float).T, 3.0, Rgba(0.9, 0.1, 0.1, 1))
    for s, _ in enumerate(distances):
        start, end = laser_fan(depths[s])
        meshcat.SetLineSegments(f"{prefix}/laser/{s}", start, end, 2.0, Rgba(0.1, 0.85, 0.1, 1))
        meshcat.SetObject(f"{prefix}/laser_hit/{s}", Sphere(0.0015), Rgba(0.1, 1.0, 0.1, 1))
    meshcat.SetObject(f"{prefix}/tool", Sphere(0.0015), Rgba(1.0, 1.0, 1.0, 1))
    meshcat.SetObject(f"{prefix}/estimate", Sphere(0.0012), Rgba(1.0, 0.85, 0.0, 0.9))


def look_at_seam(meshcat, seam_points, distance: float = 0.3) -> None:
    """Point the camera at the middle of the seam from ``distance`` [m] away, from above and to the side."""
    P = np.asarray(seam_points, float)
    target = 0.5 * (P.min(0) + P.max(0))
    direction = np.array([0.9, -0.5, 0.5])
    meshcat.SetCameraPose(target + distance * direction / np.linalg.norm(direction), target)


def set_frame(meshcat, poses: dict, prefix: str = PREFIX, time_in_recording: float | None = None) -> None:
    """Send one frame's poses (:func:`frame_poses`) to Meshcat; with ``time_in_recording`` they also go
    into Meshcat's recording (``meshcat.StartRecording()``) at that time."""
    from pydrake.math import RigidTransform
    kw = {} if time_in_recording is None else {"time_in_recording": float(time_in_recording)}
    meshcat.SetTransform(f"{prefix}/tool", RigidTransform(poses["tool"]), **kw)
    meshcat.SetTransform(f"{prefix}/estimate", RigidTransform(poses["estimate"]), **kw)
    meshcat.SetTransform(f"{prefix}/particles", RigidTransform(poses["nominal"]), **kw)
    for s, (X_WS, hit) in enumerate(zip(poses["laser"], poses["hit"])):
        meshcat.SetTransform(f"{prefix}/laser/{s}", RigidTransform(X_WS), **kw)
        meshcat.SetProperty(f"{prefix}/laser_hit/{s}", "visible", hit is not None, **kw)
        if hit is not None:
            meshcat.SetTransform(f"{prefix}/laser_hit/{s}", RigidTransform(hit), **kw)


def set_particles(meshcat, particles, name: str = "live", prefix: str = PREFIX, point_size: float = 0.0004):
    """Point cloud of the particles' translations dp (N x 6 deviations, first three columns [m]) under the
    ``particles`` frame (the nominal tool pose)."""
    from pydrake.geometry import Rgba
    P = np.asarray(particles, float)
    meshcat.SetObject(f"{prefix}/particles/{name}", point_cloud(P[:, :3].T), point_size, Rgba(0.2, 0.35, 1.0, 1))
