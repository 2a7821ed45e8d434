"""The eightieth round's rule (``unexplained.ACCELERATION_SMOOTH_REQUIRED``) on fresh closed-loop logs: how many null
logs keep an entry or a finding, and whether an out-of-vocabulary log loses `unexplained` or gains a name.

Logs as ``bench_time_shift_null_rate.py`` generates them (seeds outside every benchmark spec; null: 1,000,000 + i,
out of vocabulary: 2,000,000 + i; ``--rate``, ``--noise``).  Each log is diagnosed with the rule on; where the rule
held an ``acceleration`` entry back (anywhere in the search, which may run the final residual's tests more than once)
it is diagnosed again with the rule off, elsewhere the rule changed nothing and the verdict off is the verdict on.

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/bench_acceleration_smooth_fresh.py --kind null --rate 50
           --noise gaussian --start 500 --n 1000 [--lane 0/2] --json out.json
       python benchmarks/bench_acceleration_smooth_fresh.py --summary a.json b.json
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_diagnose_testbench as B  # noqa: E402
import bench_time_shift_null_rate as T  # noqa: E402

RULE = "ACCELERATION_SMOOTH_REQUIRED"


def diagnose_both(log) -> tuple:
    """(verdict with the rule on, verdict with it off, what it held back): the off run only where it held back."""
    from drake_est.diagnose import diagnose, unexplained as U
    held = []
    original, was = U.acceleration_comb_only, getattr(U, RULE)

    def counted(smooth, n_tests, *a, **kw):
        got = original(smooth, n_tests, *a, **kw)
        if got:
            held.append(None if smooth is None else [float(smooth[0]), float(smooth[1])])
        return got

    U.acceleration_comb_only = counted
    setattr(U, RULE, True)
    try:
        on = T._verdict(diagnose(log, robot="generic", seed=0, simulate=False))
    finally:
        U.acceleration_comb_only = original
        setattr(U, RULE, was)
    if not held:
        return on, on, held
    setattr(U, RULE, False)
    try:
        off = T._verdict(diagnose(log, robot="generic", seed=0, simulate=False))
    finally:
        setattr(U, RULE, was)
    return on, off, held


def run(kind, start, n, lane, path, rate, noise) -> list:
    """Rows of the generated logs start .. start+n-1 (this lane's share), written to ``path`` every ten logs."""
    from drake_est.errors import DataError
    from drake_est.progress import progress
    i0, m = B._lane(lane)
    rows = []
    for i in progress(range(start + i0, start + n, m), desc=f"acceleration rule, {kind}"):
        s = T.spec(kind, i, rate, noise)
        log, truth = B.loop_log(s)
        row = {"i": i, "kind": kind, "effect": next(iter(s["effects"]), None), "seed": s["seed"], "rate": rate,
               "noise": noise, "duration": s["duration"], "noise_std": s["noise_std"],
               "visible": list(truth["effects"])}
        try:
            row["on"], row["off"], row["held_back"] = diagnose_both(log)
        except DataError as e:
            row["refused"] = str(e)
        rows.append(row)
        if path and len(rows) % 10 == 0:
            Path(path).write_text(json.dumps(rows))
    if path:
        Path(path).write_text(json.dumps(rows))
    return rows


def summary(rows) -> dict:
    """Per kind: null logs with any entry or finding (off, on; the 95 % upper bound on); out-of-vocabulary logs
    (visible ones) `unexplained` off and on, those that lose it or gain a name; the refused and not-visible logs
    counted by number."""
    out = {}
    for kind in ("null", "oov"):
        rs = [r for r in rows if r["kind"] == kind]
        if not rs:
            continue
        refused = [r["i"] for r in rs if "refused" in r]
        rs = [r for r in rs if "refused" not in r]
        not_visible = [r["i"] for r in rs if kind == "oov" and not r["visible"]]
        rs = [r for r in rs if kind == "null" or r["visible"]]
        d = {"logs": len(rs), "refused": refused, "not_visible": not_visible,
             "fired": [r["i"] for r in rs if r["held_back"]]}
        if kind == "null":
            for s in ("off", "on"):
                hit = [r["i"] for r in rs if r[s]["findings"] or r[s]["unexplained"]]
                d[s] = {"with_entry_or_finding": hit, "rate": len(hit) / max(len(rs), 1),
                        "upper_95": T.upper_95(len(hit), len(rs))}
        else:
            for s in ("off", "on"):
                d[s] = {"unexplained": [r["i"] for r in rs if r[s]["unexplained"] and not r[s]["findings"]],
                        "named_something": [r["i"] for r in rs if r[s]["findings"]]}
            d["lost_unexplained"] = [r["i"] for r in rs if r["off"]["unexplained"] and not r["on"]["unexplained"]]
            d["name_gained"] = [r["i"] for r in rs if set(r["on"]["findings"]) - set(r["off"]["findings"])]
        out[kind] = d
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kind", default="null")
    ap.add_argument("--rate", type=float, default=50.0, help="sample rate [Hz] of the generated logs (50)")
    ap.add_argument("--noise", default="gaussian", help="torque noise: gaussian (default), student_t, quantized")
    ap.add_argument("--start", type=int, default=0)
    ap.add_argument("--n", type=int, default=100)
    ap.add_argument("--lane", default=None, metavar="I/N")
    ap.add_argument("--json", default=None)
    ap.add_argument("--summary", nargs="+", default=None, metavar="JSON")
    a = ap.parse_args(argv)
    if a.summary:
        print(json.dumps(summary(T._read(a.summary)), indent=1))
        return
    T.spec(a.kind, 0, a.rate, a.noise)           # a bad option: one line, before any log is generated
    print(json.dumps(summary(run(a.kind, a.start, a.n, a.lane, a.json, a.rate, a.noise)), indent=1))


if __name__ == "__main__":
    main()
