"""The hundred-and-fifth round's probe: a law in time beside a Stribeck law of its joint, marked ambiguous with
``stribeck`` where a free function of the joint's state (with a speed block) and the law explain each other.

The forty-sixth round sets aside a law in time beside a Stribeck law that a free function of its joint's state
explains; the fifty-third round keeps it where the law explains that function back, since only the law then keeps the
two apart.  Fresh loop spec 43172 (a load beside a Gaussian-law Stribeck hump at 100 Hz with a quantized torque, 99 %
of the moving samples below twice vs) is reported with the load, a Stribeck law fitted with vs = 0.43 against 0.20
rad/s planted, and an abrupt change at 74.3 s ambiguous with a position friction and a time-periodic disturbance: a
wrong name.  Given the state's speed and jerk blocks the change lowers the held-out RMSE by 1.2 %, given the change
the function by 1.5 %.  The rule (``core.TIME_LAW_BESIDE_STRIBECK_BOTH_WAYS_RULE``, the mark:
``core.mark_time_law_beside_stribeck_both_ways``; rule file:
``benchmarks/results/diagnose_time_law_beside_stribeck_both_ways_round105_rule.txt``) reports such a law ambiguous
with ``stribeck``; the model is not changed.

The rule can only act in a log whose final findings name a law in time not yet ambiguous with Stribeck beside a
Stribeck law (``--keys touchable``).  ``--keys control`` draws up to 100 kept closed-loop rows (seed 105) that name a
law in time beside a Stribeck law named or reported as a rival and are not touchable, where the rule can only act on
a finding no kept row shows; with ``--family=testbench`` both list every open-loop row that qualifies
(``touchable``) or every open-loop row (``control``).  ``--keys examined LANE.json`` gives the keys a lane drew.  The
rule is counted as acting where the mark turns a law ambiguous with Stribeck.

    python benchmarks/probe_time_law_beside_stribeck_both_ways.py --keys touchable > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_time_law_beside_stribeck_both_ways.py OUT.json $(cat kt.txt)
    python benchmarks/probe_time_law_beside_stribeck_both_ways.py --keys control > kc.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_time_law_beside_stribeck_both_ways.py OUT.json $(cat kc.txt)
    python benchmarks/probe_time_law_beside_stribeck_both_ways.py --against-off-rows A.json B.json  # the docs' table
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_position_friction_halves import row_class  # noqa: E402,F401
from probe_ripple_before_position_law import (  # noqa: E402,F401
    drawn_control_keys, examined_keys, touchable_or_control_keys_cli)
from probe_runner import kept_keys, probe_main, run_rule_probe  # noqa: E402
from probe_time_law_beside_untestable_stribeck import findings, marked_records  # noqa: E402,F401

from drake_est.diagnose.core import TIME_LAWS  # noqa: E402

RULE = "TIME_LAW_BESIDE_STRIBECK_BOTH_WAYS_RULE"
FUNC = "mark_time_law_beside_stribeck_both_ways"
STRIBECK = "stribeck"
#: how many control rows ``--keys control`` draws, and the seed it draws them with
CONTROL_ROWS, CONTROL_SEED = 100, 105


def touchable(r: dict) -> bool:
    """Whether the rule can change a kept row: a Stribeck law named, and a law in time named not ambiguous with
    Stribeck."""
    f = findings(r)
    return STRIBECK in {e for e, _ in f} and any(e in TIME_LAWS and STRIBECK not in rivals for e, rivals in f)


def control(r: dict) -> bool:
    """A row of the control: a law in time named beside a Stribeck law named or reported as a rival, not
    touchable."""
    f = findings(r)
    return (any(e in TIME_LAWS for e, _ in f) and any(e == STRIBECK or STRIBECK in rivals for e, rivals in f)
            and not touchable(r))


def control_keys(family: str = "loop", results_dir=None) -> list:
    """The control: for the closed loop up to :data:`CONTROL_ROWS` keys drawn (seed :data:`CONTROL_SEED`) from the
    :func:`control` rows, sorted; for another family every kept row."""
    return drawn_control_keys(family, control, CONTROL_ROWS, CONTROL_SEED, results_dir)


def keys_cli(argv) -> None:
    """``--keys touchable [--family=F]``, ``--keys control [--family=F]`` or ``--keys examined JSON...``: print those
    keys."""
    touchable_or_control_keys_cli(argv, touchable, control_keys)


def _record(got, a, kw):
    """The records of the laws the mark turned ambiguous with Stribeck (None: it marked none)."""
    return marked_records(got, "stribeck_shape_beside")


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it acted, store the rows and the rows of
    the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="marked",
                          row_class=row_class, compare_off=True)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if not against_off_cli(argv):
        probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
