"""Synth's null logs with the reference's knots on the samples and between them: where the "unexplained" entries of
synth's null logs at 100 Hz come from.

:func:`drake_est.synth.synthesize` follows a cubic Hermite reference with knots every 20 ms; its desired
acceleration, and with it the computed-torque controller's torque, jumps at each knot.  At rates that divide 50 Hz
every knot falls on a sample, where the logged torque is the value after the jump while the smoothed acceleration
sees both sides.  This script diagnoses synth null logs (nothing planted, joint 1 sweeping; stripped to t, q, tau
as ``bench_unexplained_lowrate.py`` does) with the knots where they are (``knot_offset`` 0) and moved by half a
sample period, and keeps what each reports.

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/bench_synth_knots.py --seeds 9000,9001,9002,9003 --rates 100,250
           [--lane 0/2] --json out.json
       python benchmarks/bench_synth_knots.py --from-json a.json,b.json [--json merged.json]
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_diagnose_testbench as B  # noqa: E402


def one(seed: int, rate: float, offset: float) -> dict:
    from drake_est.data import Log
    from drake_est.diagnose import diagnose
    from drake_est.synth import synthesize
    log, _ = synthesize("none", seed=seed, duration=300.0, sample_rate=rate, knot_offset=offset)
    log = Log(t=log.t, q=log.q, tau=log.tau, joints=log.joints)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    return {"seed": seed, "rate": rate, "knot_offset_s": offset, "findings": [f["effect"] for f in d["findings"]],
            "unexplained": [{"joint": u["joint"], "variable": u["variable"],
                             "share": u["share_of_residual_variance"]} for u in d["unexplained"]]}


def summary(rows) -> dict:
    """Per rate and knot placement: logs, logs with a finding, logs with an "unexplained" entry."""
    out = {}
    for r in rows:
        key = f"{r['rate']:g} Hz, knots {'on the samples' if r['knot_offset_s'] == 0 else 'between the samples'}"
        s = out.setdefault(key, {"logs": 0, "with_a_finding": 0, "with_an_unexplained_entry": 0, "largest_share": 0.0})
        s["logs"] += 1
        s["with_a_finding"] += bool(r["findings"])
        s["with_an_unexplained_entry"] += bool(r["unexplained"])
        s["largest_share"] = max([s["largest_share"]] + [u["share"] for u in r["unexplained"]])
    return out


def table_lines(s) -> list:
    """The docs' table (tests/test_diagnose_stribeck_backfit.py checks it is printed from the kept JSON)."""
    out = ["| synth null logs | logs | with a finding | with an `unexplained` entry | largest share |",
           "|---|---|---|---|---|"]
    for key, v in s.items():
        out.append(f"| {key} | {v['logs']} | {v['with_a_finding']} | {v['with_an_unexplained_entry']} | "
                   f"{v['largest_share']:.2f} |")
    return out


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", default="9000,9001,9002,9003")
    ap.add_argument("--rates", default="100")
    ap.add_argument("--lane", default=None, metavar="I/N")
    ap.add_argument("--json", default=None)
    ap.add_argument("--from-json", default=None, help="comma-separated outputs of earlier runs (lanes) to merge")
    a = ap.parse_args(argv)
    if a.from_json:
        rows = [r for f in a.from_json.split(",") for r in json.load(open(f))["rows"]]
    else:
        from drake_est.progress import progress
        jobs = [(int(s), float(r), o) for r in a.rates.split(",") for s in a.seeds.split(",")
                for o in (0.0, 0.5 / float(r))]
        i, n = B._lane(a.lane)
        rows = [one(*job) for job in progress(jobs[i::n], desc="synth knots")]
    rows = sorted(rows, key=lambda r: (r["rate"], r["knot_offset_s"], r["seed"]))
    out = {"rows": rows, "summary": summary(rows)}
    print("\n".join(table_lines(out["summary"])))
    if a.json:
        from drake_est.jsonutil import dump_json
        dump_json(out, a.json)
    return out


if __name__ == "__main__":
    main()
