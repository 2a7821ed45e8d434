"""The ninety-ninth round's probe: a named motor-position ripple is reported ambiguous with a disturbance periodic in
time where a sinusoid at the frequency locked to the held-out split explains most of its joint's nominal training
residual.

Fresh loop spec 40305 (a time-periodic disturbance alone at 0.5 Hz, 1000 Hz, quantized torque, an axis that barely
moves) is named a motor-position ripple: the held-out blocks alternate every second, so every training block sees
the same half of the 0.5 Hz cycle and every held-out block the other half, and the disturbance fitted on one half
predicts the other worse than no disturbance at all.  The rule (``core.RIPPLE_BESIDE_SPLIT_LOCKED_DISTURBANCE``,
where it acts: ``core.split_locked_disturbance``; rule file:
``benchmarks/results/diagnose_ripple_split_locked_round99_rule.txt``) only relabels the final findings.

A kept row can change only when one of its findings has a motor-position ripple at its head and no time-periodic
disturbance (``--keys touchable``), and its log's nominal training residual is mostly a sinusoid at the locked
frequency on some joint (``--screen``: preparation and the nominal fit, no diagnosis); the screens list those.

    python benchmarks/probe_ripple_split_locked.py --keys touchable > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_ripple_split_locked.py --screen S0.json --lane=0/2 $(cat kt.txt)
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_ripple_split_locked.py --screen S1.json --lane=1/2 $(cat kt.txt)
    python benchmarks/probe_ripple_split_locked.py --keys screened S0.json S1.json > ks.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_ripple_split_locked.py OUT.json $(cat ks.txt)
    python benchmarks/probe_ripple_split_locked.py --against-off-rows OUT.json     # the docs' table

``--min-share=0.2`` before ``--screen`` lists the joints from a share of 0.2 up, near the rule's threshold of 0.5.
"""
from __future__ import annotations

import functools
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_diagnose_testbench as B  # noqa: E402
from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_position_friction_halves import row_class  # noqa: E402
import probe_state_check_speeds  # noqa: E402
from probe_runner import kept_keys, run_rule_probe  # noqa: E402
from probe_state_check_speeds import screen_cli, screened_keys  # noqa: E402,F401

RULE = "RIPPLE_BESIDE_SPLIT_LOCKED_DISTURBANCE"
FUNC = "split_locked_disturbance"
WHAT = "a joint whose nominal training residual is mostly a sinusoid at the split's locked frequency"
RIPPLE, PERIODIC = "motor_position_ripple", "time_periodic_disturbance"


def touchable(row) -> bool:
    """Whether the rule can change this kept row: a finding with a motor-position ripple at its head and no
    time-periodic disturbance in it."""
    for part in row["got"].split("+"):
        head = part[len("ambiguous("):].split("|")[0] if part.startswith("ambiguous(") else part
        if head == RIPPLE and PERIODIC not in part:
            return True
    return False


def touchable_keys(family: str = "loop", results_dir=None) -> list:
    """The keys of ``family``'s kept rows that are :func:`touchable`, sorted."""
    return kept_keys(family, touchable, results_dir)


#: ``--keys touchable [--family=F]`` / ``--keys screened SCREEN.json ...``, as the ninety-first round's probe reads them
keys_cli = functools.partial(probe_state_check_speeds.keys_cli, candidate_keys=touchable_keys, name="touchable")


def locked_joints(family: str, spec: dict, min_share: float | None = None) -> dict:
    """{joint: :func:`core.split_locked_disturbance`} of the log of ``spec`` (of ``family``) as prepared for its kept
    row, on the nominal fit's residual (no diagnosis): the joints the rule can mark, or with ``min_share`` (the
    screen's ``--min-share=X``; default the rule's own, ``core.SPLIT_LOCKED_SHARE``) those whose share of the nominal
    training residual reaches it (a lower one lists the joints near the rule's threshold, whose logs a lane then
    diagnoses with the rule on: the screen reads the residual of the log as prepared, the rule the one after the
    search's outlier screen and inertia backfit); ``{"refused": message}`` when preparation refuses the log."""
    from drake_est.diagnose import core
    prep = probe_state_check_speeds.prepared_log(family, spec)
    if isinstance(prep, dict):
        return prep
    fit0 = core.Model(prep, []).fit()
    out = {}
    for j in prep.joints:
        got = core.split_locked_disturbance(prep, j, core._residual(prep, fit0, j), min_share=min_share)
        if got is not None:
            out[str(j)] = got
    return out


def _record(got, a, kw):
    """The record of one firing (None: the sinusoid at the locked frequency explains too little)."""
    if got is None:
        return None
    return {"joint": int(a[1]), **got}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it marked a ripple, store the rows and
    those of the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="marked",
                          row_class=row_class, compare_off=True)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    min_share = None
    for a in [a for a in argv if a.startswith("--min-share=")]:
        try:
            min_share = float(a.split("=", 1)[1])
        except ValueError:
            raise SystemExit(f"--min-share: expected a number, got {a.split('=', 1)[1]!r}")
        if not 0.0 <= min_share <= 1.0:
            raise SystemExit(f"--min-share: expected a share in [0, 1], got {min_share}")
        argv.remove(a)
    if min_share is not None and argv[:1] != ["--screen"]:
        raise SystemExit("--min-share goes with --screen (the rule itself always runs at core.SPLIT_LOCKED_SHARE)")
    what, extra = WHAT, {}
    if min_share is not None:
        what = f"a joint where a sinusoid at the split's locked frequency holds {min_share} of the residual or more"
        extra = {"extra": {"min_share": min_share}}
    probe_state_check_speeds.screen_probe_main(argv, __doc__, keys_cli, run,
                                               measure=functools.partial(locked_joints, min_share=min_share),
                                               what=what, desc="prepare (nominal fit, locked sinusoid)", **extra)


if __name__ == "__main__":
    main()
