"""The sixty-seventh round's probe: the data selection's speed bound (9.9) from the velocity's second differences.

The diagnosis leaves out samples slower than max(5 % of the top speed, 10 x the velocity jitter), the jitter read
from the velocity's first differences (``nominal.velocity_jitter(v, 1)``).  At 10 Hz a smooth multisine changes its
speed a lot between samples, so that bound reaches half the top speed and most Stribeck laws there are missed
(declared untestable).  Second differences do not see a steady acceleration; this probe sets
``nominal.V_JITTER_DIFFERENCE_ORDER = 2`` and, for each kept closed-loop log it is given, generates the log, compares
the two bounds and, where the bound moves, diagnoses it and stores the row beside its kept row.  ``--summary`` sorts
the stored rows: planted effects now found (mended), a correct row now not, a name that was not planted (the
judge's ``wrong``), a null log that gains an entry.

    python benchmarks/probe_jitter_second_differences.py --keys --sample-rate 10 --above 2950 --below 26799 --seed 67 > ks.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_jitter_second_differences.py OUT.json $(cat ks.txt)
    python benchmarks/probe_jitter_second_differences.py --summary A.json,B.json
    python benchmarks/probe_jitter_second_differences.py --table-row A.json B.json

Writes OUT.json every ten logs (a long run can be stopped; ``examined`` says how far it got).  The committed JSONs
of the round: ``diagnose_jitter_second_differences_round67_*.json`` (docs/readme/diagnose_testbench.md).
"""
from __future__ import annotations

import json
import os
import random
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_diagnose_testbench as B  # noqa: E402


def sample_keys(sample_rate: float, above: int = -1, seed: int = 67, below: int | None = None) -> list:
    """The kept closed-loop logs at ``sample_rate`` [Hz] with ``above`` < k <= ``below``, in a random order (seeded)."""
    ks = sorted(k for (f, _, k), (_, r) in B.kept_rows_naming("any", sample_rate=sample_rate).items()
                if f == "loop" and k > above and (below is None or k <= below))
    return random.Random(seed).sample(ks, len(ks))


def speed_bounds(v) -> tuple:
    """(bound with first differences, bound with second differences) of the selection (9.9) for velocity ``v``."""
    import numpy as np

    from drake_est.diagnose import nominal
    vref = float(np.quantile(np.abs(v), 0.95))
    return tuple(max(nominal.V_MIN_FRACTION * vref, 10.0 * nominal.velocity_jitter(v, o)) for o in (1, 2))


def run(out_path: str, keys) -> dict:
    from drake_est.diagnose import nominal
    kept = {k: v for (f, _, k), v in B.kept_rows_naming("any").items() if f == "loop"}
    missing = [k for k in keys if k not in kept]
    if missing:
        raise SystemExit(f"no kept closed-loop row for k = {missing[0]} ({len(missing)} such)")
    nominal.V_JITTER_DIFFERENCE_ORDER = 2
    res = {"jitter_difference_order": 2, "examined": 0, "keys_examined": [], "touched": [], "rows": [], "refused": []}
    for m, k in enumerate(keys):
        spec = B.loop_cases(k + 1)[k]
        log, _ = B.loop_log(spec)
        full = nominal.with_diagnosis_derivatives(log)
        bounds = [speed_bounds(full.dq[:, c]) for c in range(full.q.shape[1])]
        res["examined"] += 1
        res["keys_examined"].append(k)
        if any(abs(b1 - b2) > 1e-12 * b1 for b1, b2 in bounds):
            res["touched"].append({"k": k, "v_min_first": bounds[0][0], "v_min_second": bounds[0][1]})
            rows = []
            B._run_family("loop", [spec], rows, k, res["refused"])
            for r in rows:
                r["kept_json"], r["kept_row"] = kept[k][0], kept[k][1]
                res["rows"].append(r)
        if m % 10 == 9:
            B._write_json(res, out_path)
    B._write_json(res, out_path)
    return res


def classify(r) -> str:
    """What the second-difference bound did to a row, against its kept row."""
    old = r["kept_row"]
    if r["wrong"] and set(r["wrong"]) != set(old["wrong"]):
        return "wrong name"
    if r["truth"] == "none":
        return "null log, entry gained" if r["got"] != "none" and old["got"] == "none" else (
            "null log, entry lost" if old["got"] != "none" and r["got"] == "none" else "null log, same")
    if r["correct"] and not old["correct"]:
        return "mended"
    if old["correct"] and not r["correct"]:
        return "correct before, not now"
    return "same verdict" if r["got"] == old["got"] else "other change of the named effects"


def summary(paths) -> dict:
    rows, examined, touched = [], 0, 0
    for p in paths:
        d = json.load(open(p))
        rows += d["rows"]
        examined += d["examined"]
        touched += len(d["touched"])
    out = {"examined": examined, "touched": touched, "diagnosed": len(rows), "classes": {}, "cases": {}}
    for r in rows:
        c = classify(r)
        out["classes"][c] = out["classes"].get(c, 0) + 1
        if c not in ("same verdict", "mended", "null log, same"):
            out["cases"].setdefault(c, []).append(
                {"k": r["k"], "truth": r["truth"], "kept": r["kept_row"]["got"], "now": r["got"],
                 "sample_rate": r["sample_rate"], "noise": r["noise"], "duration": r["duration"]})
    out["mended_missed_stribeck"] = sum(classify(r) == "mended" and "stribeck" in r["kept_row"]["missed"]
                                        for r in rows)
    return out


TABLE_CLASSES = ("mended", "correct before, not now", "wrong name", "null log, entry gained",
                 "other change of the named effects", "same verdict", "null log, same")


def table_row(name: str, s: dict) -> str:
    """The docs' table row of one of the round's JSONs (``name``) from its ``summary``: logs examined, bound moved,
    then the rows per class of ``TABLE_CLASSES`` and the specs that gained a wrong name."""
    c = s["classes"]
    wrong = ", ".join(str(x["k"]) for x in s["cases"].get("wrong name", [])) or "none"
    cells = [f"`{name}`", str(s["examined"]), str(s["touched"])] + [str(c.get(k, 0)) for k in TABLE_CLASSES]
    return "| " + " | ".join(cells + [wrong]) + " |"


def report_cli(argv) -> bool:
    """The probes' shared report commands: ``--table-row A.json B.json`` (each JSON's row of the docs' table) and
    ``--summary A.json,B.json`` (their summary as JSON).  Returns True when ``argv`` was one of them (printed)."""
    if argv and argv[0] == "--table-row":
        if len(argv) < 2:
            raise SystemExit("--table-row needs one or more JSON files")
        from pathlib import Path
        for p in argv[1:]:
            print(table_row(Path(p).name, summary([p])))
        return True
    if argv and argv[0] == "--summary":
        if len(argv) < 2:
            raise SystemExit("--summary needs a comma-separated list of JSON files")
        print(json.dumps(summary(argv[1].split(",")), indent=1))
        return True
    return False


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "--keys":
        import argparse
        ap = argparse.ArgumentParser()
        ap.add_argument("--keys", action="store_true")
        ap.add_argument("--sample-rate", type=float, required=True)
        ap.add_argument("--above", type=int, default=-1)
        ap.add_argument("--below", type=int, default=None)
        ap.add_argument("--seed", type=int, default=67)
        a = ap.parse_args(argv)
        print(" ".join(str(k) for k in sample_keys(a.sample_rate, a.above, a.seed, a.below)))
        return
    if report_cli(argv):
        return
    if len(argv) < 2:
        raise SystemExit(__doc__)
    try:
        keys = [int(x) for x in argv[1:]]
    except ValueError as e:
        raise SystemExit(f"expected closed-loop spec numbers after OUT.json: {e}")
    res = run(argv[0], keys)
    print(f"examined {res['examined']}, bound moved in {len(res['touched'])}, diagnosed {len(res['rows'])}")


if __name__ == "__main__":
    main()
