"""What the tests of the "unexplained" verdict read on logs whose truth is known: the null tail of each test's share.

Every test of :func:`drake_est.diagnose.unexplained.residual_structure` reports a structure when its p-value is
below the Bonferroni level *and* it holds a minimum share of the residual variance (``MIN_SHARE`` and the per-test
shares).  This script diagnoses the logs of a range of benchmark specs (``--family loop``: the closed-loop
generator's specs, ``testbench``: the open-loop testbench's) and keeps, per log, what every test of the final
residual read (``DiagnosisResult.structure_readings``: p-value, share, whether the ADC guard holds it back).  From
those it prints, per test, the largest share among null logs where the test was significant (the null tail a share
threshold must clear), and, for other share thresholds of one test, how many null, out-of-vocabulary and
vocabulary logs would gain an entry (the other rules as in the code).

The readings are those of the code that ran; a threshold changed here changes the search only through the
not-confirmed and separation rules, which read the entries (run the diagnosis benchmark again to see that).

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/bench_unexplained_shares.py --family loop --start 3500 --n 1000
           [--lane 0/2] --json out.json
       python benchmarks/bench_unexplained_shares.py --from-json a.json,b.json [--test time_shift_torque_vs_position
           --shares 0.005,0.01,0.02]
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_diagnose_testbench as B  # noqa: E402

KINDS = ("null", "oov", "vocab")


def kind(row) -> str:
    """null (nothing planted), oov (an out-of-vocabulary effect that is visible), vocab (the rest)."""
    planted = set(row["planted"]) - set(row["not_visible"])
    if not row["planted"]:
        return "null"
    return "oov" if planted & (set(B.OOV) | set(B.LOOP_OOV)) else "vocab"


def diagnosed_specs(family: str, start: int, n: int, lane: str | None = None, desc: str = ""):
    """Diagnose specs start .. start+n-1 of ``family`` (this lane's share, ``--lane I/N``) with the generic axis:
    yields (k, spec, truth, report, refused): the report, or None and the row {"k", "family", "refused"} of a log
    the diagnosis refuses with a one-line DataError."""
    from drake_est.diagnose import diagnose
    from drake_est.errors import DataError
    from drake_est.progress import progress
    specs = {"loop": B.loop_cases, "testbench": B.cases}[family](start + n)
    i, m = B._lane(lane)
    for k in progress(range(start + i, start + n, m), desc=f"{family} {desc}".strip()):
        spec = specs[k]
        log, truth = B.family_log(family, spec)
        try:
            rep, refused = diagnose(log, robot="generic", seed=0, simulate=False), None
        except DataError as e:
            rep, refused = None, {"k": k, "family": family, "refused": str(e)}
        yield k, spec, truth, rep, refused


def block_arguments(ap) -> None:
    """The command-line options of a script that diagnoses a block of benchmark specs (:func:`diagnosed_specs`)
    or merges earlier runs (lanes)."""
    ap.add_argument("--family", default="loop", choices=["loop", "testbench"])
    ap.add_argument("--start", type=int, default=0)
    ap.add_argument("--n", type=int, default=100)
    ap.add_argument("--lane", default=None, metavar="I/N")
    ap.add_argument("--json", default=None)
    ap.add_argument("--from-json", default=None, help="comma-separated outputs of earlier runs (lanes) to merge")


def write_compact(out, path) -> None:
    """``out`` as compact strict JSON (thousands of rows: dump_json indents, which doubles the size)."""
    from drake_est.jsonutil import to_jsonable
    Path(path).write_text(json.dumps(out, separators=(",", ":"), default=to_jsonable, allow_nan=False))


def collect(family: str, start: int, n: int, lane: str | None = None) -> list:
    """Diagnose specs start .. start+n-1 of ``family`` (this lane's share) and keep each log's test readings."""
    rows = []
    for k, spec, truth, rep, refused in diagnosed_specs(family, start, n, lane, "readings"):
        if rep is None:
            rows.append(refused)
            continue
        nv = truth.get("not_visible") if family == "loop" else None
        rows.append({"k": k, "family": family, "planted": [e for e in spec["effects"] if not e.startswith("_")],
                     "not_visible": sorted((nv or {}).keys()), "sample_rate": spec["sample_rate"],
                     "duration": spec["duration"], "noise": spec.get("noise", "gaussian"), "findings": rep.effects,
                     "unexplained": [u["variable"] for u in rep.result.unexplained],
                     "readings": rep.result.structure_readings})
    return rows


def need(variable: str, shares: dict | None = None) -> float:
    """The share a test's structure must hold (the code's, :func:`~drake_est.diagnose.unexplained.share_needed`;
    ``shares`` overrides per test)."""
    from drake_est.diagnose.unexplained import share_needed
    if shares and variable in shares:
        return shares[variable]
    return share_needed(variable)


def entries(row, shares: dict | None = None) -> set:
    """The variables the non-reversal tests report for this log's readings under the share thresholds."""
    from drake_est.diagnose.unexplained import ALPHA_UNEXPLAINED
    out = set()
    for r in row["readings"]:
        if r["variable"] == "velocity_reversals" or r["adc_guarded"]:
            continue
        if r["p_value"] < ALPHA_UNEXPLAINED / r["n_tests"] and r["share"] >= need(r["variable"], shares):
            out.add((r["joint"], r["variable"]))
    return out


def null_tails(rows) -> dict:
    """Per test: per kind, the logs where it was significant (not held back by the ADC guard), and the largest share
    among the null ones."""
    from drake_est.diagnose.unexplained import ALPHA_UNEXPLAINED
    out = {}
    for row in rows:
        for r in row["readings"]:
            if r["variable"] == "velocity_reversals" or r.get("adc_guarded"):
                continue
            if r["p_value"] < ALPHA_UNEXPLAINED / r["n_tests"]:
                t = out.setdefault(r["variable"], {"significant": {k: 0 for k in KINDS}, "null_max_share": None,
                                                   "null_max_share_k": None})
                t["significant"][kind(row)] += 1
                if kind(row) == "null" and (t["null_max_share"] is None or r["share"] > t["null_max_share"]):
                    t["null_max_share"], t["null_max_share_k"] = r["share"], row["k"]
    return out


def variants(rows, test: str, shares) -> list:
    """For each share threshold of ``test``: the logs of each kind that gain or lose an entry against the code's."""
    out = []
    for s in shares:
        gain = {k: [] for k in KINDS}
        lose = {k: [] for k in KINDS}
        for row in rows:
            a, b = entries(row), entries(row, {test: s})
            if b - a and not a:
                gain[kind(row)].append(row["k"])
            if a and not b:
                lose[kind(row)].append(row["k"])
        out.append({"test": test, "share": s, "logs_gaining_an_entry": gain, "logs_losing_every_entry": lose})
    return out


def summary(rows, test=None, shares=()) -> dict:
    rows = [r for r in rows if "readings" in r]
    counts = {k: sum(kind(r) == k for r in rows) for k in KINDS}
    with_entry = {k: sum(bool(entries(r)) for r in rows if kind(r) == k) for k in KINDS}
    out = {"logs": len(rows), "kinds": counts, "logs_with_an_entry_of_these_tests": with_entry,
           "null_tails": null_tails(rows)}
    if test:
        out["variants"] = variants(rows, test, shares)
    return out


def table_lines(s) -> list:
    """The per-test table of a summary (the docs quote it; tests/test_diagnose_structure_readings.py checks it)."""
    out = ["| test | share needed | significant in null / out-of-vocabulary / vocabulary logs | largest share, null (log) |",
           "|---|---|---|---|"]
    for name, t in sorted(s["null_tails"].items()):
        sg = t["significant"]
        mx = "—" if t["null_max_share"] is None else f"{t['null_max_share']:.4f} ({t['null_max_share_k']})"
        out.append(f"| {name} | {need(name):g} | {sg['null']} / {sg['oov']} / {sg['vocab']} | {mx} |")
    return out


def print_summary(s) -> None:
    print(f"{s['logs']} logs {s['kinds']}; with an entry of the share-thresholded tests: "
          f"{s['logs_with_an_entry_of_these_tests']}")
    print("\n".join(table_lines(s)))
    for v in s.get("variants", []):
        g, lo = v["logs_gaining_an_entry"], v["logs_losing_every_entry"]
        print(f"{v['test']} at {v['share']:g}: logs gaining an entry: null {len(g['null'])} {g['null'][:8]}, "
              f"out-of-vocabulary {len(g['oov'])} {g['oov'][:12]}, vocabulary {len(g['vocab'])}; losing every entry: "
              f"null {len(lo['null'])}, out-of-vocabulary {len(lo['oov'])} {lo['oov'][:12]}, vocabulary {len(lo['vocab'])}")


def main(argv=None):
    ap = argparse.ArgumentParser()
    block_arguments(ap)
    ap.add_argument("--test", default=None, help="with --shares: the test whose share threshold is varied")
    ap.add_argument("--shares", default="", help="comma-separated share thresholds for --test")
    a = ap.parse_args(argv)
    if a.from_json:
        rows = [r for f in a.from_json.split(",") for r in json.load(open(f))["rows"]]
    else:
        rows = collect(a.family, a.start, a.n, a.lane)
    shares = [float(x) for x in a.shares.split(",") if x]
    out = {"rows": rows, **summary(rows, a.test, shares)}
    print_summary(out)
    if a.json:
        write_compact(out, a.json)
    return out


if __name__ == "__main__":
    main()
