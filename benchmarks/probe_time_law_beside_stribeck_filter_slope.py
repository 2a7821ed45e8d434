"""The hundred-and-second round's probe: the forty-sixth round's check of a law in time beside a Stribeck law against
a free function of the joint's state, which may now also take the derivative filter's error through the friction
curve's slope.

A law of the friction in time (an abrupt change or an energy drift) on a joint whose model holds a Stribeck law must
predict the held-out residual given a free function of the joint's state, else it is set aside
(``core.time_law_explained_by_state``).  Fresh loop spec 41591 (an asymmetric level beside Stribeck at 250 Hz, a
quantized torque) names an abrupt change at 70.7 s beside the pair, with 6 % lower held-out RMSE, which the state's
function does not explain.  The derivative filter's error in qd grows with the jerk and reaches the torque through
the friction curve's slope, steep at low speed beside a Stribeck hump; the jerk alone, beside the level and the
Stribeck law, lowers the held-out RMSE by 9 %.  Offered the jerk times kernels in |qd|
(``competition.filter_slope_columns``, the hundred-and-first round's block), the function explains the change and
the change is set aside.  The rule (``core.TIME_LAW_BESIDE_STRIBECK_FILTER_SLOPE_RULE``, the block:
``core.filter_slope_block``; rule file:
``benchmarks/results/diagnose_time_law_beside_stribeck_filter_slope_round102_rule.txt``) offers that block in the
check beside a Stribeck law.

The rule can only act in a log where a law in time meets a Stribeck law on its joint: the kept rows whose ``got`` or
set-aside list holds a law in time and a Stribeck law (``--keys touchable``; the set-aside list is stored since
closed-loop spec 3700).  ``--keys control`` draws 100 kept closed-loop rows (seed 102) that name or set aside a
Stribeck law and no law in time, where the rule can only act on a law in time that no kept row shows; with
``--family=testbench`` both list every open-loop row that qualifies (``touchable``) or every open-loop row
(``control``).  ``--keys examined LANE.json`` gives the keys a lane drew.  The rule is counted as acting where the
check sets a law aside with the filter's block among the function's chosen blocks.

    python benchmarks/probe_time_law_beside_stribeck_filter_slope.py --keys touchable > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_time_law_beside_stribeck_filter_slope.py OUT.json $(cat kt.txt)
    python benchmarks/probe_time_law_beside_stribeck_filter_slope.py --keys control > kc.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_time_law_beside_stribeck_filter_slope.py OUT.json $(cat kc.txt)
    python benchmarks/probe_time_law_beside_stribeck_filter_slope.py --against-off-rows A.json B.json  # the docs' table
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_position_friction_halves import row_class  # noqa: E402,F401
from probe_ripple_before_position_law import (  # noqa: E402,F401
    _holds, drawn_control_keys, examined_keys, touchable_or_control_keys_cli)
from probe_runner import kept_keys, probe_main, run_rule_probe  # noqa: E402

from drake_est.diagnose.core import TIME_LAWS  # noqa: E402

RULE = "TIME_LAW_BESIDE_STRIBECK_FILTER_SLOPE_RULE"
FUNC = "time_law_explained_by_state"
STRIBECK = "stribeck"
#: how many control rows ``--keys control`` draws, and the seed it draws them with
CONTROL_ROWS, CONTROL_SEED = 100, 102


def touchable(r: dict) -> bool:
    """Whether the rule can change a kept row: a law in time and a Stribeck law among its findings, named or set
    aside."""
    return _holds(r, STRIBECK) and any(_holds(r, law) for law in TIME_LAWS)


def control(r: dict) -> bool:
    """A row of the control: a Stribeck law named or set aside, no law in time."""
    return _holds(r, STRIBECK) and not any(_holds(r, law) for law in TIME_LAWS)


def control_keys(family: str = "loop", results_dir=None) -> list:
    """The control: for the closed loop :data:`CONTROL_ROWS` keys drawn (seed :data:`CONTROL_SEED`) from the
    :func:`control` rows, sorted; for another family every kept row."""
    return drawn_control_keys(family, control, CONTROL_ROWS, CONTROL_SEED, results_dir)


def keys_cli(argv) -> None:
    """``--keys touchable [--family=F]``, ``--keys control [--family=F]`` or ``--keys examined JSON...``: print those
    keys."""
    touchable_or_control_keys_cli(argv, touchable, control_keys)


def state_set_aside_record(got, flag: str):
    """The record of one law that ``core.time_law_explained_by_state`` set aside (``got``: its ``(effect, joint,
    why)``) where its entry holds ``flag`` (None: the check set nothing aside, or its entry lacks ``flag``): the law,
    the state function's size and the held-out tests it read (this probe's and the hundred-and-fourth round's)."""
    if got is None or not got[2].get(flag):
        return None
    effect, joint, why = got
    t = why["state_law_test"]
    return {"effect": effect, "joint": int(joint), "state_columns": int(why["state_columns"]),
            "rmse_reduction_given_state": float(t["rmse_reduction"]), "p_value_given_state": float(t["p_value"]),
            "rmse_reduction_alone": float(why["heldout_rmse_reduction_alone"]),
            "state_rmse_reduction": float(why["state_heldout_rmse_reduction"])}


def _record(got, a, kw):
    """The record of one law set aside with the filter's block among the state function's chosen blocks (None: the
    check set nothing aside, or set it aside without that block)."""
    return state_set_aside_record(got, "filter_slope_chosen")


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it acted, store the rows and the rows of
    the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="set_aside",
                          row_class=row_class, compare_off=True)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if not against_off_cli(argv):
        probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
