"""Slow torque disturbances periodic in time, below the closed-loop generator's range (issue 16, items 1 and 2).

The closed-loop generator (:mod:`drake_est.diagnose.testbench_loop`) plants time-periodic disturbances from 0.3 Hz up
(36 periods in a 120 s log and more).  This benchmark plants slower ones, 0.04 to 0.15 Hz (5 to 18 periods), one per
log at the generator's typical size, 120 s at 100 Hz with Gaussian noise, on the generator's own axes and reference
families (point-to-point moves or multisines, drawn by the seed).  Under point-to-point moves the motion's spectral
lines are dense below a few tenths of a hertz, so such a disturbance lies at a line of the motion.  Each log is
scored as the testbench benchmark scores it (:func:`bench_diagnose_testbench.judge`): correct, wrong name, missed.

Usage (about 1 s per log):
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_slow_disturbance.py --json out.json
    [--freqs 0.04,0.05,0.06,0.08,0.1,0.15] [--seeds 0-11]
The JSON keeps every row (planted frequency, seed, reference family, what the diagnosis said) and the counts.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("DRAKE_EST_NO_PROGRESS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent))

FREQS_HZ = (0.04, 0.05, 0.06, 0.08, 0.1, 0.15)


def specs(freqs, seeds) -> list:
    """One closed-loop spec per (frequency [Hz], seed): the disturbance alone at size 1, 120 s at 100 Hz."""
    return [{"effects": {"time_periodic_disturbance": 1.0, "_f_hz": float(f)}, "seed": int(s), "sample_rate": 100.0,
             "duration": 120.0, "noise": "gaussian", "noise_std": 0.1} for f in freqs for s in seeds]


def run(freqs=FREQS_HZ, seeds=range(12)) -> dict:
    """Diagnose every spec; rows as the testbench benchmark writes them plus ``f_hz`` and ``trajectory``."""
    import bench_diagnose_testbench as b
    sp = specs(freqs, list(seeds))
    rows, refused = [], []
    b._run_family("loop", sp, rows, 0, refused)
    for r in rows:
        r["f_hz"] = sp[r["k"]]["effects"]["_f_hz"]
        r["seed"] = sp[r["k"]]["seed"]
        r["trajectory"] = b.loop_log(sp[r["k"]])[1]["trajectory"]
    s = b.summarize(rows)
    return {"logs": s["logs"], "correct": s["correct"], "wrong_names": s["wrong_names"], "missed": s["missed"],
            "per_frequency": counts_by(rows, "f_hz", freqs), "rows": rows, "refused": refused}


def counts_by(rows, key: str, values) -> dict:
    """{str(value): {"logs", "correct", "wrong", "missed"}} of the rows whose ``key`` is each of ``values``."""
    out = {}
    for x in values:
        rs = [r for r in rows if r[key] == x]
        out[str(x)] = {"logs": len(rs), **{k: sum(1 for r in rs if r[k]) for k in ("correct", "wrong", "missed")}}
    return out


def print_counts(title: str, d: dict, groups: str, label) -> None:
    """The run's counts (:func:`counts_text`) and each group's (``d[groups]``, named by ``label(key)``)."""
    print(f"{title}: {counts_text(d)}")
    for g, c in d[groups].items():
        print(f"  {label(g)}: {c['correct']}/{c['logs']} correct, {c['wrong']} wrong, {c['missed']} missed")


def counts_text(d: dict) -> str:
    """"C / N correct, W wrong names, M missed" of one run's JSON (the docs quote it; tests check the quote)."""
    return f"{d['correct']} / {d['logs']} correct, {d['wrong_names']} wrong names, {d['missed']} missed"


def _seeds(text: str) -> list:
    if "-" in text:
        a, b = text.split("-")
        return list(range(int(a), int(b) + 1))
    return [int(x) for x in text.split(",")]


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--freqs", default=",".join(str(f) for f in FREQS_HZ), help="planted frequencies [Hz]")
    ap.add_argument("--seeds", default="0-11", help="generator seeds: 'A-B' or comma-separated")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    out = run([float(x) for x in a.freqs.split(",")], _seeds(a.seeds))
    print_counts("slow disturbances", out, "per_frequency", lambda f: f"{f} Hz")
    if a.json:
        from drake_est.jsonutil import dump_json
        dump_json(out, a.json)
    return out


if __name__ == "__main__":
    main()
