"""Several logs of one machine in one diagnosis (issue #16, item 5).

:func:`drake_est.diagnose.concatenate_logs` puts the logs one after the other with a ``log_index`` channel;
:func:`~drake_est.diagnose.nominal.prepare` then holds out whole logs (even-numbered logs train,
odd-numbered ones validate).  The model is common to all logs (the nominal friction and every extension),
except where physics says a log may differ: the Coulomb and viscous levels follow the temperature of the
joint, which differs from session to session.  So every log gets its own offsets [dkv_k, dkc_k] on top of
the common friction (:func:`per_log_offsets`), estimated on that log's own samples after the common part is
fixed -- also on a held-out log, as a temperature would have to be measured there (2 numbers per log, the
same for the nominal and every extended model, so the held-out comparisons stay fair).  Effects that
vary within a log (time-periodic, abrupt change, energy drift) cannot be carried to a held-out log, so they
are only accepted when they do show there.  The energy state of the energy-dependent friction (9.23) is a
state of one session: it restarts at zero at each log's first sample (:func:`unit_energy_per_log`) and
never runs across the boundary between two logs, in the regression and in the re-simulation.  The
re-simulation (:mod:`drake_est.diagnose.simulate`) uses each log's own offsets and never lets a window
cross from one log into the next.
"""
from __future__ import annotations

import numpy as np

#: per-log offsets are estimated only for logs with at least this many used samples of the joint
MIN_LOG_SAMPLES = 20


def log_name(lg, k: int) -> str:
    """The file a log came from (``meta["file"]``), else ``log <k + 1>``."""
    return str(lg.meta.get("file") or f"log {k + 1}") if getattr(lg, "meta", None) else f"log {k + 1}"


def check_logs(logs) -> None:
    """Several logs of one machine must log the same joints, hold data (at least two samples and a torque
    column) and be different recordings: the same data given twice would sit in the training and in the
    held-out logs at once.  Raises :class:`~drake_est.errors.DataError` with one line naming the file."""
    import hashlib

    from drake_est.errors import DataError
    if len(logs) < 2:
        raise DataError("several-log diagnosis needs at least two logs")
    joints = list(logs[0].joints)
    seen = {}
    for k, lg in enumerate(logs):
        name = log_name(lg, k)
        if list(lg.joints) != joints:
            raise DataError(f"{name}: joints {list(lg.joints)} differ from those of {log_name(logs[0], 0)} {joints}; "
                            "several logs of one machine must log the same joints")
        if lg.t is None or np.asarray(lg.t).size < 2:
            raise DataError(f"{name}: the log is empty (fewer than two samples)")
        if lg.tau is None:
            raise DataError(f"{name}: the log has no torque columns (tau<j>)")
        h = hashlib.sha1()
        for a in (lg.t, lg.q, lg.tau):
            h.update(np.ascontiguousarray(np.asarray(a, float)).tobytes())
        key = h.hexdigest()
        if key in seen:
            raise DataError(f"{name}: the same data as {seen[key]} (a log given twice); each recording may be "
                            "given once, whole logs are held out")
        seen[key] = name


def log_ids(prep, jd):
    """0-based log number of each used row of joint data ``jd``; None for a single log."""
    li = prep.log.channels.get("log_index") if prep.log.channels else None
    if li is None:
        return None
    return np.asarray(li).astype(int)[jd.rows]


def log_starts(prep):
    """Index (into the full, concatenated log) of each log's first sample; None for a single log."""
    li = prep.log.channels.get("log_index") if prep.log.channels else None
    if li is None:
        return None
    li = np.asarray(li)
    return np.flatnonzero(np.r_[True, li[1:] != li[:-1]])


def unit_energy_per_log(t, W, tau_e, starts=None):
    """The unit-gain energy E of Eq. (9.23) (:func:`~drake_est.identification.friction.extensions.unit_energy`)
    restarted at E = 0 at every index in ``starts`` (each log's first sample): every log starts cold and
    its energy depends on its own history only.  ``starts=None``: one log, no restart."""
    from drake_est.identification.friction.extensions import unit_energy
    W = np.asarray(W, float)
    if starts is None or len(starts) <= 1:
        return unit_energy(t, W, tau_e)
    E = np.zeros_like(W)
    bounds = sorted(set(int(s) for s in starts) | {0, W.size})
    for a, b in zip(bounds[:-1], bounds[1:]):
        if b - a >= 2:
            E[a:b] = unit_energy(t[a:b], W[a:b], tau_e)
    return E


def energy_fn(prep):
    """The unit-gain energy function ``E(t, W, tau_e)`` that the energy detector uses for this prepared log:
    :func:`unit_energy_per_log` restarting at each log's first sample for several logs, None (the detector's
    plain (9.23)) for one log."""
    starts = log_starts(prep)
    if starts is None:
        return None
    return lambda t, W, tau_e: unit_energy_per_log(t, W, tau_e, starts)


def log_at_time(prep, t) -> int | None:
    """0-based number of the log that time ``t`` of the concatenated log belongs to; None for one log."""
    starts = log_starts(prep)
    if starts is None:
        return None
    li = np.asarray(prep.log.channels["log_index"]).astype(int)
    k = int(np.searchsorted(prep.log.t[starts], t, side="right")) - 1
    return int(li[starts[max(k, 0)]])


def per_log_offsets(jd, ids, pred):
    """``(pred + offsets, {log: [dkv, dkc]})``: per-log Coulomb/viscous offsets fitted by least squares to
    the residual ``jd.y - pred`` of each log (columns [qd, sign(qd)] of Eq. (9.2)); a log whose columns
    are rank deficient (one direction, one speed) gets the minimum-norm solution."""
    v = jd.v[jd.rows]
    B = np.column_stack([v, np.sign(v)])
    out = pred.copy()
    offs = {}
    for k in np.unique(ids):
        m = ids == k
        if m.sum() < MIN_LOG_SAMPLES:
            continue
        c, *_ = np.linalg.lstsq(B[m], jd.y[m] - pred[m], rcond=None)
        out[m] += B[m] @ c
        offs[int(k)] = [float(c[0]), float(c[1])]
    return out, offs


def per_log_table(prep, res) -> list:
    """One row per log: its role (train / validate; ``held_out`` True for validation logs, which are not used
    for fitting), samples used, the nominal and final model's RMSE on it (held-out RMSE for validation logs)
    and the final model's Coulomb/viscous offsets [dkv, dkc] of that log."""
    rows = []
    files = str(prep.log.meta.get("file", "")).split(" + ")
    for j, jd in prep.joints.items():
        ids = log_ids(prep, jd)
        if ids is None:
            return []
        y = jd.y
        e0 = y - res.nominal_fit.pred[j]
        e1 = y - res.final_fit.pred[j]
        offs = getattr(res.final_fit, "per_log", {}).get(j, {})
        for k in np.unique(ids):
            m = ids == k
            rows.append({"log": int(k) + 1, "file": files[k] if k < len(files) else f"log{k + 1}", "joint": int(j),
                         "role": "validate" if k % 2 else "train", "held_out": bool(k % 2), "samples": int(m.sum()),
                         "nominal_rmse": float(np.sqrt(np.mean(e0[m] ** 2))),
                         "final_rmse": float(np.sqrt(np.mean(e1[m] ** 2))),
                         "rmse_reduction": float(1 - np.sqrt(np.mean(e1[m] ** 2)) / np.sqrt(np.mean(e0[m] ** 2))),
                         "median_speed": float(np.median(np.abs(jd.v[jd.rows][m]))),
                         "offsets_dkv_dkc": offs.get(int(k))})
    return rows


def across_logs_evidence(prep, ext) -> dict | None:
    """For a periodic finding of a several-log diagnosis: whether a single log could have told a ripple in
    position from a disturbance periodic in time (its own speed levels, :func:`speed_level_ratio`) and
    whether the logs together can -- an effect that shows only across logs.  None for one log or other
    effects."""
    from drake_est.diagnose.competition import ONE_SPEED_RATIO, PERIODIC_PAIR, periodic_window_s, speed_level_ratio
    if ext.effect not in PERIODIC_PAIR or ext.shared:
        return None
    jd = prep.joints[ext.joint]
    ids = log_ids(prep, jd)
    if ids is None:
        return None
    w = periodic_window_s(ext, jd)
    single = []
    for k in np.unique(ids):
        m = ids == k
        if m.sum() < MIN_LOG_SAMPLES:
            continue
        sub = _Rows(jd, jd.rows[m])
        single.append(speed_level_ratio(sub, w))
    combined = speed_level_ratio(jd, w)
    return {"speed_level_ratio_per_log": single, "speed_level_ratio_all_logs": combined,
            "identifiable_in_a_single_log": bool(max(single) >= ONE_SPEED_RATIO) if single else False,
            "identifiable_across_logs": bool(combined >= ONE_SPEED_RATIO),
            "held_out": "whole logs"}


class _Rows:
    """Joint data restricted to some rows (what :func:`speed_level_ratio` reads)."""

    def __init__(self, jd, rows):
        self.t, self.v, self.rows = jd.t, jd.v, rows
