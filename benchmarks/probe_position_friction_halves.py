"""The eighty-first round's probe: a position friction on a joint whose final residual holds structure must predict
one half of the log from the other where both halves visit the same positions.

Fresh out-of-vocabulary spec 94 of ``benchmarks/bench_time_shift_null_rate.py`` (an elastic gear at 4.5 Hz beside a
4.9 Hz loop, 50 Hz) is named ``position_dependent_friction``: its ringing after a few point-to-point moves lasts
longer than a validation block, so a law of the position fitted on a transient's training blocks predicts its
held-out blocks.  The rule (``core.POSITION_FRICTION_ACROSS_HALVES``; rule file:
``benchmarks/results/diagnose_position_friction_halves_round81_rule.txt``) is the last final-model check, so it can
only act on the model that is final with the rule off: ``--keys touchable`` lists the kept rows with a position
friction in ``got`` and a non-empty ``unexplained`` list.  ``--synth K OUT.json``: the kept synth row K (generic
robot), on and off.

    python benchmarks/probe_position_friction_halves.py --keys touchable [--family=testbench] > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_position_friction_halves.py OUT.json $(cat kt.txt)
    python benchmarks/probe_position_friction_halves.py --against-off-rows A.json B.json
    python benchmarks/probe_position_friction_halves.py --synth 1 OUT.json
"""
from __future__ import annotations

import functools
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import probe_position_laws_speed_curve as speed_curve  # noqa: E402
from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_runner import probe_main, run_rule_probe  # noqa: E402

RULE = "POSITION_FRICTION_ACROSS_HALVES"
FUNC = "position_friction_not_held_across_halves"


def touchable(row) -> bool:
    """Whether the rule can change the kept row: a position friction in its diagnosis and a non-empty verdict."""
    return "position_dependent_friction" in (row.get("got") or "") and bool(row.get("unexplained"))


touchable_keys = functools.partial(speed_curve.touchable_keys, touchable=touchable)
keys_cli = functools.partial(speed_curve.keys_cli, touchable=touchable)


def row_class(family: str, r: dict) -> str:
    """The probe's class of a kept row: its kind (null, oov or vocab)."""
    return speed_curve.B.row_kind(r)


def _record(got, a, kw):
    """The record of one firing (None: every position friction held, or the rule was off)."""
    if got is None:
        return None
    e, why = got
    return {"effect": e.effect, "joint": int(e.joint), "half_gains": why["half_gains"],
            "rows_compared": why["rows_compared"]}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it set a finding aside, store the rows
    and the rows of the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="set_aside",
                          row_class=row_class, compare_off=True)


def synth_row(k: int, rule: str = RULE) -> dict:
    """The kept synth row ``k`` (generic robot) diagnosed with the switch ``core.<rule>`` on and off: ``{"on": row,
    "off": row, "kept": row}``."""
    from drake_est.diagnose import core
    B = speed_curve.B
    kept = {kk: r for (f, robot, kk), (_, r) in B.kept_rows_naming("any").items()
            if f == "synth" and robot == "generic"}
    if k not in kept:
        raise SystemExit(f"no kept synth row for k = {k}")
    spec = B.synth_cases(k + 1)[k]
    was = getattr(core, rule)
    out = {"kept": kept[k]}
    try:
        for name, on in (("on", True), ("off", False)):
            setattr(core, rule, on)
            rows = []
            B._run_family("synth", [spec], rows, k)
            out[name] = [r for r in rows if r.get("robot") == "generic"][0]
    finally:
        setattr(core, rule, was)
    return out


def synth_cli(argv, rule: str = RULE) -> bool:
    """``--synth K OUT.json``: :func:`synth_row` of ``K`` for the switch ``rule``, written to OUT.json; False when
    ``argv`` does not ask for it."""
    if argv[:1] != ["--synth"]:
        return False
    if len(argv) != 3 or not argv[1].isdigit():
        raise SystemExit("usage: --synth K OUT.json")
    with open(argv[2], "w") as f:
        json.dump(synth_row(int(argv[1]), rule=rule), f, indent=1, default=str)
    return True


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if not synth_cli(argv) and not against_off_cli(argv):
        probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
