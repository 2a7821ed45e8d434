"""The hundred-and-eighth round's probe: an abrupt change that the final model names beside an energy drift of its
joint, held against the drift fitted to Algorithm 6's fixed point.

The search fits an energy drift with two passes of Algorithm 6's fixed-point iteration
(``detectors.energy``); the thesis runs it until convergence.  Fresh loop spec 45767 (an energy drift alone, at 10 Hz
with Gaussian noise over 600 s) names the drift (80.4 % lower held-out RMSE) and then an abrupt change at 300.35 s,
the log's thermal peak (7.2 % more): a wrong name.  After the two passes the friction power the drift is driven by
still moves by 3.7 %; with passes until it settles (four) the drift alone lowers the held-out RMSE by 81.4 % and the
change is no longer significant beside it.  The rule (``core.CHANGE_BESIDE_DRIFT_AT_FIXED_POINT_RULE``, the check:
``core.change_beside_drift_at_fixed_point``, the first of the final model's checks) fits the drift again to its fixed
point where the final model holds a change beside it and sets the change aside when it is not significant given that
drift.

The rule can only act in a diagnosis whose final model, at one of its checks, holds an abrupt change and an energy
drift on one joint.  A kept row shows its last final model and the findings set aside before it (rows of specs
0-3699 do not store the set-aside list), so ``--keys touchable`` lists the kept rows whose findings and set-aside
findings hold both laws in time, and the rows without a stored set-aside list that name either.  ``--keys control``
draws 100 kept closed-loop rows (seed 108) that name a law in time and are not touchable; with ``--family=testbench``
both list every open-loop row that qualifies (``touchable``) or every open-loop row (``control``).  ``--keys examined
LANE.json`` gives the keys a lane drew.  The rule is counted as acting where the check sets a change aside.

    python benchmarks/probe_change_beside_drift.py --keys touchable > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_change_beside_drift.py OUT.json $(cat kt.txt)
    python benchmarks/probe_change_beside_drift.py --keys control > kc.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_change_beside_drift.py OUT.json $(cat kc.txt)
    python benchmarks/probe_change_beside_drift.py --against-off-rows A.json B.json  # the docs' table
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
from probe_time_law_beside_untestable_stribeck import findings  # noqa: E402,F401

from drake_est.diagnose.core import TIME_LAWS  # noqa: E402

RULE = "CHANGE_BESIDE_DRIFT_AT_FIXED_POINT_RULE"
FUNC = "change_beside_drift_at_fixed_point"
#: how many control rows ``--keys control`` draws, and the seed it draws them with
CONTROL_ROWS, CONTROL_SEED = 100, 108


def _set_aside_effects(r: dict) -> list | None:
    """The effects a kept row set aside (None: the row does not store its set-aside list)."""
    sa = r.get("set_aside")
    if sa is None:
        return None
    return [x.get("effect") if isinstance(x, dict) else x for x in sa]


def touchable(r: dict) -> bool:
    """Whether the rule can change a kept row: its named findings and the findings it set aside hold an abrupt change
    and an energy drift; or it does not store what it set aside and names either."""
    named = {e for e, _ in findings(r)}
    aside = _set_aside_effects(r)
    if aside is None:
        return bool(named & set(TIME_LAWS))
    return set(TIME_LAWS) <= named | set(aside)


def control(r: dict) -> bool:
    """A row of the control: a law in time named, not touchable."""
    return bool({e for e, _ in findings(r)} & set(TIME_LAWS)) and not touchable(r)


def control_keys(family: str = "loop", results_dir=None) -> list:
    """The control: for the closed loop :data:`CONTROL_ROWS` keys drawn (seed :data:`CONTROL_SEED`) from the
    :func:`control` rows, sorted; for another family every kept row."""
    return drawn_control_keys(family, control, CONTROL_ROWS, CONTROL_SEED, results_dir)


def keys_cli(argv) -> None:
    """``--keys touchable [--family=F]``, ``--keys control [--family=F]`` or ``--keys examined JSON...``: print those
    keys."""
    touchable_or_control_keys_cli(argv, touchable, control_keys)


def _record(got, a, kw):
    """The record of one change the check set aside (None: it set nothing aside): the change, the drift's passes and
    time constants, and how far the friction power still moved after the search's two passes."""
    if got is None:
        return None
    ext, why = got
    info = why["drift_at_fixed_point"]
    return {"effect": ext.effect, "joint": int(ext.joint), "t_change_s": ext.evidence.get("t_change_s"),
            "fixed_point_passes": info["fixed_point_passes"], "time_constant_s": info["time_constant_s"],
            "search_time_constant_s": info["search_time_constant_s"],
            "w_moved_after_two_passes": info["w_moved_after_two_passes"]}


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
