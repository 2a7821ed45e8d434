"""The eighty-eighth round's probe: the linear-response check also holds a disturbance periodic in time that is not
stationary over the log (``core.LINEAR_RESPONSE_DISTURBANCE_RULE``; rule file:
``benchmarks/results/diagnose_disturbance_stationary_round88_rule.txt``).

Fresh closed-loop spec 31260 (an elastic gear at 100 Hz) is named a 2.57 Hz disturbance in time, which a free linear
response to the acceleration explains one way; fitted over eighths of the log its amplitude wanders from 0.06 to
0.41 N m.  The check acts on the final model, so the probe diagnoses each log given with the rule on and, where it set
a finding aside, again off:

    python benchmarks/probe_disturbance_stationary.py --keys named > k.txt            # closed-loop logs
    python benchmarks/probe_disturbance_stationary.py --keys named --family=testbench > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_disturbance_stationary.py OUT.json $(cat k.txt)
    python benchmarks/probe_disturbance_stationary.py --against-off-rows A.json B.json
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_position_friction_halves import row_class  # noqa: E402,F401
from probe_held_back_rival import rule_probe_main  # noqa: E402
from probe_runner import kept_keys, named_keys_cli, run_rule_probe  # noqa: E402

RULE = "LINEAR_RESPONSE_DISTURBANCE_RULE"
FUNC = "finding_explained_by_linear_response"
DISTURBANCE = "time_periodic_disturbance"
#: the final ``unexplained`` entries on whose joint the linear-response check acts (core.LINEAR_RESPONSE_TRIGGERS and
#: time_correlation, spelled out so the screen does not follow a later change of the rule)
TRIGGERS = ("acceleration", "time_correlation")


def names_disturbance(r: dict) -> bool:
    """Whether a kept row names a disturbance in time among its findings or findings set aside, and either its final
    residual holds an entry the check acts on or a final check set something aside (a pass of the diagnosis the row
    does not show may have held the disturbance beside such an entry)."""
    named = DISTURBANCE in r["got"] or any(DISTURBANCE in x for x in r.get("set_aside", []))
    return named and (bool(set(r.get("unexplained", [])) & set(TRIGGERS)) or bool(r.get("set_aside")))


def named_keys(family: str = "loop", results_dir=None) -> list:
    """The spec numbers of ``family``'s kept rows that :func:`names_disturbance`, sorted."""
    return kept_keys(family, names_disturbance, results_dir)


def keys_cli(argv) -> None:
    """``--keys named [--family=F]``: print :func:`named_keys`."""
    named_keys_cli(argv, named_keys)


def _record(got, a, kw):
    """The record of one firing on a disturbance (None: every finding stood, a smooth law was set aside as before the
    round, or the rule was off)."""
    if got is None or got[0].effect != DISTURBANCE:
        return None
    e, why = got
    st = why["disturbance_stationarity"]
    return {"effect": e.effect, "joint": int(e.joint), "coherence": st["coherence"],
            "amplitudes": st["amplitudes"], "heterogeneity": st["heterogeneity"],
            "finding_given_linear_response": why["finding_given_linear_response"],
            "linear_response_given_finding": why["linear_response_given_finding"]}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it set a disturbance aside, store the rows
    and the rows of the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="set_aside",
                          row_class=row_class, compare_off=True, module="core")


def main(argv=None):
    rule_probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
