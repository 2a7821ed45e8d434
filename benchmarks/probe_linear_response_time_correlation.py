"""The seventy-eighth round's probe: the linear-response check (an elastic gear's resonance) also holds the laws of a
joint whose final residual is correlated in time, not only of one whose residual depends on the acceleration.

:func:`drake_est.diagnose.core.finding_explained_by_linear_response` sets aside a smooth law of the position or speed
that a free linear response to the acceleration explains one way; it ran only on joints with an ``acceleration`` entry
of the "unexplained" verdict.  The rule (``core.LINEAR_RESPONSE_ON_TIME_CORRELATION``; rule:
``benchmarks/results/diagnose_linear_response_time_correlation_round78_rule.txt``) adds the joints with a
``time_correlation`` entry.  ``--keys touchable``: the kept rows whose final residual has a ``time_correlation`` entry
and no ``acceleration`` entry and that name a law the check holds.  The rule fires where the check returns another
finding than it returns with the rule off (each call is made again with the rule off).

    python benchmarks/probe_linear_response_time_correlation.py --keys touchable > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_linear_response_time_correlation.py OUT.json $(cat kt.txt)
    python benchmarks/probe_linear_response_time_correlation.py --against-off-rows A.json B.json
"""
from __future__ import annotations

import functools
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import probe_position_laws_speed_curve as speed_curve  # noqa: E402
from probe_held_back_rival import (AGAINST_OFF_HEADER, against_off, against_off_cli,  # noqa: E402,F401
                                   against_off_row)
from probe_held_back_rival import rule_probe_main  # noqa: E402
from probe_runner import run_rule_probe  # noqa: E402

RULE = "LINEAR_RESPONSE_ON_TIME_CORRELATION"


def touchable(row) -> bool:
    """Whether the rule can change the kept row: a ``time_correlation`` entry, no ``acceleration`` entry, and a law
    of :data:`drake_est.diagnose.core.LINEAR_RESPONSE_EFFECTS` named (outright or among ambiguous names)."""
    from drake_est.diagnose.core import LINEAR_RESPONSE_EFFECTS
    u = row.get("unexplained") or []
    return ("time_correlation" in u and "acceleration" not in u
            and any(e in row.get("got", "") for e in LINEAR_RESPONSE_EFFECTS))


touchable_keys = functools.partial(speed_curve.touchable_keys, touchable=touchable)
keys_cli = functools.partial(speed_curve.keys_cli, touchable=touchable)


def row_class(family: str, r: dict) -> str:
    """The probe's class of a kept row: its kind (null, oov or vocab)."""
    return speed_curve.B.row_kind(r)


def _hit(got):
    return None if got is None else (got[0].effect, int(got[0].joint))


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it fired, store the rows and the rows of
    the same logs with the rule off."""
    from drake_est.diagnose import core
    original = core.finding_explained_by_linear_response

    def record(got, a, kw):
        was = getattr(core, RULE)
        setattr(core, RULE, False)
        try:
            off = original(*a, **kw)
        finally:
            setattr(core, RULE, was)
        if _hit(got) == _hit(off):
            return None
        return {"on": _hit(got), "off": _hit(off),
                "tests": None if got is None else {k: got[1][k] for k in ("finding_given_linear_response",
                                                                         "linear_response_given_finding")}}

    return run_rule_probe(out_path, keys, family, rule=RULE, func="finding_explained_by_linear_response",
                          record=record, hits_key="set_aside", row_class=row_class, compare_off=True, module="core")


def main(argv=None):
    rule_probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
