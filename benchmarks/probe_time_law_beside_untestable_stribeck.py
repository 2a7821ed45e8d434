"""The hundred-and-third round's probe: a law in time beside a law of the state, on a joint that cannot test a Stribeck
law and whose other finding is already reported ambiguous with one, marked ambiguous with ``stribeck`` where a free
function of the joint's state (with a speed block) and the law explain each other.

The fifty-third round keeps a law in time that a free function of its joint's state explains when the law explains
that function back: only the law then keeps the two apart.  Fresh loop spec 41808 (a load beside Stribeck at 50 Hz
with Student-t noise, 97 % of its moving samples below twice vs) is reported with the load ambiguous with Stribeck and
an abrupt change at 86.3 s ambiguous with an energy drift: a wrong name.  Given the state's speed, inertia and load
blocks the change lowers the held-out RMSE by -15 %, given the change the function by -5.9 %; the change's segments
differ in their viscous slope, the Stribeck curve's drop between the slow moves and the faster ones.  The rule
(``core.TIME_LAW_BESIDE_UNTESTABLE_STRIBECK_RULE``, the mark: ``core.mark_time_law_beside_untestable_stribeck``;
rule file: ``benchmarks/results/diagnose_time_law_beside_untestable_stribeck_round103_rule.txt``) reports such a law
ambiguous with ``stribeck``; the model is not changed.

The rule can only act in a log whose final findings name a law in time not yet ambiguous with Stribeck beside another
finding reported ambiguous with Stribeck (``--keys touchable``).  ``--keys control`` draws 100 kept closed-loop rows
(seed 103) that name a law in time beside a law of the state and are not touchable, where the rule can only act on a
finding no kept row shows; with ``--family=testbench`` both list every open-loop row that qualifies (``touchable``)
or every open-loop row (``control``).  ``--keys examined LANE.json`` gives the keys a lane drew.  The rule is counted
as acting where the mark turns a law ambiguous with Stribeck.

    python benchmarks/probe_time_law_beside_untestable_stribeck.py --keys touchable > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_time_law_beside_untestable_stribeck.py OUT.json $(cat kt.txt)
    python benchmarks/probe_time_law_beside_untestable_stribeck.py --keys control > kc.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_time_law_beside_untestable_stribeck.py OUT.json $(cat kc.txt)
    python benchmarks/probe_time_law_beside_untestable_stribeck.py --against-off-rows A.json B.json  # the docs' table
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_position_friction_halves import row_class  # noqa: E402,F401
from probe_ripple_before_position_law import (  # noqa: E402,F401
    drawn_control_keys, examined_keys, touchable_or_control_keys_cli)
from probe_runner import kept_keys, probe_main, run_rule_probe  # noqa: E402

from drake_est.diagnose.core import TIME_LAWS  # noqa: E402

RULE = "TIME_LAW_BESIDE_UNTESTABLE_STRIBECK_RULE"
FUNC = "mark_time_law_beside_untestable_stribeck"
STRIBECK = "stribeck"
#: the laws of the state a law in time may stand beside (single-joint vocabulary effects outside the laws in time)
STATE_LAWS = ("stribeck", "position_dependent_load", "position_dependent_friction", "asymmetric_coulomb",
              "motor_position_ripple")
#: how many control rows ``--keys control`` draws, and the seed it draws them with
CONTROL_ROWS, CONTROL_SEED = 100, 103


def findings(r: dict) -> list:
    """A kept row's named findings as ``(effect, rivals)``: ``ambiguous(A|B|C)`` is the finding A, not separated from B
    and C."""
    out = []
    for part in (r["got"].split("+") if r["got"] not in ("", "none") else []):
        if part.startswith("ambiguous(") and part.endswith(")"):
            names = part[len("ambiguous("):-1].split("|")
            out.append((names[0], names[1:]))
        else:
            out.append((part, []))
    return out


def touchable(r: dict) -> bool:
    """Whether the rule can change a kept row: a law in time named and not ambiguous with Stribeck, beside another
    finding reported ambiguous with Stribeck."""
    f = findings(r)
    laws = [k for k, (e, rivals) in enumerate(f) if e in TIME_LAWS and STRIBECK not in rivals]
    return any(STRIBECK in rivals for k, (_, rivals) in enumerate(f) if k not in laws) and bool(laws)


def control(r: dict) -> bool:
    """A row of the control: a law in time named beside a law of the state, not touchable."""
    f = findings(r)
    return (any(e in TIME_LAWS for e, _ in f) and any(e in STATE_LAWS for e, _ in f)) and not touchable(r)


def control_keys(family: str = "loop", results_dir=None) -> list:
    """The control: for the closed loop :data:`CONTROL_ROWS` keys drawn (seed :data:`CONTROL_SEED`) from the
    :func:`control` rows, sorted; for another family every kept row."""
    return drawn_control_keys(family, control, CONTROL_ROWS, CONTROL_SEED, results_dir)


def keys_cli(argv) -> None:
    """``--keys touchable [--family=F]``, ``--keys control [--family=F]`` or ``--keys examined JSON...``: print those
    keys."""
    touchable_or_control_keys_cli(argv, touchable, control_keys)


def marked_records(got, key: str):
    """The records of the laws a mark turned ambiguous with Stribeck (``got``: the marked steps; None: it marked
    none), each from the evidence under the step's competition ``key``: this probe's and the hundred-and-fifth
    round's."""
    if not got:
        return None
    out = []
    for st in got:
        info = st.competition[key]
        out.append({"effect": st.ext.effect, "joint": int(st.ext.joint), "blocks": list(info["blocks"]),
                    "rmse_reduction_given_state": float(info["finding_given_state"]["rmse_reduction"]),
                    "rmse_reduction_of_state_given_law": float(info["state_given_finding"]["rmse_reduction"]),
                    "rmse_reduction_alone": float(info["heldout_rmse_reduction_alone"]),
                    "state_rmse_reduction": float(info["state_heldout_rmse_reduction_alone"])})
    return out


def _record(got, a, kw):
    """The records of the laws the mark turned ambiguous with Stribeck (None: it marked none)."""
    return marked_records(got, "untestable_stribeck_beside")


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it acted, store the rows and the rows of
    the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="marked",
                          row_class=row_class, compare_off=True)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if not against_off_cli(argv):
        probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
