"""The sixty-eighth round's probe: laws of the friction in time held back by the ADC guard, judged by the readings.

On a quantized torque the ADC guard (``core._above_quantization``) keeps a candidate only where it changes the
held-out prediction by more than half a step; a drift of the friction over minutes changes it by less on every
sample, so 51 kept closed-loop rows at 50 Hz (an energy drift over 600 s, mostly a quantized torque) end as "none"
with F-tests of p = 0.  This probe sets ``core.TIME_LAWS_BY_READINGS_LIKELIHOOD = True`` (a law in time held back by
the guard is kept when the likelihood of the quantized readings favours it: ``core.time_law_beyond_rounding``) and,
for each kept closed-loop log it is given, generates and diagnoses it, counts how often the rule kept a candidate the
guard held back, and where it did stores the row beside its kept row (a log where it never did gets the kept row's
diagnosis: the rule changes nothing else).

    python benchmarks/probe_time_laws_readings_likelihood.py --keys --noise quantized --seed 68 > ks.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_time_laws_readings_likelihood.py OUT.json $(cat ks.txt)
    python benchmarks/probe_time_laws_readings_likelihood.py --table-row A.json B.json

    python benchmarks/probe_time_laws_readings_likelihood.py --keys --family testbench > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_time_laws_readings_likelihood.py --family=testbench OUT.json $(cat kt.txt)

``--keys`` options: ``--family`` (loop, testbench), ``--noise`` (quantized), ``--missed EFFECT`` (only kept rows missing it), ``--truth none|oov|any``,
``--sample-rate HZ``, ``--seed`` (a seeded random order).  Writes OUT.json every ten logs (``examined`` says how far
a stopped run got).  Rows are sorted as in the sixty-seventh round's probe (``probe_jitter_second_differences``).
"""
from __future__ import annotations

import os
import random
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_diagnose_testbench as B  # noqa: E402
from probe_jitter_second_differences import classify, report_cli, summary, table_row  # noqa: E402,F401  (re-exported for the docs test)

OOV = ("backlash", "compliance", "sensor_delay")


def sample_keys(noise: str | None = "quantized", missed: str | None = None, truth: str = "any",
                sample_rate: float | None = None, seed: int = 68, family: str = "loop") -> list:
    """Kept logs of ``family`` with this ``noise``, ``missed`` effect, ``truth`` class (``none``: null logs, ``oov``: out
    of the vocabulary, ``any``) and ``sample_rate`` [Hz], in a seeded random order."""
    ks = []
    for (f, _, k), (_, r) in B.kept_rows_naming("any", sample_rate=sample_rate).items():
        if f != family or (noise is not None and r.get("noise", "gaussian") != noise):
            continue
        if missed is not None and missed not in r["missed"]:
            continue
        if truth == "none" and r["truth"] != "none":
            continue
        if truth == "oov" and r["truth"] not in OOV:
            continue
        ks.append(k)
    ks.sort()
    return random.Random(seed).sample(ks, len(ks))


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` (``loop``: the closed-loop generator; ``testbench``: the
    open-loop one) with the rule on; store the rows of the logs where it let a candidate through."""
    from drake_est.diagnose import core
    if family not in ("loop", "testbench"):
        raise SystemExit(f"--family must be loop or testbench, got {family!r}")
    kept = {k: v for (f, _, k), v in B.kept_rows_naming("any").items() if f == family}
    missing = [k for k in keys if k not in kept]
    if missing:
        raise SystemExit(f"no kept {family} row for k = {missing[0]} ({len(missing)} such)")
    make = B.loop_cases if family == "loop" else B.cases
    core.TIME_LAWS_BY_READINGS_LIKELIHOOD = True
    rule = core.time_law_beyond_rounding
    kept_by_rule = []

    def counted(prep, model, ext, *a, **kw):
        got = rule(prep, model, ext, *a, **kw)
        if got is not None:
            kept_by_rule.append({"effect": ext.effect, "joint": int(ext.joint),
                                 "heldout_loglik_gain_profiled": got["heldout_loglik_gain_profiled"],
                                 "rounding_lr_bound": got["rounding_lr_bound"]})
        return got

    core.time_law_beyond_rounding = counted
    res = {"rule": "TIME_LAWS_BY_READINGS_LIKELIHOOD", "family": family, "examined": 0, "keys_examined": [], "touched": [], "rows": [],
           "refused": []}
    try:
        for m, k in enumerate(keys):
            spec = make(k + 1)[k]
            kept_by_rule.clear()
            rows = []
            B._run_family(family, [spec], rows, k, res["refused"])
            res["examined"] += 1
            res["keys_examined"].append(k)
            if kept_by_rule:
                res["touched"].append({"k": k, "kept_by_rule": list(kept_by_rule)})
                for r in rows:
                    r["kept_json"], r["kept_row"] = kept[k][0], kept[k][1]
                    res["rows"].append(r)
            if m % 10 == 9:
                B._write_json(res, out_path)
    finally:
        core.time_law_beyond_rounding = rule
        core.TIME_LAWS_BY_READINGS_LIKELIHOOD = False
    B._write_json(res, out_path)
    return res


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "--keys":
        import argparse
        ap = argparse.ArgumentParser()
        ap.add_argument("--keys", action="store_true")
        ap.add_argument("--noise", default="quantized")
        ap.add_argument("--missed", default=None)
        ap.add_argument("--truth", choices=("any", "none", "oov"), default="any")
        ap.add_argument("--sample-rate", type=float, default=None)
        ap.add_argument("--seed", type=int, default=68)
        ap.add_argument("--family", choices=("loop", "testbench"), default="loop")
        a = ap.parse_args(argv)
        noise = None if a.noise == "any" else a.noise
        print(" ".join(str(k) for k in sample_keys(noise, a.missed, a.truth, a.sample_rate, a.seed, a.family)))
        return
    if report_cli(argv):
        return
    family = "loop"
    if argv and argv[0].startswith("--family="):
        family = argv.pop(0).split("=", 1)[1]
    if len(argv) < 2:
        raise SystemExit(__doc__)
    try:
        keys = [int(x) for x in argv[1:]]
    except ValueError as e:
        raise SystemExit(f"expected spec numbers after OUT.json: {e}")
    res = run(argv[0], keys, family)
    print(f"examined {res['examined']}, rule fired in {len(res['touched'])}, diagnosed {len(res['rows'])}")


if __name__ == "__main__":
    main()
