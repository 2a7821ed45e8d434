"""The eighty-fifth round's probe: an abrupt change that the negative-friction guard refuses is searched again among
the switches where the model with it dissipates (``core.DISSIPATIVE_CHANGE_RULE``; rule file:
``benchmarks/results/diagnose_dissipative_change_round85_rule.txt``).

Fresh closed-loop spec 30172 (an abrupt change beside a motor ripple at 100 Hz) is named an energy drift: the change
search put the switch where only slow moves follow, the fitted viscous coefficient after it is -9.7 N m s/rad, the
guard refuses the change and the drift takes its place.  The rule acts only where the guard refuses a change, which
only a diagnosis shows: the probe diagnoses every log given with the rule on and, where a dissipative switch was
offered, again off:

    python benchmarks/probe_dissipative_change.py --keys lane 0/60 > k.txt      # every 60th kept closed-loop log
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_dissipative_change.py OUT.json $(cat k.txt)
    python benchmarks/probe_dissipative_change.py --against-off-rows A.json B.json
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_position_friction_halves import row_class  # noqa: E402,F401
from probe_held_back_rival import rule_probe_main  # noqa: E402
from probe_runner import keys_args, run_rule_probe  # noqa: E402

RULE = "DISSIPATIVE_CHANGE_RULE"
FUNC = "dissipative_change"


def lane_keys(lane: str, family: str = "loop", results_dir=None) -> list:
    """Lane ``i/n`` of the kept logs of ``family``: every n-th of their spec numbers in order, from the i-th."""
    import bench_diagnose_testbench as B
    i, n = B._lane(lane)
    keys = sorted({k for (f, _, k) in B.kept_rows_naming("any", results_dir) if f == family})
    return keys[i::n]


def keys_cli(argv) -> None:
    """``--keys lane I/N [--family=F]``: print :func:`lane_keys`."""
    family, rest = keys_args(argv)
    if len(rest) != 2 or rest[0] != "lane":
        raise SystemExit("--keys: expected 'lane I/N'")
    print(" ".join(str(k) for k in lane_keys(rest[1], family)))


def _record(got, a, kw):
    """The record of one call (None: no switch dissipates, so the refused change stands as it did)."""
    ext = a[4] if len(a) > 4 else kw["ext"]
    if got is None:
        return None
    return {"joint": int(ext.joint), "refused_t_change_s": float(ext.spec["t_change"]),
            "t_change_s": float(got.spec["t_change"])}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it offered a dissipative switch, store the
    rows and the rows of the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="offered",
                          row_class=row_class, compare_off=True, module="core")


def main(argv=None):
    rule_probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
