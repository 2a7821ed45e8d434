"""The seventy-second round's probe: position laws against a free speed curve in their place.

On a joint whose final residual still depends on the velocity and that holds position laws but no Stribeck law, the
rule (``core.mark_position_laws_within_speed_curve``, switched on by ``core.POSITION_LAWS_AGAINST_SPEED_CURVE``; rule:
``benchmarks/results/diagnose_position_laws_speed_curve_round72_rule.txt``) marks the position laws ambiguous with
``stribeck`` when the held-out blocks do not separate the final model from the one with a free speed curve in their
place.  The rule only relabels findings after the final residual is tested, so a kept row can change only when its
report has an ``unexplained`` entry on the velocity and a position law among its findings: ``--keys`` lists exactly
those rows.  For each log given this probe diagnoses it with the rule on, records where the rule marked a finding,
and there diagnoses it again with the rule off on the same machine (``rows_off``).

    python benchmarks/probe_position_laws_speed_curve.py --keys touchable > k.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_position_laws_speed_curve.py OUT.json $(cat k.txt)
    python benchmarks/probe_position_laws_speed_curve.py --against-off A.json B.json
    python benchmarks/probe_position_laws_speed_curve.py --against-off-rows A.json B.json     # the docs' table

``--against-off``: the rows where the rule fired, judged against their rule-off rows (as the seventy-first round's
probe, ``probe_held_back_rival.against_off``).
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_diagnose_testbench as B  # noqa: E402
# against_off, against_off_row and the header: this probe's judging and docs table (its tests read them here)
from probe_held_back_rival import (AGAINST_OFF_HEADER, against_off, against_off_cli,  # noqa: E402,F401
                                   against_off_row)
from probe_pair_rescue import row_class  # noqa: E402
from probe_held_back_rival import rule_probe_main  # noqa: E402
from probe_runner import run_rule_probe  # noqa: E402

POSITION_LAWS = ("position_dependent_friction", "position_dependent_load")


def finding_heads(got: str) -> list:
    """The effect at the head of each finding of a row's ``got`` ("A+ambiguous(B|C)" -> [A, B])."""
    out = []
    for part in got.split("+"):
        if part in ("none", "unexplained"):
            continue
        out.append(part[len("ambiguous("):].split("|")[0] if part.startswith("ambiguous(") else part)
    return out


def touchable(row) -> bool:
    """Whether the rule can change this kept row: an ``unexplained`` entry on the velocity and a position law at the
    head of one of its findings."""
    return "velocity" in (row.get("unexplained") or []) and any(h in POSITION_LAWS for h in finding_heads(row["got"]))


def touchable_keys(family: str = "loop", touchable=touchable) -> list:
    """The keys of ``family``'s kept rows the rule can change (``touchable(row)``, default :func:`touchable`), in
    order (also the seventy-fourth round's probe, with its own predicate)."""
    return sorted(k for (f, _, k), (_, r) in B.kept_rows_naming("any").items() if f == family and touchable(r))


def keys_cli(argv, touchable=touchable):
    """``--keys touchable [--family=F]``: print the keys of :func:`touchable_keys` for the predicate ``touchable``."""
    if len(argv) < 2 or argv[1] != "touchable":
        raise SystemExit("--keys: the only class is 'touchable'")
    family = "loop"
    for a in argv[2:]:
        if a.startswith("--family="):
            family = a.split("=", 1)[1]
    print(" ".join(map(str, touchable_keys(family, touchable))))


def _marked(got, a, kw):
    """The record of one firing (None: the curve was separated, or the check did not apply)."""
    if got is None:
        return None
    return {"joint": int(a[3]), **got}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it fired, store the rows and the rows of
    the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule="POSITION_LAWS_AGAINST_SPEED_CURVE",
                          func="position_laws_not_separated_from_speed_curve", record=_marked, hits_key="marked",
                          row_class=row_class, compare_off=True)


def main(argv=None):
    rule_probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
