"""Loader for the EMPS benchmark (electro-mechanical positioning system, a real prismatic axis).

Source: wmkouw/NSI-EMPS, data/ (MIT license); benchmark of Janot, Gautier and Brunot (2019),
"Data set and reference models of EMPS".  Two MATLAB v5 files, 1 kHz, 24.8 s each:

* ``DATA_EMPS.mat``: ``t`` [s], ``qm`` motor (cart) position [m], ``qg`` reference position [m],
  ``vir`` controller output [V], ``gtau`` drive gain [N/V], ``kp``, ``kv`` controller gains.
* ``DATA_EMPS_PULSES.mat``: the same trajectory with a square wave ``pulses_N`` (values 0 and 5)
  injected into the loop; every edge is followed by a force transient of up to ~180 N lasting
  about 0.1 s (see :func:`pulse_edges`).

Units in the returned :class:`~drake_est.data.Log`: ``q1`` = ``qm`` [m]; ``tau1`` = drive force
``gtau * vir`` [N]; channels ``qg`` [m], ``vir`` [V] and (pulses file) ``pulses_N`` (as logged).
Velocities/accelerations are not filled in: the case study (:mod:`drake_est.cases.emps`) differentiates
a zero-phase low-pass filtered position; ``log.with_derivatives()`` gives the generic estimate.
"""
from __future__ import annotations

import numpy as np
import scipy.io

from drake_est.data import from_arrays
from drake_est.datasets.paths import data_file
from drake_est.errors import DataError

FILES = {"emps": "emps/DATA_EMPS.mat", "pulses": "emps/DATA_EMPS_PULSES.mat"}

#: approximate reference values of the benchmark (Janot et al. 2019) as quoted in the project's
#: issue: mass [kg], viscous [N s/m], Coulomb [N]
PUBLISHED = {"M": 95.0, "Fv": 200.0, "Fc": 20.0}


def emps_path(name: str = "emps", path=None):
    """Path of an EMPS file: ``name`` is ``"emps"``, ``"pulses"`` or a file name in ``emps/``."""
    sub = FILES.get(name, f"emps/{name}")
    return data_file(sub, path)


def load_emps(name: str = "emps", path=None):
    """Load ``DATA_EMPS.mat`` (``name="emps"``) or ``DATA_EMPS_PULSES.mat`` (``"pulses"``) as a
    :class:`~drake_est.data.Log` (one prismatic joint, SI units, see the module doc)."""
    f = emps_path(name, path)
    try:
        d = scipy.io.loadmat(str(f))
    except Exception as err:  # noqa: BLE001 - unreadable file becomes a one-line DataError
        raise DataError(f"{f}: not a readable MATLAB file ({err.__class__.__name__})") from None
    for key in ("t", "qm", "vir", "gtau"):
        if key not in d:
            raise DataError(f"{f}: variable '{key}' is missing (not an EMPS data file?)")
    t = np.asarray(d["t"], float).ravel()
    qm = np.asarray(d["qm"], float).ravel()
    vir = np.asarray(d["vir"], float).ravel()
    gtau = float(np.asarray(d["gtau"]).item())
    channels = {"vir": vir}
    if "qg" in d:
        channels["qg"] = np.asarray(d["qg"], float).ravel()
    if "pulses_N" in d:
        channels["pulses_N"] = np.asarray(d["pulses_N"], float).ravel()
    if not (len(t) == len(qm) == len(vir)):
        raise DataError(f"{f}: t, qm and vir have different lengths ({len(t)}, {len(qm)}, {len(vir)})")
    meta = {"file": str(f), "source": "EMPS benchmark (Janot, Gautier, Brunot 2019), wmkouw/NSI-EMPS, MIT",
            "gtau_N_per_V": gtau, "units": {"q1": "m", "tau1": "N (gtau * vir)", "qg": "m", "vir": "V"},
            "joint_type": "prismatic"}
    for k in ("kp", "kv"):
        if k in d:
            meta[k] = float(np.asarray(d[k]).item())
    return from_arrays(t, qm, tau=gtau * vir, joints=[1], channels=channels, meta=meta)


def pulse_edges(log) -> np.ndarray:
    """Sample indices where the injected ``pulses_N`` square wave changes value (empty without pulses)."""
    p = log.channels.get("pulses_N")
    if p is None:
        return np.zeros(0, dtype=int)
    return np.flatnonzero(np.diff(p) != 0) + 1
