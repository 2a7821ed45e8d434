"""The ninety-third round's probe: a position load whose held-out gain lies mostly on the few samples moving in the
direction in which the log cannot test an asymmetric Coulomb level is reported ambiguous with that level.

``detectors.asymmetric_testable`` makes the level a candidate only when each direction holds at least 5 % of the
selected training samples.  On a log that moves one way almost always, a position load (its gravity harmonic and its
kernels sum to a constant) fixed by the few training samples of the other direction explains a level of that
direction, and is named (fresh loop spec 35997: an asymmetric level at 250 Hz named a position load, 85 % of its
held-out gain in the 57 of 6,935 held-out samples moving in the negative direction).  The rule
(``core.LOAD_IN_UNTESTED_DIRECTION_RULE``, the function where it acts: ``core.mark_load_in_untested_direction``; rule
file: ``benchmarks/results/diagnose_load_untested_direction_round93_rule.txt``) fits the level in the load's place on
the final model and marks the load ambiguous with it when the held-out blocks do not show the load predicting better.

It acts on the final model only, after every check, and changes no model: it can only change a log whose kept row
names a position load in ``got`` (``--keys candidates``), on a joint where the level is untestable.
``--screen OUT.json [--lane=I/N] [--family=F]`` generates and prepares those logs (no diagnosis) and lists the ones with
such a joint and held-out rows in its rare direction; ``--keys screened SCREEN.json ...`` prints them for the probe.

    python benchmarks/probe_load_untested_direction.py --keys candidates [--family=testbench] > kc.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_load_untested_direction.py --screen S0.json --lane=0/2 $(cat kc.txt)
    python benchmarks/probe_load_untested_direction.py --keys screened S0.json S1.json > ks.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_load_untested_direction.py OUT.json $(cat ks.txt)
    python benchmarks/probe_load_untested_direction.py --against-off-rows A.json B.json     # the docs' table
"""
from __future__ import annotations

import functools
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_position_friction_halves import row_class  # noqa: E402,F401
import probe_state_check_speeds  # noqa: E402
from probe_runner import kept_keys, run_rule_probe  # noqa: E402
from probe_state_check_speeds import screen_cli, screened_keys  # noqa: E402,F401

RULE = "LOAD_IN_UNTESTED_DIRECTION_RULE"
FUNC = "mark_load_in_untested_direction"
WHAT = "a joint whose asymmetric level is untestable, with held-out rows in its rare direction"


def candidate(r: dict, family: str = "loop") -> bool:
    """Whether a kept row can be changed by the rule: it names a position load (alone or in an ambiguity)."""
    return "position_dependent_load" in r.get("got", "")


def candidate_keys(family: str = "loop", results_dir=None) -> list:
    """The spec numbers of ``family``'s kept rows that are :func:`candidate`, sorted."""
    return kept_keys(family, lambda r: candidate(r, family), results_dir)


def untested_direction_rows(family: str, spec: dict) -> dict:
    """{joint: [its rare direction's selected training samples, all selected training samples, its rare direction's
    held-out rows]} of the joints of the log of ``spec`` (of ``family``), as prepared for its kept row (no diagnosis),
    whose asymmetric level is untestable (``core.untested_direction``) and whose rare direction has held-out rows;
    ``{"refused": message}`` when preparation refuses the log (:func:`probe_state_check_speeds.per_joint_of_prepared`)."""
    from drake_est.diagnose.core import untested_direction

    def rows(jd):
        way = untested_direction(jd)
        if way is not None and way[1].any():
            return [int(way[2]), int(way[3]), int(way[1].sum())]
        return None
    return probe_state_check_speeds.per_joint_of_prepared(family, spec, rows)


#: ``--keys candidates`` / ``--keys screened S.json ...``, as the ninety-first round's probe reads them
keys_cli = functools.partial(probe_state_check_speeds.keys_cli, candidate_keys=candidate_keys)


def _record(got, a, kw):
    """The record of one call that marked a load (None: it marked none, or the rule was off)."""
    if not got:
        return None
    return {"marked": [{"joint": int(st.ext.joint), **st.competition["untested_direction"]} for st in got]}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it marked a load, store the rows and the
    rows of the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="loads",
                          row_class=row_class, compare_off=True)


def main(argv=None):
    probe_state_check_speeds.screen_probe_main(list(sys.argv[1:] if argv is None else argv), __doc__, keys_cli, run,
                                               measure=untested_direction_rows, what=WHAT,
                                               desc="prepare (untested direction)")


if __name__ == "__main__":
    main()
