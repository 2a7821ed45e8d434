"""Confusion matrix of the diagnosis on logs from the independent generator
:mod:`drake_est.diagnose.testbench` (not synth): every effect alone, pairs, one-third size, Stribeck with
several vs, time-periodic disturbances at several frequencies, null logs with Gaussian,
Student-t and quantized noise, 10-1000 Hz, and the out-of-vocabulary effects (backlash, delay) that must
end as "unexplained".  (One-speed logs, where ripple and time-periodic are ambiguous, are in
tests/test_diagnose_multilog.py, not here.)  The ``got`` label of a finding reported "ambiguous between A and
B" is ``ambiguous(A|B)``.

A log counts as: ``correct`` (every planted vocabulary effect named or part of an "ambiguous between"
pair, no other name; out-of-vocabulary: no name and a non-empty ``unexplained``), ``wrong`` (a name not
planted), ``missed`` (a planted effect not named).

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/bench_diagnose_testbench.py [--n 150] [--json out.json]
       python benchmarks/bench_diagnose_testbench.py --from-json out.json   (counts and matrix again)
"""
from __future__ import annotations

import argparse
import json
import os
import time
from collections import Counter

import numpy as np

os.environ.setdefault("DRAKE_EST_NO_PROGRESS", "1")

SINGLE = ["stribeck", "time_periodic_disturbance", "motor_position_ripple", "position_dependent_friction",
          "position_dependent_load", "asymmetric_coulomb", "abrupt_change", "energy_dependent_friction"]
PAIRS = [("stribeck", "motor_position_ripple"), ("time_periodic_disturbance", "asymmetric_coulomb"),
         ("position_dependent_friction", "abrupt_change"), ("stribeck", "time_periodic_disturbance")]
OOV = ["backlash", "delay"]


def cases(n: int):
    """n randomized log specs cycling through the families (seeded)."""
    fam = ([("single", (e,)) for e in SINGLE] + [("pair", p) for p in PAIRS] + [("third", (e,)) for e in SINGLE[:4]]
           + [("null", ())] * 3 + [("oov", (e,)) for e in OOV])
    out = []
    for k in range(n):
        kind, effs = fam[k % len(fam)]
        rng = np.random.default_rng(500 + k)
        size = 1.0 / 3.0 if kind == "third" else 1.0
        spec = {"effects": {e: size for e in effs}, "seed": 1000 + k,
                "sample_rate": float(rng.choice([10.0, 50.0, 100.0, 250.0, 1000.0])),
                "duration": float(rng.choice([120.0, 120.0, 300.0])),
                "noise": ["gaussian", "student_t", "quantized"][k % 3],
                "noise_std": float(rng.uniform(0.02, 0.1)), "speeds": 6}
        if spec["sample_rate"] >= 1000:
            spec["duration"] = 120.0
        if "energy_dependent_friction" in effs:
            spec["duration"] = 600.0
            spec["sample_rate"] = min(spec["sample_rate"], 50.0)
        if "stribeck" in effs:
            spec["effects"]["_vs"] = float(rng.choice([0.05, 0.1, 0.2]))
        if "time_periodic_disturbance" in effs:
            spec["effects"]["_f_hz"] = float(min(rng.choice([0.7, 3.0, 11.0, 37.0]), 0.3 * spec["sample_rate"]))
        out.append(spec)
    return out


def judge(spec, d):
    planted = {e for e in spec["effects"] if not e.startswith("_")}
    vocab = planted - set(OOV)
    named = set()
    for f in d["findings"]:
        named |= set(f.get("ambiguous_between", [f["effect"]]))
    wrong = sorted({f["effect"] for f in d["findings"]} - vocab
                   if not any(f.get("ambiguous_between") for f in d["findings"]) else
                   {f["effect"] for f in d["findings"] if not (set(f.get("ambiguous_between", [f["effect"]])) & vocab)})
    missed = sorted(vocab - named)
    oov = planted & set(OOV)
    unexpl_ok = (not oov) or bool(d["unexplained"])
    return {"wrong": wrong, "missed": missed, "oov_unexplained": unexpl_ok,
            "correct": not wrong and not missed and unexpl_ok}


def summarize(rows) -> dict:
    """Counts, the confusion (truth -> what the diagnosis said) and a markdown matrix from the per-log rows."""
    conf = Counter((r["truth"], r["got"]) for r in rows)
    oov = [r for r in rows if set(r["truth"].split("+")) & set(OOV)]
    null = [r for r in rows if r["truth"] == "none"]
    truths = sorted({t for t, _ in conf})
    gots = sorted({g for _, g in conf})
    L = ["| planted \\ diagnosed | " + " | ".join(gots) + " |", "|---" * (len(gots) + 1) + "|"]
    for t in truths:
        L.append(f"| {t} | " + " | ".join(str(conf.get((t, g), "")) for g in gots) + " |")
    return {"logs": len(rows), "correct": sum(r["correct"] for r in rows),
            "wrong_names": sum(bool(r["wrong"]) for r in rows), "missed": sum(bool(r["missed"]) for r in rows),
            "oov_logs": len(oov), "oov_unexplained_right": sum(r["oov_unexplained"] and not r["wrong"] for r in oov),
            "oov_not_unexplained": sum(not r["oov_unexplained"] for r in rows),
            "null_logs": len(null), "null_logs_clean": sum(r["got"] == "none" for r in null),
            "wrong_name_cases": [{"k": r["k"], "truth": r["truth"], "got": r["got"]} for r in rows if r["wrong"]],
            "missed_cases": [{"k": r["k"], "truth": r["truth"], "got": r["got"], "missed": r["missed"]}
                             for r in rows if r["missed"]],
            "median_seconds_per_log": float(np.median([r["seconds"] for r in rows])) if rows else None,
            "confusion": {f"{t} -> {g}": c for (t, g), c in sorted(conf.items())},
            "matrix_markdown": "\n".join(L), "rows": rows}


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=150)
    ap.add_argument("--json", default=None)
    ap.add_argument("--from-json", default=None, help="re-summarize the rows of an earlier --json output")
    a = ap.parse_args(argv)
    if a.from_json:
        summary = summarize(json.load(open(a.from_json))["rows"])
        print(json.dumps({k: v for k, v in summary.items() if k not in ("rows", "matrix_markdown")}, indent=1))
        print(summary["matrix_markdown"])
        if a.json:
            from drake_est.jsonutil import dump_json
            dump_json(summary, a.json)
        return summary
    from drake_est.diagnose import diagnose
    from drake_est.diagnose.testbench import generate
    rows, conf = [], Counter()
    for k, spec in enumerate(cases(a.n)):
        log, truth = generate(spec["effects"], seed=spec["seed"], duration=spec["duration"],
                              sample_rate=spec["sample_rate"], speeds=spec["speeds"], noise=spec["noise"],
                              noise_std=spec["noise_std"])
        t0 = time.perf_counter()
        d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
        dt = time.perf_counter() - t0
        j = judge(spec, d)
        truth_name = "+".join(sorted(e for e in spec["effects"] if not e.startswith("_"))) or "none"
        got = "+".join(sorted(f["effect"] if not f.get("ambiguous_between") else
                              "ambiguous(" + "|".join(f["ambiguous_between"]) + ")" for f in d["findings"]))
        got = got or ("unexplained" if d["unexplained"] else "none")
        conf[(truth_name, got)] += 1
        rows.append({"k": k, "truth": truth_name, "got": got, "seconds": dt, "samples": int(log.n_samples), **j})
        print(f"{k:3d} {truth_name:50s} -> {got:50s} {'ok' if j['correct'] else 'FAIL'} {dt:5.1f}s", flush=True)
    summary = summarize(rows)
    print(json.dumps({k: v for k, v in summary.items() if k not in ("rows", "matrix_markdown")}, indent=1))
    print(summary["matrix_markdown"])
    if a.json:
        from drake_est.jsonutil import dump_json
        dump_json(summary, a.json)
    return summary


if __name__ == "__main__":
    main()
