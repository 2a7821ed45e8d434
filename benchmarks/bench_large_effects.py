"""Effects larger than the closed-loop generator's typical size (issue 16: a wrong name is worse than no name).

The closed-loop generator (:mod:`drake_est.diagnose.testbench_loop`) plants each effect at its typical size (1) or a
third of it.  Real axes can carry more: a static friction several times the Coulomb level, a warm-up that takes
most of the friction away.  A larger effect fitted by a law of the vocabulary leaves a larger misfit of the law's
shape, and that misfit is what later candidates are named for.  This benchmark plants every vocabulary effect alone
at SIZE times the typical size (2 and 3 by default), 120 s at 100 Hz with Gaussian noise, seeds 0-3, on the
generator's own axes and reference families, and scores each log as the testbench benchmark does
(:func:`bench_diagnose_testbench.judge`): correct, wrong name, missed.

Usage (about 1 s per log, 64 logs by default):
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_large_effects.py --json out.json [--sizes 2,3] [--seeds 0-3]
The JSON keeps every row (effect, size, seed, what the diagnosis said) and the counts per size.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("DRAKE_EST_NO_PROGRESS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_slow_disturbance import _seeds, counts_by, counts_text, print_counts  # noqa: E402  (same counts)

SIZES = (2.0, 3.0)


def specs(sizes, seeds) -> list:
    """One closed-loop spec per (size, vocabulary effect, seed): the effect alone, 120 s at 100 Hz."""
    from drake_est.diagnose.testbench_loop import VOCABULARY_EFFECTS
    return [{"effects": {e: float(s)}, "seed": int(k), "sample_rate": 100.0, "duration": 120.0, "noise": "gaussian",
             "noise_std": 0.1} for s in sizes for e in VOCABULARY_EFFECTS for k in seeds]


def run(sizes=SIZES, seeds=range(4)) -> dict:
    """Diagnose every spec; rows as the testbench benchmark writes them plus ``effect``, ``size`` and ``seed``."""
    import bench_diagnose_testbench as b
    sp = specs(sizes, list(seeds))
    rows, refused = [], []
    b._run_family("loop", sp, rows, 0, refused)
    for r in rows:
        (e, s), = sp[r["k"]]["effects"].items()
        r["effect"], r["size"], r["seed"] = e, s, sp[r["k"]]["seed"]
    s = b.summarize(rows)
    return {"logs": s["logs"], "correct": s["correct"], "wrong_names": s["wrong_names"], "missed": s["missed"],
            "per_size": counts_by(rows, "size", [float(x) for x in sizes]), "rows": rows, "refused": refused}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default=",".join(str(s) for s in SIZES), help="effect sizes (1 = the generator's typical)")
    ap.add_argument("--seeds", default="0-3", help="generator seeds: 'A-B' or comma-separated")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    try:
        sizes = [float(x) for x in a.sizes.split(",")]
    except ValueError:
        sizes = []
    if not sizes or any(not (s > 0) for s in sizes):
        print("bench_large_effects: --sizes must be numbers > 0", file=sys.stderr)
        raise SystemExit(2)
    out = run(sizes, _seeds(a.seeds))
    print_counts("large effects", out, "per_size", lambda s: f"size {s}")
    for r in out["rows"]:
        if not r["correct"]:
            print(f"  {r['effect']} x{r['size']:g} seed {r['seed']}: {r['got']} (wrong {r['wrong']}, missed {r['missed']})")
    if a.json:
        from drake_est.jsonutil import dump_json
        dump_json(out, a.json)
    return out


if __name__ == "__main__":
    main()
