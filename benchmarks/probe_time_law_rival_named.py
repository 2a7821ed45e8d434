"""The hundred-and-fourth round's probe: the forty-eighth round's check of a law in time against a free function of
its joint's state, which now also checks a law reported ambiguous with laws of the state that the model names beside
it.

A law of the friction in time (an abrupt change or an energy drift) beside a law of the state must predict the
held-out residual given a free function of the joint's state, else it is set aside
(``core.time_law_explained_by_state``); the forty-eighth round skips a law whose step is reported ambiguous with a law
of the state, since there the law in time stands for that law.  Fresh loop spec 42666 (a load beside a Stribeck hump
almost as large as the Coulomb level, at 100 Hz with Student-t noise) names the load, an energy drift ambiguous with a
position friction, and that position friction, ambiguous with Stribeck: the drift is a wrong name, and the law it is
ambiguous with is named beside it.  Given the state's function and the other findings the drift lowers the held-out
RMSE by -2.9 %.  The rule (``core.TIME_LAW_RIVAL_NAMED_RULE``, the screen: ``core._state_rivals_named_beside``; rule
file: ``benchmarks/results/diagnose_time_law_rival_named_round104_rule.txt``) lets the check hold such a law when every
law of the state it is ambiguous with is a finding of the model on its joint.

The rule can only act in a log whose final findings name a law in time reported ambiguous with laws of the state that
are all named beside it, and no Stribeck law (``--keys touchable``).  ``--keys control`` draws 100 kept closed-loop
rows (seed 104) that name a law in time ambiguous with a law of the state and are not touchable, where the rule can
only act on a model no kept row shows; with ``--family=testbench`` both list every open-loop row that qualifies
(``touchable``) or every open-loop row (``control``).  ``--keys examined LANE.json`` gives the keys a lane drew.  The
rule is counted as acting where the check sets a law aside that only the rule let it hold.

    python benchmarks/probe_time_law_rival_named.py --keys touchable > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_time_law_rival_named.py OUT.json $(cat kt.txt)
    python benchmarks/probe_time_law_rival_named.py --keys control > kc.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_time_law_rival_named.py OUT.json $(cat kc.txt)
    python benchmarks/probe_time_law_rival_named.py --against-off-rows A.json B.json  # the docs' table
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
from probe_time_law_beside_stribeck_filter_slope import state_set_aside_record  # noqa: E402
from probe_time_law_beside_untestable_stribeck import findings  # noqa: E402,F401

from drake_est.diagnose.core import TIME_LAWS  # noqa: E402

RULE = "TIME_LAW_RIVAL_NAMED_RULE"
FUNC = "time_law_explained_by_state"
#: how many control rows ``--keys control`` draws, and the seed it draws them with
CONTROL_ROWS, CONTROL_SEED = 100, 104


def _state_rivals(rivals) -> list:
    """The laws of the state among a finding's rivals (those outside the laws in time)."""
    return [x for x in rivals if x and x not in TIME_LAWS]


def touchable(r: dict) -> bool:
    """Whether the rule can change a kept row: no Stribeck law named, and a law in time ambiguous with laws of the
    state that are all named as findings of the row."""
    f = findings(r)
    named = {e for e, _ in f}
    if "stribeck" in named:
        return False
    return any(e in TIME_LAWS and _state_rivals(rivals) and set(_state_rivals(rivals)) <= named for e, rivals in f)


def control(r: dict) -> bool:
    """A row of the control: a law in time named ambiguous with a law of the state, not touchable."""
    return any(e in TIME_LAWS and _state_rivals(rivals) for e, rivals in findings(r)) and not touchable(r)


def control_keys(family: str = "loop", results_dir=None) -> list:
    """The control: for the closed loop :data:`CONTROL_ROWS` keys drawn (seed :data:`CONTROL_SEED`) from the
    :func:`control` rows, sorted; for another family every kept row."""
    return drawn_control_keys(family, control, CONTROL_ROWS, CONTROL_SEED, results_dir)


def keys_cli(argv) -> None:
    """``--keys touchable [--family=F]``, ``--keys control [--family=F]`` or ``--keys examined JSON...``: print those
    keys."""
    touchable_or_control_keys_cli(argv, touchable, control_keys)


def _record(got, a, kw):
    """The record of one law set aside that only the rule let the check hold, with the named laws of the state it was
    ambiguous with (None: the check set nothing aside, or a law the forty-eighth round already held)."""
    rec = state_set_aside_record(got, "ambiguous_with_named_beside")
    if rec is not None:
        rec["ambiguous_with"] = list(got[2]["ambiguous_with_named_beside"])
    return rec


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
