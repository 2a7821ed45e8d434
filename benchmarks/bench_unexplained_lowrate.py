"""False alarms and detections of the "unexplained" verdict, by sample rate (issue 16 item 3).

Null logs (no effect) and out-of-vocabulary logs (delay between torque and position samples, backlash) of
the independent generator :mod:`drake_est.diagnose.testbench`, Gaussian / Student-t / quantized noise in
turn, noise level drawn in 0.02-0.1; optionally null logs of :mod:`drake_est.synth` (IRB 140 simulation,
diagnosed as a generic axis).  For every log: whether ``unexplained`` is empty, which tests fired, and the
p-value of the reversal-impulse test (:func:`drake_est.diagnose.unexplained.reversal_impulse`).

A null log with a non-empty ``unexplained`` is a false alarm; an out-of-vocabulary log with an empty one, or
with a vocabulary name, is a miss.

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/bench_unexplained_lowrate.py --null 60 --oov 6 \\
           --rates 10,50,250 --json out.json [--synth 4]
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

os.environ.setdefault("DRAKE_EST_NO_PROGRESS", "1")

NOISES = ("gaussian", "student_t", "quantized")


def _one(log, robot="generic"):
    from drake_est.diagnose import diagnose
    from drake_est.diagnose.unexplained import reversal_impulse
    t0 = time.perf_counter()
    rep = diagnose(log, robot=robot, seed=0, simulate=False)
    res = rep.result
    res.final_fit._model = res.final_model
    d = rep.to_dict()
    ps = []
    for j in res.prep.joints:
        r = reversal_impulse(res.prep, res.final_fit, j)
        if r is not None:
            ps.append(r["p"])
    return {"findings": [f["effect"] for f in d["findings"]], "unexplained": [u["variable"] for u in d["unexplained"]],
            "reversal_p": min(ps) if ps else None, "seconds": time.perf_counter() - t0}


def run(n_null=60, n_oov=6, rates=(10.0,), n_synth=0, duration=120.0, seed0=9000):
    from drake_est.diagnose.testbench import generate
    rows = []
    for rate in rates:
        for kind, effects, n in (("null", {}, n_null), ("delay", {"delay": 1.0}, n_oov), ("backlash", {"backlash": 1.0}, n_oov)):
            for k in range(n):
                s = seed0 + k
                rng = np.random.default_rng(s)
                noise = NOISES[k % 3]
                log, _ = generate(effects, seed=s, duration=duration, sample_rate=rate, noise=noise,
                                  noise_std=float(rng.uniform(0.02, 0.1)))
                r = _one(log)
                rows.append({"generator": "testbench", "kind": kind, "rate": rate, "noise": noise, "seed": s, **r})
                print(rows[-1], flush=True)
    if n_synth:
        from drake_est.data import Log
        from drake_est.synth import synthesize
        for rate in rates:
            for k in range(n_synth):
                log, _ = synthesize("none", seed=seed0 + k, duration=300.0, sample_rate=rate)
                log = Log(t=log.t, q=log.q, tau=log.tau, joints=log.joints)
                r = _one(log)
                rows.append({"generator": "synth", "kind": "null", "rate": rate, "noise": "gaussian", "seed": seed0 + k, **r})
                print(rows[-1], flush=True)
    return summarize(rows)


def summarize(rows) -> dict:
    out = {"rows": rows, "by_rate": {}}
    for gen in sorted({r["generator"] for r in rows}):
        for rate in sorted({r["rate"] for r in rows if r["generator"] == gen}):
            R = [r for r in rows if r["generator"] == gen and r["rate"] == rate]
            null = [r for r in R if r["kind"] == "null"]
            oov = [r for r in R if r["kind"] != "null"]
            ps = [r["reversal_p"] for r in null if r["reversal_p"] is not None]
            out["by_rate"][f"{gen}@{rate:g}Hz"] = {
                "null_logs": len(null),
                "null_false_alarms": sum(bool(r["unexplained"]) or bool(r["findings"]) for r in null),
                "null_unexplained": sum(bool(r["unexplained"]) for r in null),
                "null_reversal_flags": sum("velocity_reversals" in r["unexplained"] for r in null),
                "null_reversal_tested": len(ps),
                "null_reversal_p_min": min(ps) if ps else None,
                "null_reversal_p_below_0.01": sum(p < 0.01 for p in ps),
                "oov_logs": len(oov),
                "oov_unexplained_no_name": sum(bool(r["unexplained"]) and not r["findings"] for r in oov),
                "oov_reversal_flags": sum("velocity_reversals" in r["unexplained"] for r in oov),
                "oov_named": sum(bool(r["findings"]) for r in oov),
            }
    return out


def markdown_rows(summary) -> list:
    """Rows of the docs' table (docs/readme/diagnose_testbench.md, "Unexplained at low sample rates") for the
    testbench rates of a summary: rate, null logs with ``unexplained`` (reversal test / any test), the smallest
    null p of the reversal test, out-of-vocabulary logs unexplained with no name (per kind)."""
    out = []
    for key, b in summary["by_rate"].items():
        gen, rate = key.split("@")
        if gen != "testbench":
            continue
        rows = [r for r in summary["rows"] if r["generator"] == gen and f"{r['rate']:g}Hz" == rate]
        kinds = sorted({r["kind"] for r in rows if r["kind"] != "null"})
        per = ", ".join(f"{k} {sum(bool(r['unexplained']) and not r['findings'] for r in rows if r['kind'] == k)}/"
                        f"{sum(r['kind'] == k for r in rows)}" for k in kinds)
        pmin = "n/a" if b["null_reversal_p_min"] is None else f"{b['null_reversal_p_min']:.2g}"
        out.append(f"| {rate[:-2]} Hz | {b['null_reversal_flags']}/{b['null_logs']} / {b['null_unexplained']}/{b['null_logs']} | "
                   f"{pmin} | {b['oov_unexplained_no_name']}/{b['oov_logs']} ({per}) |")
    return out


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--null", type=int, default=60)
    ap.add_argument("--oov", type=int, default=6)
    ap.add_argument("--rates", default="10")
    ap.add_argument("--synth", type=int, default=0)
    ap.add_argument("--json", default=None)
    ap.add_argument("--markdown", default=None, help="comma-separated JSONs of earlier runs: print the docs' table rows")
    a = ap.parse_args(argv)
    import json
    if a.markdown:
        for f in a.markdown.split(","):
            print("\n".join(markdown_rows(json.load(open(f)))))
        return None
    rates = tuple(float(x) for x in a.rates.split(","))
    out = run(a.null, a.oov, rates, a.synth)
    print(json.dumps(out["by_rate"], indent=1))
    if a.json:
        from drake_est.jsonutil import dump_json
        dump_json(out, a.json)
    return out


if __name__ == "__main__":
    main()
