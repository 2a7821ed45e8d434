"""The eighty-fourth round's probe: an abrupt change's time is chosen only among the splits where the training rows on
each side hold at least one sample's worth of the Coulomb + viscous law at the log's lowest and highest speed
(``detectors.CHANGE_SUPPORT_RULE``; rule file: ``benchmarks/results/diagnose_change_support_round84_rule.txt``).

Fresh closed-loop spec 30172 (an abrupt change beside a motor ripple at 100 Hz) is named an energy drift: the change
search put the switch where only slow moves follow (a segment that gives the law at the log's top speed 0.05
samples' worth), the fitted friction after it turns negative there, and the change is refused.  The rule can act
only in the logs whose training rows leave such a segment at some allowed split; they are found without diagnosing
(``bench_diagnose_testbench.py --kept-with-count unsupported_changes``), then diagnosed with the rule on and, where it
moved or refused a change, again off:

    python benchmarks/bench_diagnose_testbench.py --kept-with-count unsupported_changes --lane 0/10 --json s0.json
    python benchmarks/probe_change_support.py --keys s0.json [--family=testbench] > k0.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_change_support.py OUT.json $(cat k0.txt)
    python benchmarks/probe_change_support.py --against-off-rows A.json B.json
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_position_friction_halves import row_class  # noqa: E402,F401
from probe_held_back_rival import rule_probe_main  # noqa: E402
from probe_runner import run_rule_probe, screen_keys_cli  # noqa: E402
from probe_runner import screened_keys as runner_screened_keys  # noqa: E402

RULE = "CHANGE_SUPPORT_RULE"
FUNC = "supported_change"
COUNT = "unsupported_changes"


def screened_keys(paths, family: str = "loop") -> list:
    """The spec numbers of ``family`` that the screens ``paths`` (``--kept-with-count unsupported_changes`` JSONs)
    list as touched, sorted (:func:`probe_runner.screened_keys`)."""
    return runner_screened_keys(paths, COUNT, family)


def keys_cli(argv) -> None:
    """``--keys SCREEN.json ... [--family=F]``: print :func:`screened_keys`."""
    screen_keys_cli(argv, COUNT)


def _record(got, a, kw):
    """The record of one call (None: the search's own split was supported, so the rule changed nothing there)."""
    k = a[3] if len(a) > 3 else kw["k"]
    if got is not None and int(got) == int(k):
        return None
    return {"split": int(k), "chosen": None if got is None else int(got)}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it moved or refused a change, store the
    rows and the rows of the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="moved",
                          row_class=row_class, compare_off=True, module="detectors")


def main(argv=None):
    rule_probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
