"""The eighty-second round's probe: a position friction on a joint whose final residual holds structure must beat the
model without it on the paired held-out blocks at p < 0.01 (the search's level is 0.05).

Fresh out-of-vocabulary spec 94 of ``benchmarks/bench_time_shift_null_rate.py`` (an elastic gear at 4.5 Hz beside a
4.9 Hz loop, 50 Hz) is named ``position_dependent_friction`` with paired p = 0.041: the friction predicts the few
stretches where the gear rings after a move.  The rule (``core.POSITION_FRICTION_STRICT_PAIRED``; rule file:
``benchmarks/results/diagnose_position_friction_paired_round82_rule.txt``) is the last final-model check, so it can
only act on the model that is final with the rule off: the kept rows it can change are those of the eighty-first
round's probe (``probe_position_friction_halves.touchable``).

    python benchmarks/probe_position_friction_paired.py --keys touchable [--family=testbench] > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_position_friction_paired.py OUT.json $(cat kt.txt)
    python benchmarks/probe_position_friction_paired.py --against-off-rows A.json B.json
    python benchmarks/probe_position_friction_paired.py --synth 1 OUT.json
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_position_friction_halves import (keys_cli, row_class, synth_cli, touchable,  # noqa: E402,F401
                                             touchable_keys)
from probe_runner import probe_main, run_rule_probe  # noqa: E402

RULE = "POSITION_FRICTION_STRICT_PAIRED"
FUNC = "position_friction_weak_on_blocks"


def _record(got, a, kw):
    """The record of one firing (None: every position friction passed the stricter level, or the rule was off)."""
    if got is None:
        return None
    st, why = got
    return {"effect": st.ext.effect, "joint": int(st.ext.joint), "paired_p_value": why["paired_p_value"]}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it set a finding aside, store the rows
    and the rows of the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="set_aside",
                          row_class=row_class, compare_off=True)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if not synth_cli(argv, RULE) and not against_off_cli(argv):
        probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
