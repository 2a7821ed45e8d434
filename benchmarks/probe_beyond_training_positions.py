"""The ninety-sixth round's probe: held-out rows at positions the training rows never visit, beyond a margin of one
coarsest kernel width, are not used to judge a model.

A law of a joint's position is fitted on the training positions only; beyond them every position law extrapolates,
and a law in time takes what they leave (fresh loop spec 37492: a load at 10 Hz named an abrupt change; 14 of its 371
held-out samples lie up to 0.53 rad beyond the positions its training blocks visit).  The rule
(``nominal.BEYOND_TRAINING_POSITIONS_RULE``, the function where it acts: ``nominal.beyond_training_positions``; rule
file: ``benchmarks/results/diagnose_beyond_training_positions_round96_rule.txt``) drops those rows in ``prepare`` and
counts them.

It can only change a log whose preparation has such rows.  ``--screen OUT.json [--lane I/N] [--family=F] K ...``
generates and prepares logs (no diagnosis) and lists those; ``--keys every N [--family=F]`` prints every N-th kept
row's key (the sample the screen runs on), ``--keys all`` every kept row's; ``--keys screened SCREEN.json ...`` the
listed ones, for the probe.

    python benchmarks/probe_beyond_training_positions.py --keys every 10 > ke.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_beyond_training_positions.py --screen S0.json --lane=0/2 $(cat ke.txt)
    python benchmarks/probe_beyond_training_positions.py --keys screened S0.json S1.json > ks.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_beyond_training_positions.py OUT.json $(cat ks.txt)
    python benchmarks/probe_beyond_training_positions.py --against-off-rows A.json B.json     # the docs' table
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_position_friction_halves import row_class  # noqa: E402,F401
from probe_runner import keys_args, kept_keys, run_rule_probe  # noqa: E402
import probe_state_check_speeds  # noqa: E402
from probe_state_check_speeds import per_joint_of_prepared, screen_cli, screened_keys  # noqa: E402,F401

RULE = "BEYOND_TRAINING_POSITIONS_RULE"
FUNC = "beyond_training_positions"
WHAT = "held-out rows beyond the training positions by more than the margin"


def every_keys(n: int, family: str = "loop", results_dir=None) -> list:
    """Every ``n``-th key of ``family``'s kept rows, in order from the first."""
    return kept_keys(family, lambda r: True, results_dir)[::n]


def keys_cli(argv) -> None:
    """``--keys every N [--family=F]``, ``--keys all [--family=F]`` or ``--keys screened SCREEN.json ...``: print
    those keys."""
    family, rest = keys_args(argv)
    if rest == ["all"]:
        keys = kept_keys(family, lambda r: True)
    elif len(rest) == 2 and rest[0] == "every":
        try:
            n = int(rest[1])
        except ValueError:
            raise SystemExit(f"--keys every: expected a whole number, got {rest[1]!r}") from None
        if n < 1:
            raise SystemExit(f"--keys every: expected N >= 1, got {n}")
        keys = every_keys(n, family)
    elif rest and rest[0] == "screened" and len(rest) > 1:
        keys = screened_keys(rest[1:], family)
    else:
        raise SystemExit("--keys: expected 'every N', 'all' or 'screened SCREEN.json ...'")
    print(" ".join(str(k) for k in keys))


def rows_beyond_positions(family: str, spec: dict) -> dict:
    """{joint: held-out rows beyond its training positions by more than the margin} of the log of ``spec`` (of
    ``family``), counted by ``prepare`` with the rule on and found on its rows with it off, as prepared for its kept row (no diagnosis; the closed-loop log generated without its visibility
    check, which changes nothing in the log); joints without such rows left out, ``{"refused": message}`` when
    preparation refuses it (:func:`probe_state_check_speeds.per_joint_of_prepared`)."""
    from drake_est.diagnose.nominal import beyond_training_positions
    # with the rule on, prepare has dropped them already and counted them
    return per_joint_of_prepared(family, spec, lambda jd: int(
        jd.counts.get("beyond_training_positions", 0)
        or beyond_training_positions(jd.q[jd.rows], jd.train).sum()) or None)


def _record(got, a, kw):
    """The record of one preparation that dropped rows (None: none dropped, or the rule was off)."""
    n = int(got.sum())
    return {"rows_dropped": n} if n else None


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it dropped rows, store the rows and the
    rows of the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="dropped",
                          row_class=row_class, compare_off=True, module="nominal")


def main(argv=None):
    probe_state_check_speeds.screen_probe_main(list(sys.argv[1:] if argv is None else argv), __doc__, keys_cli, run,
                                               measure=rows_beyond_positions, what=WHAT,
                                               desc="prepare (beyond training positions)")


if __name__ == "__main__":
    main()
