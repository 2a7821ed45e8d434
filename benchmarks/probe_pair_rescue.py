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
from probe_jitter_second_differences import classify, summary, table_row  # noqa: E402,F401  (re-exported)
from probe_runner import probe_main, run_rule_probe  # noqa: E402

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


def _let_through(got, a, kw):
    """The record of one pair the rule let through (None: it let none through)."""
    if got is None:
        return None
    info = got[2]
    return {"effect": got[0][0].effect, "partner": info["partner"], "joint": info["joint"],
            "paired_p_value_of_both": info["paired_p_value_of_both"]}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; store the rows of the logs where it let a pair
    through."""
    return run_rule_probe(out_path, keys, family, rule="PAIR_RESCUE", func="pair_rescue", record=_let_through,
                          hits_key="let_through", row_class=row_class)


def keys_cli(argv, seed: int = 70):
    """``--keys CLASS [--seed N]``: print the kept logs of that class (:func:`sample_keys`); ``seed``: the default
    order (the seventy-first round's probe, on the same classes, passes 71)."""
    import argparse
    ap = argparse.ArgumentParser()
    ap.add_argument("--keys", choices=CLASSES, required=True)
    ap.add_argument("--seed", type=int, default=seed)
    a = ap.parse_args(argv)
    print(" ".join(str(k) for k in sample_keys(a.keys, a.seed)))


def main(argv=None):
    probe_main(sys.argv[1:] if argv is None else argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
