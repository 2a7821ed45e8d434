"""The eighty-sixth round's probe: a motor-position ripple found after its joint's first position law is held against
that law at a finer resolution, as a later position law is (``core.FINER_BASIS_RIPPLE_RULE``; rule file:
``benchmarks/results/diagnose_finer_basis_ripple_round86_rule.txt``).

Fresh closed-loop spec 31089 (a position friction of two bumps at 50 Hz) is named the friction with 8 kernels and a
ripple of 2.07 cycles/rad beside it; the friction alone at 16 kernels predicts the held-out data better than both.
The check acts on the final model, so the probe diagnoses each log given with the rule on and, where it set a ripple
aside, again off:

    python benchmarks/probe_finer_basis_ripple.py --keys named > k.txt            # closed-loop logs
    python benchmarks/probe_finer_basis_ripple.py --keys named --family=testbench > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_finer_basis_ripple.py OUT.json $(cat k.txt)
    python benchmarks/probe_finer_basis_ripple.py --against-off-rows A.json B.json
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_position_friction_halves import row_class  # noqa: E402,F401
from probe_held_back_rival import rule_probe_main  # noqa: E402
from probe_runner import kept_keys, named_keys_cli, run_rule_probe  # noqa: E402

RULE = "FINER_BASIS_RIPPLE_RULE"
FUNC = "later_position_law_within_finer_basis"
POSITION_LAWS = ("position_dependent_friction", "position_dependent_load")


def names_pair(r: dict, laws=POSITION_LAWS) -> bool:
    """Whether a kept row names a motor-position ripple and one of ``laws`` (a position law unless given) among its
    planted effects, findings or findings set aside (the rows whose diagnosis may have held the pair in a final
    model)."""
    said = [r["truth"], r["got"], " ".join(r.get("set_aside", []))]
    return (any("motor_position_ripple" in x for x in said)
            and any(law in x for x in said for law in laws))


def named_keys(family: str = "loop", results_dir=None, laws=POSITION_LAWS) -> list:
    """The spec numbers of ``family``'s kept rows that :func:`names_pair` with ``laws``, sorted."""
    return kept_keys(family, lambda r: names_pair(r, laws), results_dir)


def keys_cli(argv, laws=POSITION_LAWS) -> None:
    """``--keys named [--family=F]``: print :func:`named_keys` with ``laws``."""
    named_keys_cli(argv, lambda family: named_keys(family, laws=laws))


def _record(got, a, kw):
    """The record of one firing: the check set a ripple aside (None otherwise; a later position law set aside is the
    check as it was)."""
    if got is None or got[0].effect != "motor_position_ripple":
        return None
    e, why = got
    return {"effect": e.effect, "joint": int(e.joint), "kernels_finer": int(why["kernels_finer"]),
            "gain_over_finer": float(why["gain_over_finer"])}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it set a ripple aside, store the rows and
    the rows of the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="set_aside",
                          row_class=row_class, compare_off=True, module="core")


def main(argv=None):
    rule_probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
