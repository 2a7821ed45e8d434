"""Loader for the KUKA KR300 R2500 ultra identification benchmark.

Source: JonasWeigand/Robot_Identification, data/recorded_trajectories (MIT license; Weigand et al.,
industrial robot identification benchmark).  Files ``kuka_kr300/recorded_FF_{A,B,C}_08ms.mat``:
struct ``rec`` with rows = axes 1-6, 250 Hz, 10 s each:

* ``act_pos_mot_deg``: motor-encoder position, already divided by the gear ratio (link-side degrees);
* ``act_pos_se_deg``: link-side (secondary) encoder [deg]; real on axes 1-3, constant on axes 4-6;
* ``act_vel_mot_deg_per_s``: motor velocity, link-side [deg/s];
* ``act_torque_abs_nm``: motor torque [N m] (motor side; at most ~20 N m).

``kuka_kr300/data_ref.mat`` holds ``para``: gear ratios ``u`` (154-267), and friction parameters
``f_vis``, ``f_coul``, ``f_a``, ``f_b``, ``f_asym`` on the link side (N m s/rad, N m).

Units in the returned :class:`~drake_est.data.Log` (joints 1-6): ``q`` = motor-encoder position
[rad] (link side), ``dq`` = recorded motor velocity [rad/s] (link side), ``ddq`` by
Savitzky-Golay differentiation of ``q``, ``tau`` = link-side torque = gear ratio x motor torque
[N m] (gearbox efficiency not modelled); channels ``q_link<j>`` = link-side encoder [rad]
(axes 1-3), ``tau_motor<j>`` [N m].
"""
from __future__ import annotations

import numpy as np
import scipy.io

from drake_est.data import from_arrays, smooth_derivatives
from drake_est.datasets.paths import data_file
from drake_est.errors import DataError

TRAJECTORIES = ("A", "B", "C")
LINK_ENCODER_AXES = (1, 2, 3)


def _loadmat(f):
    try:
        return scipy.io.loadmat(str(f), squeeze_me=True, struct_as_record=False)
    except Exception as err:  # noqa: BLE001 - unreadable file becomes a one-line DataError
        raise DataError(f"{f}: not a readable MATLAB file ({err.__class__.__name__})") from None


def load_kuka_parameters(path=None) -> dict:
    """Gear ratios and the benchmark's friction parameters from ``data_ref.mat`` (arrays of 6)."""
    f = data_file("kuka_kr300/data_ref.mat", path)
    d = _loadmat(f)
    if "para" not in d:
        raise DataError(f"{f}: struct 'para' is missing")
    p = d["para"]
    out = {}
    for k in ("u", "f_coul", "f_vis", "f_asym", "f_a", "f_b", "m_payload"):
        if hasattr(p, k):
            out[k] = np.asarray(getattr(p, k), float)
    if "u" not in out or out["u"].shape != (6,):
        raise DataError(f"{f}: para.u (6 gear ratios) is missing")
    return out


def load_kuka(traj: str = "A", path=None, gear_ratios=None, window_s: float = 0.04):
    """Trajectory ``traj`` ("A", "B" or "C") as a 6-joint :class:`~drake_est.data.Log` (see module doc)."""
    traj = str(traj).upper()
    if traj not in TRAJECTORIES:
        raise DataError(f"unknown KUKA trajectory '{traj}' (choose A, B or C)")
    f = data_file(f"kuka_kr300/recorded_FF_{traj}_08ms.mat", path)
    d = _loadmat(f)
    if "rec" not in d:
        raise DataError(f"{f}: struct 'rec' is missing")
    rec = d["rec"]
    need = ("time_cont", "act_pos_mot_deg", "act_pos_se_deg", "act_vel_mot_deg_per_s", "act_torque_abs_nm")
    for k in need:
        if not hasattr(rec, k):
            raise DataError(f"{f}: field rec.{k} is missing")
    u = np.asarray(gear_ratios if gear_ratios is not None else load_kuka_parameters(path)["u"], float)
    t = np.asarray(rec.time_cont, float).ravel()
    q = np.deg2rad(np.asarray(rec.act_pos_mot_deg, float).T)
    qse = np.deg2rad(np.asarray(rec.act_pos_se_deg, float).T)
    dq = np.deg2rad(np.asarray(rec.act_vel_mot_deg_per_s, float).T)
    tau_m = np.asarray(rec.act_torque_abs_nm, float).T
    if q.shape != (len(t), 6):
        raise DataError(f"{f}: positions have shape {q.shape}, expected ({len(t)}, 6)")
    _, ddq, info = smooth_derivatives(t, q, window_s=window_s)
    channels = {f"q_link{j}": qse[:, j - 1] for j in LINK_ENCODER_AXES}
    channels.update({f"tau_motor{j}": tau_m[:, j - 1] for j in range(1, 7)})
    meta = {"file": str(f), "trajectory": traj,
            "source": "KUKA KR300 R2500 ultra, JonasWeigand/Robot_Identification (MIT)",
            "gear_ratios": u.tolist(),
            "units": {"q": "rad (motor encoder / gear ratio)", "dq": "rad/s (recorded)", "ddq": "rad/s^2 (SG)",
                      "tau": "N m link side = gear ratio * motor torque", "q_link": "rad (link encoder)",
                      "tau_motor": "N m"},
            "derivatives": info}
    return from_arrays(t, q, tau=tau_m * u, dq=dq, ddq=ddq, joints=[1, 2, 3, 4, 5, 6], channels=channels,
                       meta=meta)
