"""The ninety-fourth round's probe: a ripple of a joint refined on the residual of the model without a law of the
joint's position that a round has just accepted.

The detector places a ripple's components one after another; the ripple backfit looks again only once a later
finding is in the model.  A position load accepted next holds the ripple's phase misfit, and the backfit settles
beside it (fresh loop spec 37278: a ripple of 5.5704 cycles/rad placed at 5.529 beside an abrupt change, reported with
a load that took 71 % of the held-out RMSE).  The rule (``core.RIPPLE_REFINED_BEFORE_POSITION_LAW_RULE``, the function
where it acts: ``core.ripple_refined_before_position_law``; rule file:
``benchmarks/results/diagnose_ripple_before_position_law_round94_rule.txt``) chooses the ripple's frequencies jointly
on the residual of the model without the law and, when that lowers the joint's training residual, runs the law's
round again on the refined model.

The rule can only act where a law of position is accepted beside a ripple: the kept rows whose ``got`` or set-aside
list holds both (``--keys touchable``; the set-aside list is stored since closed-loop spec 3700).  ``--keys control``
draws 100 kept closed-loop rows (seed 94) that name a ripple without a law of position; with ``--family=testbench``
it lists every open-loop row.  Both select from the kept rows as they stand: once a round's rows are folded they may
select other keys, and ``--keys examined LANE.json`` gives the keys a lane drew.

    python benchmarks/probe_ripple_before_position_law.py --keys touchable > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_ripple_before_position_law.py OUT.json $(cat kt.txt)
    python benchmarks/probe_ripple_before_position_law.py --keys control > kc.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_ripple_before_position_law.py OUT.json $(cat kc.txt)
    python benchmarks/probe_ripple_before_position_law.py --against-off-rows A.json B.json     # the docs' table

The ninety-fifth round's rule (``core.RIPPLE_REFINED_WHERE_LAW_FALLS_RULE``: the same refinement, kept only where the
law is no longer significant given the refined ripple) is probed with ``--rule=where_law_falls`` before OUT.json.
"""
from __future__ import annotations

import functools
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_position_friction_halves import row_class  # noqa: E402,F401
from probe_runner import keys_args, kept_keys, probe_main, run_rule_probe  # noqa: E402

from drake_est.diagnose.competition import POSITION_LAWS  # noqa: E402

#: ``--rule=NAME``: the round's switch this probe turns on (the ninety-fourth round's unless given)
RULES = {"before_position_law": "RIPPLE_REFINED_BEFORE_POSITION_LAW_RULE",
         "where_law_falls": "RIPPLE_REFINED_WHERE_LAW_FALLS_RULE"}
FUNC = "ripple_refined_before_position_law"
RIPPLE = "motor_position_ripple"
#: how many control rows ``--keys control`` draws, and the seed it draws them with
CONTROL_ROWS, CONTROL_SEED = 100, 94


def _holds(r: dict, effect: str) -> bool:
    """Whether a kept row names ``effect`` in ``got`` (alone or in an ambiguity) or lists it as set aside."""
    return effect in r["got"] or effect in (r.get("set_aside") or [])


def touchable(r: dict) -> bool:
    """Whether the rule can change a kept row: a motor ripple and a law of position among its findings, named or set
    aside."""
    return _holds(r, RIPPLE) and any(_holds(r, p) for p in POSITION_LAWS)


def control(r: dict) -> bool:
    """A row of the control: a motor ripple named, no law of position named or set aside."""
    return RIPPLE in r["got"] and not any(_holds(r, p) for p in POSITION_LAWS)


def drawn_control_keys(family: str, control, rows: int, seed: int, results_dir=None) -> list:
    """A probe's control: for the closed loop ``rows`` keys drawn (seed ``seed``) from the kept rows where
    ``control(row)`` holds, sorted; for another family every kept row (this probe's and the hundredth round's)."""
    if family != "loop":
        return kept_keys(family, lambda r: True, results_dir)
    pool = kept_keys(family, control, results_dir)
    rng = np.random.default_rng(seed)
    return sorted(int(k) for k in rng.choice(pool, size=min(rows, len(pool)), replace=False))


def control_keys(family: str = "loop", results_dir=None) -> list:
    """The control: for the closed loop :data:`CONTROL_ROWS` keys drawn (seed :data:`CONTROL_SEED`) from the
    :func:`control` rows, sorted; for another family every kept row."""
    return drawn_control_keys(family, control, CONTROL_ROWS, CONTROL_SEED, results_dir)


def examined_keys(paths) -> list:
    """The keys the probe JSONs ``paths`` examined, in order (a lane run again on the keys it drew: the kept rows
    move when a round's rows are folded, and with them what ``touchable`` and ``control`` select)."""
    import json
    keys = []
    for p in paths:
        try:
            keys += json.load(open(p))["keys_examined"]
        except (OSError, ValueError, KeyError) as e:
            raise SystemExit(f"--keys examined: {p}: not a probe JSON ({e})")
    return keys


def touchable_or_control_keys_cli(argv, touchable, control_keys) -> None:
    """``--keys touchable [--family=F]`` (the kept rows where ``touchable(row)`` holds), ``--keys control
    [--family=F]`` (``control_keys(family)``) or ``--keys examined JSON...``: print those keys (this probe's and the
    hundredth round's)."""
    family, rest = keys_args(argv)
    if rest == ["touchable"]:
        keys = kept_keys(family, touchable)
    elif rest == ["control"]:
        keys = control_keys(family)
    elif rest[:1] == ["examined"] and len(rest) > 1:
        keys = examined_keys(rest[1:])
    else:
        raise SystemExit("--keys: expected 'touchable', 'control' or 'examined JSON...'")
    print(" ".join(str(k) for k in keys))


def keys_cli(argv) -> None:
    """``--keys touchable``, ``--keys control`` or ``--keys examined JSON...`` of this probe
    (:func:`touchable_or_control_keys_cli`)."""
    touchable_or_control_keys_cli(argv, touchable, control_keys)


def _record(got, a, kw):
    """The record of one refinement (None: no ripple moved, or the rule was off)."""
    moved = got[2]
    if not moved:
        return None
    law = a[4]
    return {"law": law.effect, "joint": int(law.joint),
            "moved": [{"from": [float(x) for x in old.spec["frequencies_per_arm_rad"]],
                       "to": [float(x) for x in new.spec["frequencies_per_arm_rad"]]} for _, old, new in moved]}


def run(out_path: str, keys, family: str = "loop", rule: str = "before_position_law") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule ``rule`` (a key of :data:`RULES`) on; where it
    acted, store the rows and the rows of the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULES[rule], func=FUNC, record=_record, hits_key="refined",
                          row_class=row_class, compare_off=True)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    rule = "before_position_law"
    for a in [a for a in argv if a.startswith("--rule=")]:
        rule = a.split("=", 1)[1]
        argv.remove(a)
        if rule not in RULES:
            raise SystemExit(f"--rule must be one of {', '.join(RULES)}, got {rule!r}")
    if not against_off_cli(argv):
        probe_main(argv, __doc__, keys_cli, functools.partial(run, rule=rule))


if __name__ == "__main__":
    main()
