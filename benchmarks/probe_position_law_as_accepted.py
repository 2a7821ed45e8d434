"""The seventy-fourth round's probe: a position law tested with its accepted kernel count when its fresh
re-detection chose another one and is not significant.

``core.finding_to_set_aside`` runs the round again on the model without each finding, and sets the finding aside
when the fresh candidate of its effect is not significant there.  The rule (``core._position_law_as_accepted``,
switched on by ``core.POSITION_LAW_AS_ACCEPTED_IN_ITS_CHECK``; rule:
``benchmarks/results/diagnose_position_law_as_accepted_round74_rule.txt``) then evaluates a position law as
accepted, given the others, when the fresh one has another number of kernels, and keeps it in the check when it passes
the round's tests (loop spec 11558: a 16-kernel load set aside because the fresh load, 32 kernels, predicted the
held-out data worse).  The rule can only change a log whose search, without it, sets a position law aside in this
check, so the selection is the kept rows with a position law among their set-aside findings (``--keys touchable``).

    python benchmarks/probe_position_law_as_accepted.py --keys touchable > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_position_law_as_accepted.py OUT.json $(cat kt.txt)
    python benchmarks/probe_position_law_as_accepted.py --against-off A.json B.json
    python benchmarks/probe_position_law_as_accepted.py --against-off-rows A.json B.json     # the docs' table

``--against-off``: the rows where the rule fired, judged against their rule-off rows
(``probe_held_back_rival.against_off``).
"""
from __future__ import annotations

import functools
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import probe_position_laws_speed_curve as speed_curve  # noqa: E402
# against_off, against_off_row and the header: this probe's judging and docs table (its tests read them here)
from probe_held_back_rival import (AGAINST_OFF_HEADER, against_off, against_off_cli,  # noqa: E402,F401
                                   against_off_row)
from probe_own_finding_in_check import _kept  # noqa: E402
from probe_pair_rescue import row_class  # noqa: E402
from probe_held_back_rival import rule_probe_main  # noqa: E402
from probe_runner import run_rule_probe  # noqa: E402


def touchable(row) -> bool:
    """Whether the rule can change this kept row: a position law among its set-aside findings."""
    return any(p in (row.get("set_aside") or []) for p in speed_curve.POSITION_LAWS)


# the seventy-second round's key selection, with this round's predicate
touchable_keys = functools.partial(speed_curve.touchable_keys, touchable=touchable)
keys_cli = functools.partial(speed_curve.keys_cli, touchable=touchable)


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it fired, store the rows and the rows of
    the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule="POSITION_LAW_AS_ACCEPTED_IN_ITS_CHECK",
                          func="_position_law_as_accepted", record=_kept, hits_key="kept_in_check",
                          row_class=row_class, compare_off=True)


def main(argv=None):
    rule_probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
