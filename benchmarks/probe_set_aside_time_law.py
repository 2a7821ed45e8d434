"""The ninety-second round's probe: a law in time set aside as not significant given later findings, among which the
other law in time stands, is tried again with that law closed.

``core.finding_to_set_aside`` checks every finding against the others, one at a time.  When a later law in time and
further findings together took what the first law in time explained, the first one is no longer significant given
them and is set aside, and the search then names the later law and the further findings (fresh loop spec 35738: an
abrupt change beside a motor ripple at 10 Hz, named as an energy drift, a position friction and a load beside the
ripple).  The rule (``core.SET_ASIDE_TIME_LAW_ALTERNATIVE``, the function where it acts:
``core.set_aside_time_law_alternative``; rule file: ``benchmarks/results/diagnose_set_aside_time_law_round92_rule.txt``)
runs the search again with the named law closed and the set-aside one open, and keeps that alternative when it needs
fewer findings and the held-out blocks do not show the final model predicting better.

The rule can only change a log whose diagnosis set one law in time aside and names the other: its kept row lists the
one among its findings set aside and the other in ``got`` (``--keys touchable``).  Kept rows written before the
set-aside list was stored (closed-loop specs 0-3699, the open-loop testbench and synth rows) cannot be screened this
way; the open-loop rows are probed whole (``--keys all --family=testbench``).

    python benchmarks/probe_set_aside_time_law.py --keys touchable > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_set_aside_time_law.py OUT.json $(cat kt.txt)
    python benchmarks/probe_set_aside_time_law.py --keys all --family=testbench > kb.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_set_aside_time_law.py --family=testbench OUT.json $(cat kb.txt)
    python benchmarks/probe_set_aside_time_law.py --against-off-rows A.json B.json     # the docs' table
"""
from __future__ import annotations

import functools
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_position_friction_halves import row_class  # noqa: E402,F401
import probe_closed_rival  # noqa: E402
from probe_runner import kept_keys, probe_main, run_rule_probe  # noqa: E402

from drake_est.diagnose.core import TIME_LAW_PAIR  # noqa: E402

RULE = "SET_ASIDE_TIME_LAW_ALTERNATIVE"
FUNC = "set_aside_time_law_alternative"


def touchable(r: dict) -> bool:
    """Whether the rule can change a kept row: one law in time (:data:`~drake_est.diagnose.core.TIME_LAW_PAIR`) among
    the findings set aside and the other one named in ``got`` (alone or in an ambiguity)."""
    aside = r.get("set_aside") or []
    return any(law in aside and TIME_LAW_PAIR[1 - i] in r["got"] for i, law in enumerate(TIME_LAW_PAIR))


def touchable_keys(family: str = "loop", results_dir=None) -> list:
    """The spec numbers of ``family``'s kept rows that are :func:`touchable`, sorted."""
    return kept_keys(family, touchable, results_dir)


#: ``--keys touchable`` / ``--keys all``, as the ninetieth round's probe reads them
keys_cli = functools.partial(probe_closed_rival.keys_cli, touchable=touchable)


def _record(got, a, kw):
    """The record of one intervention (None: the rule did not act, or was off)."""
    if got is None:
        return None
    effect, joint, rival, _, info = got
    return {"finding": effect, "joint": int(joint), "closed": rival, "dropped": info["dropped"],
            "alternative_findings": info["alternative_findings"], "paired_p_value": info["paired_p_value"],
            "heldout_rmse": info["heldout_rmse"], "heldout_rmse_of_final_model": info["heldout_rmse_of_final_model"]}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it acted, store the rows and the rows of
    the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="alternatives",
                          row_class=row_class, compare_off=True)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if not against_off_cli(argv):
        probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
