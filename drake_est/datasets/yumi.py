"""Loader for the YuMi force/torque-sensor log (``yumi_gravitylog/gravitylog.mat``) and an
orientation-only kinematic model of one YuMi (IRB 14000) arm.

Source: baggepinnen/Robotlib.jl history, applications/data/gravitylog.mat (MIT, F. Bagge Carlson).
MATLAB v7.3 (HDF5): arrays are stored transposed, (7, N) -> returned as (N, 7).

Fields: ``q`` [rad], ``qd`` [rad/s], ``tau`` (joint torques as logged), ``f`` (N, 6) wrench: forces
in N; the torque columns are in N mm (magnitudes up to ~200 with a 0.2 kg tool), converted here to
N m (``torque_unit_scale``).

Kinematics: only the flange *orientation* matters for F/T calibration (Sec. 13.1), so the model is
the chain of rotations of the public modified Denavit-Hartenberg table of the YuMi arm (IRB 14050:
twists alpha = 0, -90, 90, -90, 90, -90, 90 deg; joint-angle offset +90 deg on the 4th joint of the
chain), with the log's columns in chain order.  The alternatives (ABB's axis numbering 1, 2, 7, 3, 4,
5, 6; offsets 0 or -90 deg) were tried on the data and leave 12-13x larger force residuals (see the
``real-yumi-ft`` case study).  The arm's base is tilted on the torso; the gravity direction in the arm
base frame is estimated from the data (:func:`drake_est.calibration.ft.calibrate_ft_unknown_gravity`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_est.datasets.paths import data_file
from drake_est.errors import DataError

ALPHA_DEG = np.array([0.0, -90.0, 90.0, -90.0, 90.0, -90.0, 90.0])
THETA_OFFSET_DEG = np.array([0.0, 0.0, 0.0, 90.0, 0.0, 0.0, 0.0])
TORQUE_UNIT_SCALE = 1e-3  # N mm -> N m


@dataclass
class YumiLog:
    q: np.ndarray      # (N, 7) rad
    qd: np.ndarray     # (N, 7) rad/s
    tau: np.ndarray    # (N, 7) as logged
    wrench: np.ndarray  # (N, 6) [N, N m]
    path: str

    def flange_poses(self, order=None, theta_offset_deg=None) -> np.ndarray:
        """(N, 4, 4) flange orientations in the arm base frame (translation zero: not modelled)."""
        return yumi_flange_rotations(self.q, order=order, theta_offset_deg=theta_offset_deg)


def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def yumi_flange_rotations(q, order=None, theta_offset_deg=None) -> np.ndarray:
    """Flange orientations (N, 4, 4) of a YuMi arm from joint angles (N, 7) [rad] in chain order.

    R = prod_i Rx(alpha_i) Rz(q_i + offset_i) (modified DH, rotations only).  ``order`` permutes the
    columns of q into chain order; ``theta_offset_deg`` replaces the default offsets.
    """
    q = np.atleast_2d(np.asarray(q, float))
    if q.shape[1] != 7:
        raise DataError(f"YuMi joint angles need 7 columns, got {q.shape[1]}")
    if order is not None:
        q = q[:, list(order)]
    off = np.radians(THETA_OFFSET_DEG if theta_offset_deg is None else np.asarray(theta_offset_deg, float))
    Rx = [_rx(a) for a in np.radians(ALPHA_DEG)]
    out = np.tile(np.eye(4), (len(q), 1, 1))
    for n, qi in enumerate(q):
        R = np.eye(3)
        for j in range(7):
            t = qi[j] + off[j]
            c, s = np.cos(t), np.sin(t)
            R = R @ Rx[j] @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        out[n, :3, :3] = R
    return out


def load_gravitylog(path=None) -> YumiLog:
    """Read ``yumi_gravitylog/gravitylog.mat`` (h5py; arrays transposed to samples x channels)."""
    import h5py

    f = data_file("yumi_gravitylog/gravitylog.mat", path)
    try:
        with h5py.File(f, "r") as h:
            arrs = {k: np.array(h[k]).T for k in ("q", "qd", "tau", "f")}
    except KeyError as err:
        raise DataError(f"{f}: missing variable {err}") from None
    except OSError as err:
        raise DataError(f"{f}: not a MATLAB v7.3/HDF5 file ({err})") from None
    W = arrs["f"].astype(float).copy()
    if W.shape[1] != 6:
        raise DataError(f"{f}: wrench 'f' must have 6 channels, got {W.shape[1]}")
    W[:, 3:] *= TORQUE_UNIT_SCALE
    return YumiLog(arrs["q"], arrs["qd"], arrs["tau"], W, str(f))
