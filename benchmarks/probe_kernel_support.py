"""The eighty-third round's probe: the position laws' detector chooses its number of kernels only among the sizes
whose every kernel holds one training sample's worth of weight (``detectors.KERNEL_SUPPORT_RULE``; rule file:
``benchmarks/results/diagnose_kernel_support_round83_rule.txt``).

Fresh closed-loop spec 29730 (a load beside Stribeck at 100 Hz) is named ``asymmetric_coulomb``: the training blocks
miss a stretch of positions the held-out blocks visit, the inner split chose 64 kernels, one of them over that hole,
and the load candidate's held-out RMSE came out worse than the model without it.  The rule can change only the logs
whose training positions leave a size unsupported; they are found without diagnosing
(``bench_diagnose_testbench.py --kept-with-count unsupported_kernels``, one lane of every ten kept logs at a time),
then diagnosed with the rule on and, where it dropped a size, again off:

    python benchmarks/bench_diagnose_testbench.py --kept-with-count unsupported_kernels --lane 0/10 --json s0.json
    python benchmarks/probe_kernel_support.py --keys s0.json [--family=testbench] > k0.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_kernel_support.py OUT.json $(cat k0.txt)
    python benchmarks/probe_kernel_support.py --against-off-rows A.json B.json
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

RULE = "KERNEL_SUPPORT_RULE"
FUNC = "supported_sizes"
COUNT = "unsupported_kernels"


def screened_keys(paths, family: str = "loop") -> list:
    """The spec numbers of ``family`` that the screens ``paths`` (``--kept-with-count unsupported_kernels`` JSONs)
    list as touched, sorted (:func:`probe_runner.screened_keys`)."""
    return runner_screened_keys(paths, COUNT, family)


def keys_cli(argv) -> None:
    """``--keys SCREEN.json ... [--family=F]``: print :func:`screened_keys`."""
    screen_keys_cli(argv, COUNT)


def _record(got, a, kw):
    """The record of one call (None: every size was supported, or the rule was off and the call not made)."""
    from drake_est.diagnose.detectors import BFE_SIZES
    sizes = a[3] if len(a) > 3 else kw.get("sizes")
    full = BFE_SIZES if sizes is None else sizes
    if len(got) == len(full):
        return None
    return {"sizes": [int(x) for x in got]}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it dropped a size, store the rows and
    the rows of the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="dropped",
                          row_class=row_class, compare_off=True, module="detectors")


def main(argv=None):
    rule_probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
