"""Does the faster log that an entry of ``next_experiment`` asks for decide?

Where the data selection's speed bound (9.9) is ten times the velocity's sample-to-sample change rather than 5 % of
the top speed (at 10 Hz up to half of it), a Stribeck law is untestable, and the report's entry names the sample rate
at which the same motion would be selected down to 5 % of the top speed (``sample_rate_hz_needed``).  This script
takes the kept benchmark rows (``bench_diagnose_testbench.py``'s JSONs) where a planted Stribeck law was missed,
diagnoses each log again to read that entry, generates the same spec (same motion, effects, noise and seed) at the
rate the entry asks for, diagnoses it and judges it; as a control it does the same for the kept null logs (nothing
planted) whose report has such an entry: at the faster rate they must stay free of names.

``--entry residual-tests`` does the same for the entry that a long derivative window gets (below 60 Hz the 7-sample
window spans more than 0.1 s and the tests of the final residual for a delay, backlash or an elastic gear do not all
run; the entry asks for 60 Hz): the kept rows where a visible out-of-vocabulary effect did not end as `unexplained`
(kind ``oov``) and the kept null logs, both below 60 Hz, where the entry can appear.

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/bench_next_experiment_rate.py [--entry stribeck|residual-tests]
           [--lane 0/2] --json out.json
       python benchmarks/bench_next_experiment_rate.py --from-json a.json,b.json [--json merged.json]
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_diagnose_testbench as B  # noqa: E402


#: the entries this script checks: which report entries ask for a faster log
ENTRIES = ("stribeck", "residual-tests")


def rate_entries(d, entry: str = "stribeck") -> list:
    """The report's entries of kind ``entry`` that ask for a faster log: sample rates [Hz]."""
    if entry == "stribeck":
        return [float(e["sample_rate_hz_needed"]) for e in d["next_experiment"]
                if e.get("sample_rate_hz_needed") and e["reason"].startswith("stribeck")]
    return [float(e["sample_rate_hz_needed"]) for e in d["next_experiment"] if e.get("tests_off")]


def logs_to_check(results_dir=None, entry: str = "stribeck", jsons=None) -> list:
    """[(family, k, kind)] of the kept rows (sorted, one per log; of the kept JSONs named in ``jsons`` only when
    given).  ``stribeck``: ``miss`` where a planted Stribeck law was missed, ``null`` where nothing visible was planted.
    ``residual-tests``: below 60 Hz only, ``oov`` where a visible out-of-vocabulary effect did not end as
    `unexplained`, and ``null``."""
    out = set()
    for (fam, _, k), (name, r) in B.kept_rows_naming("any", results_dir).items():
        if fam not in ("loop", "testbench") or (jsons is not None and name not in jsons):
            continue
        null = r["truth"] == "none" or r["truth"].startswith("none (")
        if entry == "stribeck":
            if "stribeck" in r.get("missed", []):
                out.add((fam, k, "miss"))
            elif null:
                out.add((fam, k, "null"))
        elif r["sample_rate"] < 60.0:
            if not r.get("oov_unexplained", True):
                out.add((fam, k, "oov"))
            elif null:
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


def check(lane: str | None = None, entry: str = "stribeck", at_rate: float | None = None) -> list:
    """One row per checked log of this lane (see the module docstring); for ``stribeck``, null logs at 10 Hz only.
    ``at_rate`` [Hz]: generate the logs whose report asks for a faster log at this rate instead of the one asked for
    (the entries say "or faster")."""
    i, n = B._lane(lane)
    jobs = logs_to_check(entry=entry)
    null_rates = (10.0,) if entry == "stribeck" else (10.0, 25.0, 50.0)
    specs = B._specs_of({(fam, None, k) for fam, k, _ in jobs})
    jobs = [j for j in jobs if j[2] != "null" or specs[j[0]][j[1]].get("sample_rate") in null_rates]
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
        row["asks_for_rate_hz"] = max(rate_entries(d, entry), default=None)
        if row["asks_for_rate_hz"]:
            fast = dict(spec, sample_rate=at_rate or row["asks_for_rate_hz"])
            row["generated_at_hz"] = fast["sample_rate"]
            nv2, d2, refused2 = _diagnose(fam, fast)
            if d2 is None:
                row["at_that_rate"] = {"refused": refused2}
            else:
                row["at_that_rate"] = {"truth": B._label(spec["effects"], nv2), "got": B._got(d2),
                                       **B.judge(fast, d2, optional=nv2)}
        rows.append(row)
        print(f"{fam:9s} {k:5d} {kind:4s} {row['sample_rate']:6g} Hz  {row['got']:40s} -> "
              + (f"{row['generated_at_hz']:5.0f} Hz: {row['at_that_rate'].get('got', 'refused')}"
                 if row.get("asks_for_rate_hz") else "no rate entry"), flush=True)
    return rows


def summarize(rows) -> dict:
    """Counts per kind: logs, logs whose report asks for a faster log, and at that rate: Stribeck named (misses),
    correct, wrong names, logs with any finding (null logs)."""
    out = {}
    for kind in [k for k in ("miss", "oov", "null") if any(r["kind"] == k for r in rows)]:
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
        if kind == "oov":
            out[kind]["at_that_rate_unexplained"] = sum(j["oov_unexplained"] for j in judged)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--entry", default="stribeck", choices=ENTRIES, help="which entries' faster logs to check")
    ap.add_argument("--lane", help="i/n: every n-th log from the i-th")
    ap.add_argument("--at-rate", type=float, help="generate the faster logs at this rate [Hz] instead of the one asked")
    ap.add_argument("--json", help="write rows and summary here")
    ap.add_argument("--from-json", help="comma-separated JSONs of lanes to merge instead of running")
    a = ap.parse_args(argv)
    entry, at_rate = a.entry, a.at_rate
    if a.from_json:
        parts = [json.load(open(f)) for f in a.from_json.split(",")]
        entry, at_rate = parts[0].get("entry", "stribeck"), parts[0].get("at_rate")
        if any((p.get("entry", "stribeck"), p.get("at_rate")) != (entry, at_rate) for p in parts):
            raise SystemExit("--from-json: the lanes were run with different --entry or --at-rate")
        rows = [r for p in parts for r in p["rows"]]
        kept = parts[0].get("kept_jsons")
        if any(p.get("kept_jsons") != kept for p in parts):
            raise SystemExit("--from-json: the lanes read different kept JSONs")
    else:
        rows = check(a.lane, entry, at_rate)
        kept = [f.name for f in B.kept_jsons()]
    s = summarize(rows)
    print(json.dumps(s, indent=1))
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"entry": entry, "at_rate": at_rate, "kept_jsons": kept, "summary": s, "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
