"""The eighty-seventh round's probe: a finding beside a constant-amplitude motor-position ripple of its joint is held
against the ripple with the detector's speed-dependent amplitude (``core.RIPPLE_AMPLITUDE_RULE``; rule file:
``benchmarks/results/diagnose_ripple_amplitude_round87_rule.txt``).

Fresh closed-loop spec 31044 (a ripple alone at 50 Hz, Student-t noise) is named the ripple and an energy drift that
takes what the constant amplitude leaves at the speeds the log rarely holds.  The check acts on the final model, so
the probe diagnoses each log given with the rule on and, where it set a finding aside, again off:

    python benchmarks/probe_ripple_amplitude.py --keys named > k.txt            # closed-loop logs
    python benchmarks/probe_ripple_amplitude.py --keys named --family=testbench > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_ripple_amplitude.py OUT.json $(cat k.txt)
    python benchmarks/probe_ripple_amplitude.py --against-off-rows A.json B.json
"""
from __future__ import annotations

import functools
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from probe_finer_basis_ripple import keys_cli as _keys_cli  # noqa: E402
from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_position_friction_halves import row_class  # noqa: E402,F401
from probe_held_back_rival import rule_probe_main  # noqa: E402
from probe_runner import run_rule_probe  # noqa: E402

RULE = "RIPPLE_AMPLITUDE_RULE"
FUNC = "finding_explained_by_ripple_amplitude"
#: the laws the rule holds against the ripple (core.RIPPLE_AMPLITUDE_EFFECTS, spelled out so the screen does not
#: follow a later change of the rule)
LAWS = ("energy_dependent_friction", "abrupt_change", "stribeck", "asymmetric_coulomb", "position_dependent_friction",
        "position_dependent_load")
keys_cli = functools.partial(_keys_cli, laws=LAWS)


def _record(got, a, kw):
    """The record of one firing (None: every finding stood, or the rule was off)."""
    if got is None:
        return None
    e, why = got
    return {"effect": e.effect, "joint": int(e.joint),
            "finding_given_ripple_amplitude": why["finding_given_ripple_amplitude"],
            "ripple_amplitude_given_finding": why["ripple_amplitude_given_finding"]}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it set a finding aside, store the rows and
    the rows of the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="set_aside",
                          row_class=row_class, compare_off=True, module="core")


def main(argv=None):
    rule_probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
