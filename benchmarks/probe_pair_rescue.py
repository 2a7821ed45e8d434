"""The seventieth round's probe: two effects of one joint that mask each other, let through together.

Forward selection adds one law per round.  Where two effects share a joint, each alone leaves the other's misfit, its
held-out gain sits in a few blocks, the paired block test holds it back, and the search stops with neither named
(loop spec 19128 with its position reference moved by one ulp).  This probe sets ``core.PAIR_RESCUE = True``
(``core.pair_rescue``; rule: ``benchmarks/results/diagnose_pair_rescue_round70_rule.txt``) and, for each kept log it
is given, generates and diagnoses it, counts how often the rule let a pair through, and where it did stores the row
beside its kept row (a log where it never did gets the kept row's diagnosis: the rule changes nothing else).

    python benchmarks/probe_pair_rescue.py --keys missed > ka.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_pair_rescue.py OUT.json $(cat ka.txt)
    python benchmarks/probe_pair_rescue.py --keys testbench > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_pair_rescue.py --family=testbench OUT.json $(cat kt.txt)
    python benchmarks/probe_pair_rescue.py --table-row A.json B.json

``--keys CLASS``: ``missed`` (kept closed-loop rows with a missed effect), ``null_oov`` (null and out-of-vocabulary
closed-loop rows), ``other`` (the remaining closed-loop rows), ``testbench`` (every open-loop testbench row); each in
a seeded random order (``--seed``, default 70).  Writes OUT.json every ten logs (``examined`` says how far a stopped
run got).  Rows are classified as in the sixty-seventh round's probe (``probe_jitter_second_differences``).
"""
from __future__ import annotations

import os
import random
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_diagnose_testbench as B  # noqa: E402
from probe_jitter_second_differences import classify, report_cli, summary, table_row  # noqa: E402,F401  (re-exported)

OOV = ("backlash", "compliance", "sensor_delay")
CLASSES = ("missed", "null_oov", "other", "testbench")


def row_class(family: str, r: dict) -> str:
    """The probe's class of a kept row (:data:`CLASSES`)."""
    if family == "testbench":
        return "testbench"
    if r["missed"]:
        return "missed"
    if r["truth"] == "none" or r["truth"] in OOV:
        return "null_oov"
    return "other"


def sample_keys(cls: str, seed: int = 70) -> list:
    """The kept logs of class ``cls`` (:data:`CLASSES`) in a seeded random order."""
    if cls not in CLASSES:
        raise SystemExit(f"--keys: expected one of {', '.join(CLASSES)}, got {cls!r}")
    family = "testbench" if cls == "testbench" else "loop"
    ks = sorted({k for (f, _, k), (_, r) in B.kept_rows_naming("any").items()
                 if f == family and row_class(f, r) == cls})
    return random.Random(seed).sample(ks, len(ks))


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; store the rows of the logs where it let a pair
    through."""
    from drake_est.diagnose import core
    if family not in ("loop", "testbench"):
        raise SystemExit(f"--family must be loop or testbench, got {family!r}")
    kept = {k: v for (f, _, k), v in B.kept_rows_naming("any").items() if f == family}
    missing = [k for k in keys if k not in kept]
    if missing:
        raise SystemExit(f"no kept {family} row for k = {missing[0]} ({len(missing)} such)")
    make = B.loop_cases if family == "loop" else B.cases
    was_on, core.PAIR_RESCUE = core.PAIR_RESCUE, True
    rule = core.pair_rescue
    let_through = []

    def counted(*a, **kw):
        got = rule(*a, **kw)
        if got is not None:
            info = got[2]
            let_through.append({"effect": got[0][0].effect, "partner": info["partner"], "joint": info["joint"],
                                "paired_p_value_of_both": info["paired_p_value_of_both"]})
        return got

    core.pair_rescue = counted
    res = {"rule": "PAIR_RESCUE", "family": family, "examined": 0, "keys_examined": [], "classes_examined": {},
           "touched": [], "rows": [], "refused": []}
    try:
        for m, k in enumerate(keys):
            spec = make(k + 1)[k]
            let_through.clear()
            rows = []
            B._run_family(family, [spec], rows, k, res["refused"])
            res["examined"] += 1
            res["keys_examined"].append(k)
            c = row_class(family, kept[k][1])
            res["classes_examined"][c] = res["classes_examined"].get(c, 0) + 1
            if let_through:
                res["touched"].append({"k": k, "class": c, "let_through": list(let_through)})
                for r in rows:
                    r["kept_json"], r["kept_row"] = kept[k][0], kept[k][1]
                    res["rows"].append(r)
            if m % 10 == 9:
                B._write_json(res, out_path)
    finally:
        core.pair_rescue = rule
        core.PAIR_RESCUE = was_on
    B._write_json(res, out_path)
    return res


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "--keys":
        import argparse
        ap = argparse.ArgumentParser()
        ap.add_argument("--keys", choices=CLASSES, required=True)
        ap.add_argument("--seed", type=int, default=70)
        a = ap.parse_args(argv)
        print(" ".join(str(k) for k in sample_keys(a.keys, a.seed)))
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
