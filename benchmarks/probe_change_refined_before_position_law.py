"""The hundredth round's probe: an abrupt change of a joint whose switch is chosen again, jointly with the rest of the
model, when a round accepts a law of the joint's position beside it, kept where the law then falls.

The change's switch is found on the residual of the model at the time it is accepted, and its backfit searches again
on its partial residual: both hold the rest of the model as fitted beside the old switch.  Fresh loop spec 41128 (a
ripple and an abrupt change at 63.0 s, 100 Hz, Student-t noise) names the ripple first; its 64 coefficients take
part of the step, the change found on their residual sits at 44.1 s, and a position load accepted next lowers the
held-out RMSE by 19 %.  Chosen jointly with the ripple's columns, the switch sits at 65.8 s (the middle of the
training rows' gap around 63.0 s), where the ripple and the change predict the held-out blocks three times better and
the load is no longer significant.  The rule (``core.CHANGE_REFINED_WHERE_LAW_FALLS_RULE``, the function where it
acts: ``core.change_refined_before_position_law``; rule file:
``benchmarks/results/diagnose_change_refined_before_position_law_round100_rule.txt``) keeps the refined change only
where the law falls, and then runs the law's round again.

The rule can only act where a law of position is accepted beside an abrupt change of its joint: the kept rows whose
``got`` or set-aside list holds both (``--keys touchable``; the set-aside list is stored since closed-loop spec 3700).
``--keys control`` draws 100 kept closed-loop rows (seed 100) that name an abrupt change without a law of position;
with ``--family=testbench`` both list every open-loop row that qualifies (``touchable``) or every open-loop row
(``control``).  ``--keys examined LANE.json`` gives the keys a lane drew.

    python benchmarks/probe_change_refined_before_position_law.py --keys touchable > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_change_refined_before_position_law.py OUT.json $(cat kt.txt)
    python benchmarks/probe_change_refined_before_position_law.py --keys control > kc.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_change_refined_before_position_law.py OUT.json $(cat kc.txt)
    python benchmarks/probe_change_refined_before_position_law.py --against-off-rows A.json B.json     # the docs' table
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

from drake_est.diagnose.competition import POSITION_LAWS  # noqa: E402

RULE = "CHANGE_REFINED_WHERE_LAW_FALLS_RULE"
FUNC = "change_refined_before_position_law"
CHANGE = "abrupt_change"
#: how many control rows ``--keys control`` draws, and the seed it draws them with
CONTROL_ROWS, CONTROL_SEED = 100, 100


def touchable(r: dict) -> bool:
    """Whether the rule can change a kept row: an abrupt change and a law of position among its findings, named or
    set aside."""
    return _holds(r, CHANGE) and any(_holds(r, p) for p in POSITION_LAWS)


def control(r: dict) -> bool:
    """A row of the control: an abrupt change named, no law of position named or set aside."""
    return CHANGE in r["got"] and not any(_holds(r, p) for p in POSITION_LAWS)


def control_keys(family: str = "loop", results_dir=None) -> list:
    """The control: for the closed loop :data:`CONTROL_ROWS` keys drawn (seed :data:`CONTROL_SEED`) from the
    :func:`control` rows, sorted; for another family every kept row."""
    return drawn_control_keys(family, control, CONTROL_ROWS, CONTROL_SEED, results_dir)


def keys_cli(argv) -> None:
    """``--keys touchable [--family=F]``, ``--keys control [--family=F]`` or ``--keys examined JSON...``: print those
    keys."""
    touchable_or_control_keys_cli(argv, touchable, control_keys)


def _record(got, a, kw):
    """The record of one refinement that was kept (None: no change moved, the law stood, or the rule was off)."""
    moved = got[2]
    if not moved:
        return None
    law = a[4]
    return {"law": law.effect, "joint": int(law.joint),
            "moved": [{"from_t_change_s": float(old.spec["t_change"]), "to_t_change_s": float(new.spec["t_change"])}
                      for _, old, new in moved]}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it acted, store the rows and the rows of
    the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="refined",
                          row_class=row_class, compare_off=True)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if not against_off_cli(argv):
        probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
