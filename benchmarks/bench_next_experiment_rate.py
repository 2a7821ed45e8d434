"""Does the faster log that a Stribeck entry of ``next_experiment`` asks for decide?

Where the data selection's speed bound (9.9) is ten times the velocity's sample-to-sample change rather than 5 % of
the top speed (at 10 Hz up to half of it), a Stribeck law is untestable, and the report's entry names the sample rate
at which the same motion would be selected down to 5 % of the top speed (``sample_rate_hz_needed``).  This script
takes the kept benchmark rows (``bench_diagnose_testbench.py``'s JSONs) where a planted Stribeck law was missed,
diagnoses each log again to read that entry, generates the same spec (same motion, effects, noise and seed) at the
rate the entry asks for, diagnoses it and judges it; as a control it does the same for the kept null logs (nothing
planted) whose report has such an entry: at the faster rate they must stay free of names.

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/bench_next_experiment_rate.py [--lane 0/2] --json out.json
       python benchmarks/bench_next_experiment_rate.py --from-json a.json,b.json [--json merged.json]
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_diagnose_testbench as B  # noqa: E402


def rate_entries(d) -> list:
    """The report's Stribeck entries that ask for a faster log: [(joint, sample_rate_hz_needed)]."""
    return [(int(e["joint"]), float(e["sample_rate_hz_needed"])) for e in d["next_experiment"]
            if e.get("sample_rate_hz_needed")]


def logs_to_check(results_dir=None) -> list:
    """[(family, k, kind)] of the kept rows: ``miss`` where a planted Stribeck law was missed, ``null`` where nothing
    visible was planted (sorted, one per log)."""
    out = set()
    for (fam, _, k), (_, r) in B.kept_rows_naming("any", results_dir).items():
        if fam not in ("loop", "testbench"):
            continue
        if "stribeck" in r.get("missed", []):
            out.add((fam, k, "miss"))
        elif r["truth"] == "none" or r["truth"].startswith("none ("):
            out.add((fam, k, "null"))
    return sorted(out)


def _diagnose(fam, spec):
    """(not-visible effects, report dict or None, refusal or None) of one spec, as the benchmark judges it."""
    from drake_est.diagnose import diagnose
    from drake_est.errors import DataError
    log, truth = B.family_log(fam, spec)
    nv = truth["not_visible"] if fam == "loop" else {}
    try:
        return nv, diagnose(log, robot="generic", seed=0, simulate=False).to_dict(), None
    except DataError as exc:
        return nv, None, str(exc)


def check(lane: str | None = None, null_rates=(10.0,)) -> list:
    """One row per checked log of this lane (see the module docstring); null logs only at ``null_rates`` [Hz]."""
    i, n = B._lane(lane)
    jobs = logs_to_check()
    top = {}
    for fam, k, _ in jobs:
        top[fam] = max(top.get(fam, 0), k)
    specs = {fam: {"testbench": B.cases, "loop": B.loop_cases}[fam](top[fam] + 1) for fam in top}
    jobs = [j for j in jobs if j[2] == "miss" or specs[j[0]][j[1]].get("sample_rate") in null_rates]
    rows = []
    for fam, k, kind in jobs[i::n]:
        spec = specs[fam][k]
        nv, d, refused = _diagnose(fam, spec)
        row = {"family": fam, "k": k, "kind": kind, "sample_rate": spec.get("sample_rate"),
               "truth": B._label(spec["effects"], nv)}
        if d is None:
            rows.append({**row, "refused": refused})
            continue
        row["got"] = B._got(d)
        ent = rate_entries(d)
        row["asks_for_rate_hz"] = max((fs for _, fs in ent), default=None)
        if row["asks_for_rate_hz"]:
            fast = dict(spec, sample_rate=row["asks_for_rate_hz"])
            nv2, d2, refused2 = _diagnose(fam, fast)
            if d2 is None:
                row["at_that_rate"] = {"refused": refused2}
            else:
                row["at_that_rate"] = {"truth": B._label(spec["effects"], nv2), "got": B._got(d2),
                                       **B.judge(fast, d2, optional=nv2)}
        rows.append(row)
        print(f"{fam:9s} {k:5d} {kind:4s} {row['sample_rate']:6g} Hz  {row['got']:40s} -> "
              + (f"{row['asks_for_rate_hz']:5.0f} Hz: {row['at_that_rate'].get('got', 'refused')}"
                 if row.get("asks_for_rate_hz") else "no rate entry"), flush=True)
    return rows


def summarize(rows) -> dict:
    """Counts per kind: logs, logs whose report asks for a faster log, and at that rate: Stribeck named (misses),
    correct, wrong names, logs with any finding (null logs)."""
    out = {}
    for kind in ("miss", "null"):
        rs = [r for r in rows if r["kind"] == kind]
        asked = [r for r in rs if r.get("asks_for_rate_hz")]
        judged = [r["at_that_rate"] for r in asked if "got" in r.get("at_that_rate", {})]
        out[kind] = {"logs": len(rs), "refused": sum("refused" in r for r in rs),
                     "asking_for_a_faster_log": len(asked),
                     "at_that_rate_refused": len(asked) - len(judged),
                     "at_that_rate_correct": sum(j["correct"] for j in judged),
                     "at_that_rate_wrong_names": sum(bool(j["wrong"]) for j in judged),
                     "at_that_rate_with_a_finding": sum(j["got"] not in ("none", "unexplained") for j in judged)}
        if kind == "miss":
            out[kind]["at_that_rate_stribeck_named"] = sum("stribeck" not in j["missed"] for j in judged)
            out[kind]["rates_asked_hz"] = sorted(r["asks_for_rate_hz"] for r in asked)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--lane", help="i/n: every n-th log from the i-th")
    ap.add_argument("--json", help="write rows and summary here")
    ap.add_argument("--from-json", help="comma-separated JSONs of lanes to merge instead of running")
    a = ap.parse_args(argv)
    if a.from_json:
        rows = [r for f in a.from_json.split(",") for r in json.load(open(f))["rows"]]
    else:
        rows = check(a.lane)
    s = summarize(rows)
    print(json.dumps(s, indent=1))
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"summary": s, "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
