"""Where the next experiment points at a candidate whose held-out gain sits in a few stretches of the log.

A candidate of the last round that passes the held-out F-test and the gain but not the paired block test, with most
of its gain in a few of the paired groups (:func:`drake_est.diagnose.competition.gain_concentration`), gets a
``next_experiment`` entry: repeat what the log does in those stretches often enough for the paired test to
decide.  This script diagnoses a range of benchmark specs and counts, per kind of log (null, out-of-vocabulary,
vocabulary), the logs that get such an entry; for the vocabulary logs it counts the misses whose missed effect
the entry names (the experiment points at what is missing) and the entries that name only effects that were not
planted (the experiment asks about something that is not there: no cause is named, but the user spends a run).

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/bench_next_experiment.py --family loop --start 4300 --n 300
           [--lane 0/2] --json out.json
       python benchmarks/bench_next_experiment.py --from-json a.json,b.json [--json merged.json]
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_diagnose_testbench as B  # noqa: E402
import bench_unexplained_shares as S  # noqa: E402
from bench_unexplained_shares import KINDS, kind  # noqa: E402


def repeat_entries(d) -> list:
    """The report's repeat-the-stretches entries: effects (the describing one first), joint, repeats needed."""
    return [{"effects": [e["effect"]] + [a["effect"] for a in e.get("also", [])], "joint": e["joint"],
             "repeats_needed": e["repeats_needed"], "stretches": [s["t_s"] for s in e["stretches"]]}
            for e in d["next_experiment"] if e.get("stretches")]


def collect(family: str, start: int, n: int, lane: str | None = None) -> list:
    """Diagnose specs start .. start+n-1 of ``family`` (this lane's share): per log, what is planted, what the
    benchmark's judge says, and the repeat entries."""
    rows = []
    for k, spec, truth, rep, refused in S.diagnosed_specs(family, start, n, lane, "next experiments"):
        if rep is None:
            rows.append(refused)
            continue
        d = rep.to_dict()
        nv = (truth.get("not_visible") if family == "loop" else None) or {}
        j = B.judge(spec, d, optional=nv)
        rows.append({"k": k, "family": family, "planted": [e for e in spec["effects"] if not e.startswith("_")],
                     "not_visible": sorted(nv), "sample_rate": spec["sample_rate"], "got": B._got(d),
                     "wrong": j["wrong"], "missed": j["missed"], "repeat": repeat_entries(d)})
    return rows


def summary(rows) -> dict:
    rows = [r for r in rows if "repeat" in r]
    by = {k: [r for r in rows if kind(r) == k] for k in KINDS}
    vocab = by["vocab"]
    missed = [r for r in vocab if r["missed"]]
    points = [r["k"] for r in missed if any(set(e["effects"]) & set(r["missed"]) for e in r["repeat"])]
    planted = lambda r: set(r["planted"])  # noqa: E731
    only_absent = [r["k"] for r in rows if r["repeat"] and
                   any(not (set(e["effects"]) & planted(r)) for e in r["repeat"])]
    return {"logs": len(rows), "kinds": {k: len(v) for k, v in by.items()},
            "logs_with_a_repeat_entry": {k: [r["k"] for r in v if r["repeat"]] for k, v in by.items()},
            "vocab_logs_with_a_miss": [r["k"] for r in missed],
            "misses_the_entry_points_at": points,
            "logs_with_an_entry_naming_only_unplanted_effects": only_absent,
            "repeats_needed": sorted({e["repeats_needed"] for r in rows for e in r["repeat"]},
                                     key=lambda x: (x is None, x or 0))}


def table_lines(s, label) -> list:
    """The docs' row of one summary (tests/test_diagnose_gain_concentration.py checks it)."""
    w = s["logs_with_a_repeat_entry"]
    return ["| logs | null / out-of-vocabulary / vocabulary | with a repeat entry: null / out-of-vocabulary / "
            "vocabulary | vocabulary logs with a miss | misses the entry points at | logs with an entry naming only "
            "effects not planted |", "|---|---|---|---|---|---|",
            f"| {label} | {s['kinds']['null']} / {s['kinds']['oov']} / {s['kinds']['vocab']} | {len(w['null'])} / "
            f"{len(w['oov'])} / {len(w['vocab'])} | {len(s['vocab_logs_with_a_miss'])} | "
            f"{len(s['misses_the_entry_points_at'])} | {len(s['logs_with_an_entry_naming_only_unplanted_effects'])} |"]


def main(argv=None):
    ap = argparse.ArgumentParser()
    S.block_arguments(ap)
    a = ap.parse_args(argv)
    if a.from_json:
        rows = sorted((r for f in a.from_json.split(",") for r in json.load(open(f))["rows"]),
                      key=lambda r: (r["family"], r["k"]))
    else:
        rows = collect(a.family, a.start, a.n, a.lane)
    out = {"rows": rows, **summary(rows)}
    print("\n".join(table_lines(out, f"{len(rows)} logs")))
    for key in ("vocab_logs_with_a_miss", "misses_the_entry_points_at",
                "logs_with_an_entry_naming_only_unplanted_effects"):
        print(f"{key}: {out[key]}")
    print(f"with a repeat entry: {out['logs_with_a_repeat_entry']}")
    if a.json:
        S.write_compact(out, a.json)
    return out


if __name__ == "__main__":
    main()
