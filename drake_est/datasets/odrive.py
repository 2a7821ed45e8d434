"""Loaders for the ODrive cogging-torque data (``odrive_cogging/``); the LPV spectral case study on it is
:mod:`drake_est.cases.cogging_spectral`.

Source: gchenfc/ODrive (branch master), analysis/cogging_torque (MIT license, see the folder's LICENSE):
a brushless motor on an ODrive controller.

* Logs (``slow2/``, ``slow2_slower/``, ``slow_goodgains_2/``, ``pull_tests/``): ``.npy`` arrays (3, n) =
  [t (s), position (encoder counts, 8192 per revolution), motor current (A)]; ``nocomp`` without and
  ``comp`` with the controller's anti-cogging feed-forward.  :func:`load_odrive_log` returns a
  :class:`drake_est.data.Log` with ``q1`` the motor angle [rad] (counts * 2 pi / 8192), ``tau1`` the
  current [A] (a torque proxy: torque = k_t * current, k_t unknown; ``meta["tau_unit"] = "A"``) and
  ``dq1`` [rad/s] by Savitzky-Golay differentiation (``drake_est.data.smooth_derivatives``).
* Cogging maps (``coggingmap_0/``): 8192 values (current [A] needed to hold each encoder count over one
  revolution), measured every ``step`` counts (``_4``, ``_8``, ``_16``, ``_32`` in the file name) with
  zeros in between, ``_interp`` files filled.  :func:`load_cogging_map` returns ``(angle_rad, current_A)``
  of the measured points only (the zeros between samples are dropped; in ``_interp`` files all 8192).
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from drake_est.datasets.paths import data_dir, data_file
from drake_est.errors import DataError

COUNTS_PER_REV = 8192
FOLDER = "odrive_cogging"


def _load_array(sub: str, data=None) -> np.ndarray:
    f = data_file(f"{FOLDER}/{sub}", data)
    try:
        a = np.load(f, allow_pickle=False)
    except Exception as err:  # noqa: BLE001 - report any read failure as a data error
        raise DataError(f"cannot read {f}: {err}") from None
    return a, f


def list_logs(data=None) -> list:
    """Relative names (``slow2/nocomp_0.npy``, ...) of all logs in the folder."""
    root = data_dir(data) / FOLDER
    if not root.is_dir():
        raise DataError(f"ODrive cogging folder not found: {root}")
    return sorted(str(p.relative_to(root)) for p in root.glob("*/*.npy") if not p.parent.name.startswith("cogging"))


def load_odrive_log(name: str, data=None, derivatives: bool = True, window_s: float = 0.03):
    """One ODrive log as a :class:`drake_est.data.Log` (see module doc); ``name`` like ``"slow2/nocomp_0.npy"``.

    Rows whose time does not increase are dropped and counted in ``meta["excluded_rows"]``."""
    from drake_est.data import Log, smooth_derivatives

    a, f = _load_array(name, data)
    if a.ndim != 2 or a.shape[0] != 3:
        raise DataError(f"{f}: expected an array (3, n) = [t, position counts, current], got shape {a.shape}")
    t, counts, cur = (np.asarray(r, dtype=float) for r in a)
    finite = np.isfinite(t) & np.isfinite(counts) & np.isfinite(cur)
    keep = finite.copy()
    idx = np.flatnonzero(finite)
    # keep a strictly increasing time axis
    last = -np.inf
    for i in idx:
        if t[i] <= last:
            keep[i] = False
        else:
            last = t[i]
    excluded = int(np.sum(~keep))
    t, counts, cur = t[keep], counts[keep], cur[keep]
    if t.size < 20:
        raise DataError(f"{f}: only {t.size} usable samples")
    q = counts * (2 * np.pi / COUNTS_PER_REV)
    meta = {"source": "gchenfc/ODrive analysis/cogging_torque (MIT)", "file": str(f), "tau_unit": "A",
            "note": "tau1 is the motor current [A], a torque proxy (torque = k_t * current); q1 is the motor "
                    "angle [rad] = counts * 2 pi / 8192", "counts_per_rev": COUNTS_PER_REV,
            "compensated": bool(re.search(r"(^|/|_)comp", name) and "nocomp" not in name and "uncomp" not in name),
            "excluded_rows": excluded, "gear_ratio": 1.0}
    dq = ddq = None
    if derivatives:
        dq, ddq, info = smooth_derivatives(t, q[:, None], window_s=window_s)
        meta["derivatives"] = info
    return Log(t=t, q=q[:, None], dq=dq, ddq=ddq, tau=cur[:, None], joints=[1], meta=meta)


def load_cogging_map(name: str = "cogging_measure_final_a_4_interp.npy", data=None):
    """A measured cogging map: ``(angle_rad, current_A)`` at the measured encoder counts (see module doc)."""
    sub = name if "/" in name else f"coggingmap_0/{name}"
    a, f = _load_array(sub, data)
    a = np.asarray(a, dtype=float).ravel()
    if a.size != COUNTS_PER_REV:
        raise DataError(f"{f}: a cogging map has {COUNTS_PER_REV} values, got {a.size}")
    if "interp" in Path(sub).name:
        idx = np.arange(COUNTS_PER_REV)
    else:
        m = re.search(r"_(\d+)r?\.npy$", Path(sub).name)
        step = int(m.group(1)) if m else 1
        idx = np.arange(0, COUNTS_PER_REV, step)
    return idx * (2 * np.pi / COUNTS_PER_REV), a[idx]
