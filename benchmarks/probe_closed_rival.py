"""The ninetieth round's probe: a finding is not set aside for a rival closed on its joint earlier in the diagnosis.

``core.finding_to_set_aside`` checks every finding against the others; when a rival scores more given the other
findings and beats it on the paired held-out blocks, the finding is set aside (closed on its joint) and the search
runs again.  The rival may itself have been closed before (set aside, here or by a final check): it cannot be named,
and the check then closes both (fresh loop spec 33077, an asymmetric level beside Stribeck at 100 Hz: the load was set
aside for the level, the level for the closed load, and an abrupt change and a position friction took their place).
The rule (``core.CLOSED_RIVAL_RULE``, the function where it acts: ``core.closed_rival``; rule file:
``benchmarks/results/diagnose_closed_rival_round90_rule.txt``) judges the best rival that is not closed instead, and
reports the finding ambiguous with the closed one when that was set aside for the finding's effect.

The rule can only change a log whose diagnosis, without it, set a finding aside for a closed rival: the kept row then
lists at least two findings set aside (``--keys touchable``).  Kept rows written before the set-aside list was stored
(closed-loop specs 0-3699, the open-loop testbench and synth rows) cannot be screened this way.

    python benchmarks/probe_closed_rival.py --keys touchable > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_closed_rival.py OUT.json $(cat kt.txt)
    python benchmarks/probe_closed_rival.py --keys all --family=testbench > kb.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_closed_rival.py --family=testbench OUT.json $(cat kb.txt)
    python benchmarks/probe_closed_rival.py --against-off-rows A.json B.json     # the docs' table
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_position_friction_halves import row_class  # noqa: E402,F401
from probe_runner import keys_args, kept_keys, probe_main, run_rule_probe  # noqa: E402

RULE = "CLOSED_RIVAL_RULE"
FUNC = "closed_rival"


def touchable(r: dict) -> bool:
    """Whether the rule can change a kept row: at least two findings set aside (a finding set aside for a rival that
    was set aside before it)."""
    return len(r.get("set_aside") or []) >= 2


def touchable_keys(family: str = "loop", results_dir=None) -> list:
    """The spec numbers of ``family``'s kept rows that are :func:`touchable`, sorted."""
    return kept_keys(family, touchable, results_dir)


def keys_cli(argv, touchable=touchable) -> None:
    """``--keys touchable [--family=F]``: the kept rows for which ``touchable(row)`` holds (:func:`touchable` unless
    given; the ninety-second round's probe passes its own); ``--keys all [--family=F]``: every kept row of the family
    (for the families whose rows do not store the set-aside list)."""
    family, rest = keys_args(argv)
    if rest == ["touchable"]:
        keys = kept_keys(family, touchable)
    elif rest == ["all"]:
        keys = kept_keys(family, lambda r: True)
    else:
        raise SystemExit("--keys: expected 'touchable' or 'all'")
    print(" ".join(str(k) for k in keys))


def _record(got, a, kw):
    """The record of one intervention (None: the best rival was not closed, or the rule was off)."""
    if got is None:
        return None
    e, rival, paired_p = a[0], a[1], a[2]
    return {"finding": e.effect, "joint": int(e.joint), "closed_rival": rival.effect,
            "paired_p_value": float(paired_p), "rival_set_aside_for": got.get("better"),
            "cycle": got.get("better") == e.effect}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it acted, store the rows and the rows of
    the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="closed_rivals",
                          row_class=row_class, compare_off=True)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if not against_off_cli(argv):
        probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
