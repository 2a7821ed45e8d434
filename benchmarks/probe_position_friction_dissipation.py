"""The eighty-ninth round's probe: a position friction on a joint whose final residual holds structure must leave a
friction (its Coulomb level, at the log's extreme speeds, not below minus two noise levels at a training position).

Loop spec 30798 (an elastic gear at 1000 Hz) is named a position load and a position friction; with both the friction
of its joint along the motion falls to -5.04 N m at the end of the range.  The rule
(``core.POSITION_FRICTION_DISSIPATION_RULE``; rule file:
``benchmarks/results/diagnose_position_friction_dissipation_round89_rule.txt``) is the last final-model check, so it
can only act on the model that is final with the rule off: the kept rows it can change are those of the eighty-first
round's probe, a position friction in ``got`` and a non-empty ``unexplained`` list (``--keys touchable``, the same
screen).  ``--synth K OUT.json``: the kept synth row K (generic robot), on and off.

    python benchmarks/probe_position_friction_dissipation.py --keys touchable [--family=testbench] > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_position_friction_dissipation.py OUT.json $(cat kt.txt)
    python benchmarks/probe_position_friction_dissipation.py --against-off-rows A.json B.json
    python benchmarks/probe_position_friction_dissipation.py --synth 1 OUT.json
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import probe_position_friction_halves as halves  # noqa: E402
from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_runner import probe_main, run_rule_probe  # noqa: E402

RULE = "POSITION_FRICTION_DISSIPATION_RULE"
FUNC = "position_friction_not_dissipative"

# the rows the rule can change are the eighty-first round's: the same screen
touchable = halves.touchable
touchable_keys = halves.touchable_keys
keys_cli = halves.keys_cli
row_class = halves.row_class


def _record(got, a, kw):
    """The record of one firing (None: every position friction dissipates, or the rule was off)."""
    if got is None:
        return None
    e, why = got
    return {"effect": e.effect, "joint": int(e.joint), "friction_level": why["friction_level"]}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it set a finding aside, store the rows
    and the rows of the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="set_aside",
                          row_class=row_class, compare_off=True)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if not halves.synth_cli(argv, rule=RULE) and not against_off_cli(argv):
        probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
