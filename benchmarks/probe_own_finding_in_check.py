"""The seventy-third round's probe: a finding tested as it stands when its fresh re-detection is not significant.

``core.finding_to_set_aside`` runs the round again on the model without each finding, and sets the finding aside
when the fresh candidate of its effect is not significant there.  The rule (``core._own_finding_given_others``,
switched on by ``core.OWN_FINDING_IN_ITS_CHECK``; rule:
``benchmarks/results/diagnose_own_finding_in_check_round73_rule.txt``) then evaluates the finding as accepted, given the others, and keeps it in the check when it passes the round's tests
(loop spec 11558: a 16-kernel load set aside because the fresh load, 32 kernels, predicted the held-out data worse).
For each kept log given, this probe diagnoses it with the rule on, records where the rule kept a finding in its
check, and there diagnoses it again with the rule off on the same machine (``rows_off``).

    python benchmarks/probe_own_finding_in_check.py --keys other > ka.txt      # missed, null_oov, other, testbench
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_own_finding_in_check.py OUT.json 11558 $(cat ka.txt)
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_own_finding_in_check.py --family=testbench OUT.json $(cat kt.txt)
    python benchmarks/probe_own_finding_in_check.py --against-off A.json B.json
    python benchmarks/probe_own_finding_in_check.py --against-off-rows A.json B.json     # the docs' table

``--keys CLASS``: as the seventieth round's probe (``probe_pair_rescue``), seed 73 by default.  ``--against-off``: the
rows where the rule fired, judged against their rule-off rows (``probe_held_back_rival.against_off``).
"""
from __future__ import annotations

import functools
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

# against_off, against_off_row and the header: this probe's judging and docs table (its tests read them here)
from probe_held_back_rival import (AGAINST_OFF_HEADER, against_off, against_off_cli,  # noqa: E402,F401
                                   against_off_row)
from probe_pair_rescue import keys_cli, row_class  # noqa: E402
from probe_held_back_rival import rule_probe_main  # noqa: E402
from probe_runner import run_rule_probe  # noqa: E402


def _kept(got, a, kw):
    """The record of one firing: the finding as accepted took the fresh candidate's place (None: it did not)."""
    if not got or not got[0][1].get("as_accepted"):
        return None
    ext, tst = got[0][0], got[0][1]
    return {"effect": ext.effect, "joint": int(ext.joint), "score": float(tst["score"]),
            "rmse_reduction": float(tst["rmse_reduction"])}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it fired, store the rows and the rows of
    the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule="OWN_FINDING_IN_ITS_CHECK", func="_own_finding_given_others",
                          record=_kept, hits_key="kept_in_check", row_class=row_class, compare_off=True)


def main(argv=None):
    rule_probe_main(argv, __doc__, functools.partial(keys_cli, seed=73), run)


if __name__ == "__main__":
    main()
