"""Why the several-log ODrive diagnosis gains less on the 3x slower log (issue #16 item 5, point 3).

1. ``cases.cogging.cogging_multilog_diagnosis``: the diagnosis' held-out RMSE reduction per held-out log.
2. Per log, a least-squares fit of [qd, sign(qd), 1] + harmonics 1..60 per motor revolution (the cogging period
   is one motor revolution): amplitude and phase of the main harmonics relative to the first log.  A phase shift
   common to all harmonics (not proportional to the harmonic number) is no encoder offset and no delay.
3. Fixed-amplitude harmonics fitted on the training logs (1, 3, 5) and evaluated on the held-out logs (2, 4, 6),
   with each log's own [qd, sign(qd), 1] offsets; and the same with a per-log complex gain of the ripple
   (2 numbers per log, as a session-dependent current-loop response would give), fitted on that log.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_odrive_multilog.py --json /tmp/odrive_multilog.json
"""
from __future__ import annotations

import argparse
import json

import numpy as np


def _logs(names, v_max=3.0):
    from drake_est.cases.cogging import _select
    from drake_est.datasets.odrive import load_odrive_log
    out = []
    for n in names:
        lg, _ = _select(load_odrive_log(n), v_max)
        q, v, y = lg.q[:, 0], lg.dq[:, 0], lg.tau[:, 0]
        m = np.abs(v) > 0.05
        out.append((q[m], v[m], y[m]))
    return out


def _base(v):
    return np.column_stack([v, np.sign(v), np.ones_like(v)])


def _resid(B, e):
    return e - B @ np.linalg.lstsq(B, e, rcond=None)[0]


def harmonic_table(logs, H, show):
    z = []
    for q, v, y in logs:
        A = np.hstack([_base(v), np.cos(np.outer(q, H)), np.sin(np.outer(q, H))])
        c = np.linalg.lstsq(A, y, rcond=None)[0]
        z.append(c[3:3 + H.size] - 1j * c[3 + H.size:])
    ref = z[0]
    return [{int(H[i]): {"amplitude_A": float(abs(zk[i])), "phase_vs_log1_deg": float(np.degrees(np.angle(zk[i] / ref[i])))}
             for i in show} for zk in z]


def heldout(logs, H, train=(0, 2, 4), per_log_gain=False):
    A = [np.hstack([_base(v), np.cos(np.outer(q, H)), np.sin(np.outer(q, H))]) for q, v, _ in logs]
    c = np.linalg.lstsq(np.vstack([A[k] for k in train]), np.concatenate([logs[k][2] for k in train]), rcond=None)[0]
    n = H.size
    out = {}
    for k in range(len(logs)):
        if k in train:
            continue
        q, v, y = logs[k]
        B = _base(v)
        if per_log_gain:
            E = (c[3:3 + n] - 1j * c[3 + n:]) * np.exp(1j * np.outer(q, H))
            B = np.column_stack([B, E.sum(1).real, (1j * E.sum(1)).real])
            e1 = _resid(B, y - _base(v) @ c[:3])
        else:
            e1 = _resid(B, y - A[k] @ c)
        e0 = _resid(_base(v), y)
        out[k + 1] = float(1 - np.sqrt(np.mean(e1 ** 2)) / np.sqrt(np.mean(e0 ** 2)))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    from drake_est.cases.cogging import MULTILOG, cogging_multilog_diagnosis
    res = cogging_multilog_diagnosis()
    out = {"logs": list(MULTILOG), "diagnosis": {
        "effects": res["effects"], "ripple_per_rev": res["ripple_per_rev"],
        "heldout_rmse_reduction_pooled": res["heldout_rmse_reduction"],
        "heldout_rmse_reduction_per_log": {r["log"]: r["rmse_reduction"] for r in res["per_log"] if r["role"] == "validate"},
        "offsets_dkv_dkc": {r["log"]: r["offsets_dkv_dkc"] for r in res["per_log"]},
        "median_speed_rad_s": {r["log"]: r["median_speed"] for r in res["per_log"]}}}
    logs = _logs(MULTILOG)
    Hall = np.arange(1, 61.0)
    out["harmonics_per_log"] = harmonic_table(logs, Hall, [6, 13, 27, 11, 35])
    sets = {"7,14,28,12 per rev": np.array([7.0, 14, 28, 12]), "8 strongest": np.array([7.0, 14, 28, 12, 36, 35, 21, 56]),
            "1..60 per rev": Hall}
    out["fixed_harmonics_heldout"] = {k: heldout(logs, H) for k, H in sets.items()}
    out["fixed_harmonics_per_log_gain_heldout"] = {k: heldout(logs, H, per_log_gain=True) for k, H in sets.items()}
    print(json.dumps(out, indent=1))
    if a.json:
        from drake_est.jsonutil import dump_json
        dump_json(out, a.json)


if __name__ == "__main__":
    main()
