"""The hundred-and-first round's probe: the sixty-ninth round's rescue of a law in time held back by the torque ADC's
guard, whose check against a free function of the joint's state may also take the derivative filter's error through
the friction curve's slope where the joint's model holds a Stribeck law.

A law of the friction in time (an abrupt change or an energy drift) that changes the held-out prediction by less than
half a step of a quantized torque is held back by the ADC guard, and let past when the likelihood of the quantized
readings favours it and it predicts the held-out residual given a free function of the joint's state
(``core.time_law_beyond_rounding``).  Fresh loop spec 36374 (a load beside Stribeck at 1000 Hz, a quantized torque)
names an abrupt change, ambiguous with an energy drift, beside the pair: let past the guard, the change lowers the
held-out RMSE by 4.8 %, by 3.5 % given the state's function (p = 6e-198).  The derivative filter's error in qd grows
with the jerk and reaches the torque through the friction curve's slope, steep at low speed beside a Stribeck hump;
the log moves slowly in its first half minute.  Offered the jerk times kernels in |qd|
(``competition.filter_slope_columns``), the function lowers the held-out RMSE by 42 % alone and the change adds 0.7 %
given it.  The rule (``core.TIME_LAW_RESCUE_FILTER_SLOPE_RULE``, the function where it acts:
``core.rescue_explained_by_filter_slope``; rule file:
``benchmarks/results/diagnose_rescue_filter_slope_round101_rule.txt``) then does not let the law past the guard.

The rule can only act in a log whose torque lies on a grid (the closed-loop and open-loop generators' ``quantized``
noise) where a law in time meets a Stribeck law on its joint: the kept rows with a quantized torque whose ``got`` or
set-aside list holds a law in time and a Stribeck law (``--keys touchable``; the set-aside list is stored since
closed-loop spec 3700).  ``--keys control`` draws 100 kept closed-loop rows with a quantized torque (seed 101) that
name or set aside a Stribeck law and no law in time, where the rule can only act on a law in time that no kept row
shows; with ``--family=testbench`` both list every open-loop row that qualifies (``touchable``) or every open-loop
row (``control``).  ``--keys examined LANE.json`` gives the keys a lane drew.

    python benchmarks/probe_rescue_filter_slope.py --keys touchable > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_rescue_filter_slope.py OUT.json $(cat kt.txt)
    python benchmarks/probe_rescue_filter_slope.py --keys control > kc.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_rescue_filter_slope.py OUT.json $(cat kc.txt)
    python benchmarks/probe_rescue_filter_slope.py --against-off-rows A.json B.json     # the docs' table
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

RULE = "TIME_LAW_RESCUE_FILTER_SLOPE_RULE"
FUNC = "rescue_explained_by_filter_slope"
STRIBECK = "stribeck"
#: how many control rows ``--keys control`` draws, and the seed it draws them with
CONTROL_ROWS, CONTROL_SEED = 100, 101


def _quantized(r: dict) -> bool:
    """Whether the kept row's log has a quantized torque (the only logs with an ADC step for the guard)."""
    return r.get("noise") == "quantized"


def touchable(r: dict) -> bool:
    """Whether the rule can change a kept row: a quantized torque, and a law in time and a Stribeck law among its
    findings, named or set aside."""
    return _quantized(r) and _holds(r, STRIBECK) and any(_holds(r, law) for law in TIME_LAWS)


def control(r: dict) -> bool:
    """A row of the control: a quantized torque, a Stribeck law named or set aside, no law in time."""
    return _quantized(r) and _holds(r, STRIBECK) and not any(_holds(r, law) for law in TIME_LAWS)


def control_keys(family: str = "loop", results_dir=None) -> list:
    """The control: for the closed loop :data:`CONTROL_ROWS` keys drawn (seed :data:`CONTROL_SEED`) from the
    :func:`control` rows, sorted; for another family every kept row."""
    return drawn_control_keys(family, control, CONTROL_ROWS, CONTROL_SEED, results_dir)


def keys_cli(argv) -> None:
    """``--keys touchable [--family=F]``, ``--keys control [--family=F]`` or ``--keys examined JSON...``: print those
    keys."""
    touchable_or_control_keys_cli(argv, touchable, control_keys)


def _record(got, a, kw):
    """The record of one law not let past the guard (None: the rule was off, no Stribeck law on the joint, or the law
    still predicted the held-out residual)."""
    if got is None:
        return None
    ext = a[2]
    N, t, own, state = got
    return {"effect": ext.effect, "joint": int(ext.joint), "state_columns": int(N.shape[1]),
            "rmse_reduction_given_state": float(t["rmse_reduction"]), "p_value_given_state": float(t["p_value"]),
            "rmse_reduction_alone": float(own), "state_rmse_reduction": float(state)}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it acted, store the rows and the rows of
    the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="refused",
                          row_class=row_class, compare_off=True)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if not against_off_cli(argv):
        probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
