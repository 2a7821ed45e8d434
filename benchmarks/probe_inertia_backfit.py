"""Where the inertia backfit moves J, and whether the rows of large acceleration tell the same J (tried after the
thirty-sixth round, not kept: ``diagnose_inertia_backfit_confirm_tried.patch``).

For closed-loop benchmark logs (by default every kept row that records a backfit move, ``inertia_backfit``, plus
``--k``), the diagnosis is run with a probe around :func:`drake_est.diagnose.core.backfit_inertia` that records, at
its call, the J that the same fit gives on: all training rows (the backfit's estimate), the held-out rows, and the
training rows of the 50 %, 20 % and 10 % largest |qdd|; beside them prepare's J, the generator's J and the rule's
decision (``old_rule_moves``; ``moved_to``: the move the diagnosis makes, None where the fifty-fourth round's check
withholds it); and the J of the same fit with a free friction curve of the joint's speed beside the findings
(``J_curve`` with ``J_curve_se``: :func:`drake_est.diagnose.core.inertia_correction_beside_speed_curve`, the fit of
:func:`drake_est.diagnose.core.inertia_move_contradicted`; None without a curve).  The probe
returns what the backfit returns, so the diagnosis is the same as without it; ``--stop-at-backfit`` ends each
diagnosis at that call (the row's ``got`` is then None).  The summary also applies the tried rule to the recorded
numbers (``tried_confirm``: the move only when J + dJ > 0 and the rows of the 20 % largest |qdd| give a positive J
within a factor 2 of it).

    python benchmarks/probe_inertia_backfit.py --json benchmarks/results/diagnose_inertia_backfit_probe.json \\
        --k 11834
    python benchmarks/probe_inertia_backfit.py --large-moves 2 --stop-at-backfit \\
        --json benchmarks/results/diagnose_inertia_backfit_curve_probe.json --k 7238

Prints, per estimator, how many logs end with J within a factor 1.5 of the generator's, and the logs that do not.
"""
import argparse
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_diagnose_testbench as b  # noqa: E402

#: the subsets of training rows a J is estimated on: name -> share of the largest |qdd| (1.0: all)
SUBSETS = {"train": 1.0, "top50": 0.5, "top20": 0.2, "top10": 0.1}


def correction(A, y):
    """The backfit's own estimate (:func:`drake_est.diagnose.core.first_coefficient`) on a subset of rows; None also
    when the subset has no more rows than columns."""
    from drake_est.diagnose.core import first_coefficient
    return None if A.shape[0] <= A.shape[1] else first_coefficient(A, y)


def probe_call(prep, model, out) -> dict:
    """{joint: record} of one backfit call: prepare's J, the rule's move (or None) and the J of each subset."""
    from drake_est.diagnose import core
    rec = {}
    for j, jd in prep.joints.items():
        J = jd.counts.get("inertia")
        if J is None:
            continue
        qdd = jd.a[jd.rows]
        A = np.column_stack([qdd, model.design_with_shared(j)])
        r = {"J_prepare": float(J), "moved_to": out[j][1] if j in out else None}
        a_tr = np.abs(qdd[jd.train])
        for name, share in SUBSETS.items():
            m = jd.train & (np.abs(qdd) >= np.quantile(a_tr, 1.0 - share)) if share < 1.0 else jd.train
            est = correction(A[m], jd.y[m])
            r[f"J_{name}"] = None if est is None else float(J + est[0])
            if name == "train" and est is not None:
                dJ, se = est
                r["old_rule_moves"] = bool(abs(dJ) > core.INERTIA_BACKFIT_Z * se
                                           and abs(dJ) > core.INERTIA_BACKFIT_REL * abs(J))
        est = correction(A[jd.val], jd.y[jd.val])
        r["J_val"] = None if est is None else float(J + est[0])
        est = core.inertia_correction_beside_speed_curve(prep, model, j)
        r["J_curve"] = None if est is None else float(J + est[0])
        r["J_curve_se"] = None if est is None else est[1]
        r["curve_rule_moves"] = est is not None and bool(abs(est[0]) > core.INERTIA_BACKFIT_Z * est[1]
                                                         and abs(est[0]) > core.INERTIA_BACKFIT_REL * abs(J))
        rec[str(j)] = r
    return rec


class _Stop(Exception):
    """Ends a diagnosis at the backfit's first call (``--stop-at-backfit``)."""


def run(ks, stop=False):
    from drake_est.diagnose import core, diagnose
    orig = core.backfit_inertia
    calls = []

    def probed(prep, model, fit):
        out = orig(prep, model, fit)
        calls.append(probe_call(prep, model, out))
        if stop:
            raise _Stop
        return out

    core.backfit_inertia = probed
    rows = []
    try:
        for k in ks:
            calls.clear()
            spec = b.loop_cases(k + 1)[k]
            log, truth = b.loop_log(spec)
            try:
                got = b._got(diagnose(log, robot="generic", seed=0, simulate=False).to_dict())
            except _Stop:
                got = None
            row = {"k": k, "truth": b._label(spec["effects"], truth["not_visible"]), "got": got,
                   "J_generator": float(truth["J"]), "calls": list(calls)}
            rows.append(row)
            print(json.dumps(row), flush=True)
    finally:
        core.backfit_inertia = orig
    return rows


def summary(rows) -> dict:
    """Per estimator: logs within a factor 1.5 of the generator's J and those that are not (first call, joint 1)."""
    def final(r, key):
        J = r["J_prepare"]
        if key == "prepare":
            return J
        if key == "old_rule":
            return r["J_train"] if r.get("old_rule_moves") else J
        if key == "rule":
            return r["moved_to"] if r["moved_to"] is not None else J
        if key == "curve_rule":
            return r["J_curve"] if r.get("curve_rule_moves") else J
        if key == "tried_confirm":
            Jn, Jt = r["J_train"], r["J_top20"]
            ok = r.get("old_rule_moves") and Jn > 0 and Jt is not None and Jt > 0 and max(Jn / Jt, Jt / Jn) <= 2.0
            return Jn if ok else J
        return r.get(f"J_{key}")
    out = {}
    recs = [(row["k"], row["J_generator"], c) for row in rows if row["calls"] for c in row["calls"][:1]
            for c in c.values()]
    for key in ("prepare", "old_rule", "rule", "tried_confirm", "curve_rule", "train", "val", "top50", "top20",
                "top10", "curve"):
        if not any(f"J_{key.removesuffix('_rule')}" in r or key in ("prepare", "old_rule", "rule", "tried_confirm")
                   for _, _, r in recs):
            continue    # a JSON written before the estimator was added
        bad = []
        for k, Jg, r in recs:
            J = final(r, key)
            if J is None or J <= 0 or abs(math.log(J / Jg)) > math.log(1.5):
                bad.append(k)
        out[key] = {"within_1.5x": len(recs) - len(bad), "logs": len(recs), "not": bad}
        print(f"{key:9s} J within a factor 1.5 of the generator's: {len(recs) - len(bad):3d} / {len(recs)}  "
              f"not: {bad}")
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", default=None)
    ap.add_argument("--k", type=int, nargs="*", default=[], help="more closed-loop spec indices")
    ap.add_argument("--only-k", type=int, nargs="*", default=None, help="these spec indices only")
    ap.add_argument("--large-moves", type=float, default=None, metavar="F",
                    help="only the kept rows whose recorded move changes J by more than a factor F (or flips its sign)")
    ap.add_argument("--stop-at-backfit", action="store_true",
                    help="end each diagnosis at the backfit's first call (faster; the rows' got is None)")
    ap.add_argument("--lane", default=None, help="i/n: every n-th log from the i-th")
    args = ap.parse_args(argv)
    if args.only_k is not None:
        ks = list(args.only_k)
    else:
        def large(r):
            return any(a <= 0 or c <= 0 or max(c / a, a / c) > args.large_moves
                       for a, c in r["inertia_backfit"].values())
        ks = sorted({r["k"] for key, (_, r) in b.kept_rows_naming("any").items()
                     if key[0] == "loop" and "inertia_backfit" in r and (args.large_moves is None or large(r))}
                    | set(args.k))
    if args.lane:
        i, n = map(int, args.lane.split("/"))
        ks = ks[i::n]
    rows = run(ks, stop=args.stop_at_backfit)
    out = {"what": "inertia backfit probe (benchmarks/probe_inertia_backfit.py)", "logs": len(rows),
           "summary": summary(rows), "rows": rows}
    if args.json:
        from drake_est.jsonutil import dump_json
        dump_json(out, args.json)


if __name__ == "__main__":
    main()
