"""drake_est.calibration: sensor calibration without special equipment (thesis Sec. 6.1 and Ch. 13).

* :func:`calibrate_ft`: wrist force/torque sensor from free-air poses (convex relaxation or Cayley/TLS).
* :func:`calibrate_laser`: 2-D laser stripe scanner, point laser or 3-D scanner from scans of planes
  (iterative two-step method), with automatic plane assignment (:func:`assign_scans_to_planes`).
* SO(3)/SE(3) helpers in :mod:`drake_est.calibration.so3`.
"""
from drake_est.calibration.assignment import assign_scans_to_planes, ransac_planes
from drake_est.calibration.ft import (
    FTCalibration, calibrate_ft, calibrate_ft_unknown_gravity, gravity_excitation, simulate_ft,
)
from drake_est.calibration.laser import (
    LaserCalibration, calibrate_laser, fit_plane, plane_residuals, refine_transform, solve_transform,
    transform_error, transform_points,
)
from drake_est.calibration.linalg import tls
from drake_est.calibration.simulate import (
    LaserProblem, laser_rays, orthogonal_planes, perturb_transform, random_ft_poses, random_laser_problem,
    random_sensor_transform, scan_planes,
)
from drake_est.calibration.so3 import (
    as_matrix, as_pose_stack, cayley, exp_se3, exp_so3, inv_pose, log_se3, log_so3, make_pose, project_to_so3,
    random_rotation, rotation_error, rpy_to_matrix, skew, to_rigid_transform,
)

__all__ = [
    "FTCalibration", "LaserCalibration", "LaserProblem", "as_matrix", "as_pose_stack", "assign_scans_to_planes",
    "calibrate_ft", "calibrate_ft_unknown_gravity", "calibrate_laser", "cayley", "exp_se3", "exp_so3", "fit_plane", "gravity_excitation",
    "inv_pose", "laser_rays", "log_se3", "log_so3", "make_pose", "orthogonal_planes", "perturb_transform",
    "plane_residuals", "project_to_so3", "random_ft_poses", "random_laser_problem", "random_rotation",
    "random_sensor_transform", "ransac_planes", "refine_transform", "rotation_error", "rpy_to_matrix",
    "scan_planes", "simulate_ft", "skew", "solve_transform", "tls", "to_rigid_transform", "transform_error",
    "transform_points",
]
