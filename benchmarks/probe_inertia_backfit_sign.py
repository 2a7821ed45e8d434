"""The seventy-fifth round's probe: the inertia backfit does not move a positive J to J <= 0.

``core.backfit_inertia`` re-estimates a generic axis' inertia beside the findings.  The rule
(``core.inertia_move_through_zero``, switched on by ``core.INERTIA_BACKFIT_KEEPS_SIGN``; rule:
``benchmarks/results/diagnose_inertia_backfit_sign_round75_rule.txt``) withholds a correction that would leave a
positive J at J <= 0 (loop spec 21549: J 0.787 -> -19.3, the generator's 0.919).  The rule can only change a log
whose backfit, without it, moves J from above 0 to 0 or below; kept rows since the thirty-sixth round record the
move (``inertia_backfit``: [J from prepare, J after]), so the selection is those rows (``--keys touchable``).

    python benchmarks/probe_inertia_backfit_sign.py --keys touchable > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_inertia_backfit_sign.py OUT.json $(cat kt.txt)
    python benchmarks/probe_inertia_backfit_sign.py --against-off A.json B.json
    python benchmarks/probe_inertia_backfit_sign.py --against-off-rows A.json B.json     # the docs' table

``--against-off``: the rows where the rule fired, judged against their rule-off rows
(``probe_held_back_rival.against_off``).
"""
from __future__ import annotations

import functools
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import probe_position_laws_speed_curve as speed_curve  # noqa: E402
# against_off, against_off_row and the header: this probe's judging and docs table (its tests read them here)
from probe_held_back_rival import (AGAINST_OFF_HEADER, against_off, against_off_cli,  # noqa: E402,F401
                                   against_off_row)
from probe_pair_rescue import row_class  # noqa: E402
from probe_runner import probe_main, run_rule_probe  # noqa: E402


def moved_through_zero(row) -> bool:
    """Whether the kept row records an inertia backfit move from J > 0 to J <= 0 on some joint."""
    return any(J > 0 and J_new <= 0 for J, J_new in (row.get("inertia_backfit") or {}).values())


touchable_keys = functools.partial(speed_curve.touchable_keys, touchable=moved_through_zero)
keys_cli = functools.partial(speed_curve.keys_cli, touchable=moved_through_zero)


def _withheld(got, a, kw):
    """The record of one firing: the move withheld (None: the rule did not apply)."""
    if got is None:
        return None
    return {"J": float(a[0]), "J_moved": float(got["J_moved"]), "standard_error": float(got["standard_error"])}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it fired, store the rows and the rows of
    the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule="INERTIA_BACKFIT_KEEPS_SIGN", func="inertia_move_through_zero",
                          record=_withheld, hits_key="withheld", row_class=row_class, compare_off=True)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if not against_off_cli(argv):
        probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
