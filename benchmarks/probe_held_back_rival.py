"""The seventy-first round's probe: a round's winner beside a higher-scoring rival that only the paired test held back.

The paired block test holds a candidate back when its held-out gain sits in a few blocks.  When that candidate scored
more than the round's winner and the blocks do not show the winner predicting better than it either, the rival's
test -- not the data -- put the winner first (loop spec 28061: a position friction named over a Stribeck law that
scored twice as much).  This probe sets ``core.HELD_BACK_RIVALS = True`` (``core.held_back_rival_not_separated``;
rule: ``benchmarks/results/diagnose_held_back_rival_round71_rule.txt``) and, for each kept log it is given, generates
and diagnoses it, counts how often the rule put a rival beside a winner, and where it did stores the row beside its
kept row and beside the row of the same log diagnosed with the rule off on this machine (``rows_off``).

    python benchmarks/probe_held_back_rival.py --keys missed > ka.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_held_back_rival.py OUT.json $(cat ka.txt)
    python benchmarks/probe_held_back_rival.py --keys testbench > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_held_back_rival.py --family=testbench OUT.json $(cat kt.txt)
    python benchmarks/probe_held_back_rival.py --against-off A.json B.json
    python benchmarks/probe_held_back_rival.py --against-off-rows A.json B.json     # the docs' table

``--keys CLASS``: as the seventieth round's probe (``probe_pair_rescue``: ``missed``, ``null_oov``, ``other``,
``testbench``), seed 71 by default.  ``--against-off``: the examined rows where the rule fired, each judged against its
rule-off row of the same machine (wrong names gained and lost, missed effects, findings of null logs, ``unexplained``
of out-of-vocabulary logs, rows no longer named outright).
"""
from __future__ import annotations

import functools
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from probe_pair_rescue import keys_cli, row_class  # noqa: E402
from probe_runner import probe_main, run_rule_probe  # noqa: E402


def _beside(got, a, kw):
    """The record of one rival the rule put beside a winner (None: the rule did not)."""
    if got is None:
        return None
    ext, tst, rival, rival_tst = a[1], a[2], a[3], a[4]
    return {"winner": ext.effect, "rival": rival.effect, "joint": int(ext.joint), "winner_score": float(tst["score"]),
            "rival_score": float(rival_tst["score"]), "rival_paired_p_value": rival_tst.get("paired_p_value"),
            "paired_p_value": got}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it fired, store the rows and the rows of
    the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule="HELD_BACK_RIVALS", func="held_back_rival_not_separated",
                          record=_beside, hits_key="beside", row_class=row_class, compare_off=True)


def _outright(r) -> bool:
    """A correct row whose findings are all named outright (none ambiguous)."""
    return bool(r["correct"]) and "ambiguous(" not in r["got"]


def against_off(paths) -> dict:
    """The rows where the rule fired, judged against their rule-off rows of the same machine (the probe JSONs
    ``paths``, :func:`against_off_of`)."""
    return against_off_of(json.load(open(p)) for p in paths)


def against_off_of(probes) -> dict:
    """:func:`against_off` of probe JSONs already read (dicts with ``examined``, ``rows`` and ``rows_off``)."""
    out = {"examined": 0, "fired": 0, "classes_examined": {}, "changed": [], "wrong_gained": [], "wrong_lost": [],
           "missed_on": 0, "missed_off": 0, "null_findings_gained": [], "oov_unexplained_lost": [],
           "correct_off": 0, "outright_off": 0, "outright_lost": [], "verdict_changed": [],
           "off_differs_from_kept_row": [], "refused_off": []}
    for d in probes:
        out["examined"] += d["examined"]
        for c, n in d.get("classes_examined", {}).items():
            out["classes_examined"][c] = out["classes_examined"].get(c, 0) + n
        off = {r["k"]: r for r in d.get("rows_off", [])}
        # a log refused with the rule off has no row to judge against: counted, not judged
        out["refused_off"] += [x["k"] for x in d.get("refused_off", [])]
        for r in d["rows"]:
            o = off.get(r["k"])
            if o is None:
                continue
            out["fired"] += 1
            k = r["k"]
            out["missed_on"] += len(r["missed"])
            out["missed_off"] += len(o["missed"])
            if o["got"] != r["kept_row"]["got"]:
                # this machine's diagnosis with the rule off is not the kept row's (another CPU's last digits)
                out["off_differs_from_kept_row"].append(k)
            if r["got"] != o["got"]:
                out["changed"].append({"k": k, "truth": r["truth"], "off": o["got"], "on": r["got"]})
            if r["wrong"] and not o["wrong"]:
                out["wrong_gained"].append(k)
            if o["wrong"] and not r["wrong"]:
                out["wrong_lost"].append(k)
            if r["truth"] == "none" and r["got"] not in ("none", "unexplained") and o["got"] in ("none", "unexplained"):
                out["null_findings_gained"].append(k)
            if o["truth"] in ("backlash", "compliance", "sensor_delay") and o["oov_unexplained"] \
                    and not r["oov_unexplained"]:
                out["oov_unexplained_lost"].append(k)
            if o["correct"]:
                out["correct_off"] += 1
                if _outright(o):
                    out["outright_off"] += 1
                    if r["correct"] and not _outright(r):     # still correct, a finding now ambiguous
                        out["outright_lost"].append(k)
            if bool(r["correct"]) != bool(o["correct"]):
                out["verdict_changed"].append({"k": k, "off": bool(o["correct"]), "on": bool(r["correct"])})
    return out


#: the header of the docs' table of :func:`against_off_row`
AGAINST_OFF_HEADER = ("| JSON | logs examined | rule fired | named effects changed | wrong name gained | wrong name lost | "
                      "missed effects, off -> on | null log, finding gained | out of vocabulary, `unexplained` lost | "
                      "correct, no longer named outright | mended | broken |\n|---|---|---|---|---|---|---|---|---|---|---|---|")


def against_off_row(name: str, s: dict) -> str:
    """One row of the docs' table: :func:`against_off` of one JSON ``name``."""
    mended = sum(1 for v in s["verdict_changed"] if v["on"])
    broken = sum(1 for v in s["verdict_changed"] if not v["on"])
    return (f"| `{name}` | {s['examined']} | {s['fired']} | {len(s['changed'])} | {len(s['wrong_gained'])} | "
            f"{len(s['wrong_lost'])} | {s['missed_off']} -> {s['missed_on']} | {len(s['null_findings_gained'])} | "
            f"{len(s['oov_unexplained_lost'])} | {len(s['outright_lost'])} | {mended} | {broken} |")


def against_off_cli(argv) -> bool:
    """``--against-off A.json ...`` (:func:`against_off`, as JSON) and ``--against-off-rows A.json ...`` (the docs'
    table) for every probe that diagnoses the fired logs again with the rule off; False when ``argv`` asks for
    neither."""
    if not argv or argv[0] not in ("--against-off", "--against-off-rows"):
        return False
    if argv[0] == "--against-off":
        if len(argv) < 2:
            raise SystemExit("--against-off: give the probe's JSON files")
        print(json.dumps(against_off(argv[1:]), indent=1))
        return True
    print(AGAINST_OFF_HEADER)
    for p in argv[1:]:
        print(against_off_row(os.path.basename(p), against_off([p])))
    return True


def rule_probe_main(argv, doc: str, keys_cli, run) -> None:
    """The command line of a probe that diagnoses the fired logs again with the rule off: ``--against-off`` and
    ``--against-off-rows`` (:func:`against_off_cli`), else :func:`probe_runner.probe_main` (``argv`` None: the
    process's arguments)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not against_off_cli(argv):
        probe_main(argv, doc, keys_cli, run)


def main(argv=None):
    rule_probe_main(argv, __doc__, functools.partial(keys_cli, seed=71), run)


if __name__ == "__main__":
    main()
