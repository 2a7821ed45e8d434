"""The eightieth round's probe: an ``acceleration`` entry of the "unexplained" verdict only where a smooth function of
the acceleration holds the structure too.

:func:`drake_est.diagnose.unexplained.residual_structure` reports a dependence of the final held-out residual on the
acceleration from a one-way ANOVA over 20 quantile bins.  Fresh closed-loop null logs at 50 Hz with Gaussian torque
noise got such an entry in 20 of 500 (4 %, ``benchmarks/results/time_shift_guard_fresh_null_rate_50_g.json``), each
with bin means that alternate in sign from one bin to the next.  The rule
(``unexplained.ACCELERATION_SMOOTH_REQUIRED``; rule file:
``benchmarks/results/diagnose_acceleration_smooth_round80_rule.txt``) also asks a continuous piecewise-linear
function of the acceleration's rank (:func:`~drake_est.diagnose.unexplained.smooth_rank_dependence`) to pass the level
and hold ``MIN_SHARE``.  It can only remove ``acceleration`` entries, so ``--keys touchable``: the kept rows with an
``acceleration`` entry.  The rule fires where it holds an entry back.

    python benchmarks/probe_acceleration_smooth.py --keys touchable [--family=testbench] > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_acceleration_smooth.py OUT.json $(cat kt.txt)
    python benchmarks/probe_acceleration_smooth.py --against-off-rows A.json B.json
"""
from __future__ import annotations

import functools
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import probe_position_laws_speed_curve as speed_curve  # noqa: E402
from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_held_back_rival import rule_probe_main  # noqa: E402
from probe_runner import run_rule_probe  # noqa: E402

RULE = "ACCELERATION_SMOOTH_REQUIRED"


def touchable(row) -> bool:
    """Whether the rule can change the kept row: its final residual has an ``acceleration`` entry."""
    return "acceleration" in (row.get("unexplained") or [])


touchable_keys = functools.partial(speed_curve.touchable_keys, touchable=touchable)
keys_cli = functools.partial(speed_curve.keys_cli, touchable=touchable)


def row_class(family: str, r: dict) -> str:
    """The probe's class of a kept row: its kind (null, oov or vocab)."""
    return speed_curve.B.row_kind(r)


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it held an entry back, store the rows and
    the rows of the same logs with the rule off."""

    def record(got, a, kw):
        if not got:
            return None
        smooth = a[0]
        return {"smooth_p_value": None if smooth is None else float(smooth[0]),
                "smooth_share": None if smooth is None else float(smooth[1]), "n_tests": int(a[1])}

    return run_rule_probe(out_path, keys, family, rule=RULE, func="acceleration_comb_only", record=record,
                          hits_key="held_back", row_class=row_class, compare_off=True, module="unexplained")


def main(argv=None):
    rule_probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
