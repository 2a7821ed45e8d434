"""The ninety-eighth round's probe: the seventy-second round's check of a joint's position laws against a free speed
curve in their place also runs where the final residual's velocity structure was held back by the ADC guard alone, on
a joint whose Stribeck law is untestable.

Fresh loop spec 33286 (Stribeck alone at 50 Hz, quantized torque, selected speeds within a factor 3) is named a
position friction outright: no Stribeck candidate can compete there, and the velocity structure of its final residual
(49 % of the held-out variance) lies under the ADC's step, so the seventy-second round's check, which needs an
``unexplained`` velocity entry, does not run.  The rule (``core.POSITION_LAWS_SPEED_CURVE_ADC_GUARDED``, where it
acts: ``core.position_laws_beside_guarded_velocity``; rule file:
``benchmarks/results/diagnose_speed_curve_adc_guarded_round98_rule.txt``) only relabels the final findings.

A kept row can change only when it names a position law at the head of a finding, no Stribeck law and no
``unexplained`` velocity entry (``--keys touchable``), and its log's preparation gives the joint a quantized torque and
selected speeds too narrow for the Stribeck detector (``--screen``, no diagnosis); the screens list those.

    python benchmarks/probe_speed_curve_adc_guarded.py --keys touchable > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_speed_curve_adc_guarded.py --screen S0.json --lane=0/2 $(cat kt.txt)
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_speed_curve_adc_guarded.py --screen S1.json --lane=1/2 $(cat kt.txt)
    python benchmarks/probe_speed_curve_adc_guarded.py --keys screened S0.json S1.json > ks.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_speed_curve_adc_guarded.py OUT.json $(cat ks.txt)
    python benchmarks/probe_speed_curve_adc_guarded.py --against-off-rows OUT.json     # the docs' table
"""
from __future__ import annotations

import functools
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_diagnose_testbench as B  # noqa: E402
from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_position_friction_halves import row_class  # noqa: E402
from probe_position_laws_speed_curve import POSITION_LAWS, finding_heads  # noqa: E402
import probe_state_check_speeds  # noqa: E402
from probe_runner import kept_keys, run_rule_probe  # noqa: E402
from probe_state_check_speeds import screen_cli, screened_keys  # noqa: E402,F401

RULE = "POSITION_LAWS_SPEED_CURVE_ADC_GUARDED"
FUNC = "position_laws_beside_guarded_velocity"
WHAT = "a joint with a quantized torque whose Stribeck law is untestable"


def touchable(row) -> bool:
    """Whether the rule can change this kept row: a position law at the head of one of its findings, no Stribeck law
    at the head of one and no ``unexplained`` entry on the velocity (those the seventy-second round's check runs on
    already)."""
    heads = finding_heads(row["got"])
    return (any(h in POSITION_LAWS for h in heads) and "stribeck" not in heads
            and "velocity" not in (row.get("unexplained") or []))


def touchable_keys(family: str = "loop", results_dir=None) -> list:
    """The keys of ``family``'s kept rows that are :func:`touchable`, sorted."""
    return kept_keys(family, touchable, results_dir)


#: ``--keys touchable [--family=F]`` / ``--keys screened SCREEN.json ...``, as the ninety-first round's probe reads them
keys_cli = functools.partial(probe_state_check_speeds.keys_cli, candidate_keys=touchable_keys, name="touchable")


def guarded_joints(family: str, spec: dict) -> dict:
    """{joint: {"adc_step", "speed_ratio"}} of the log of ``spec`` (of ``family``) as prepared for its kept row (no
    diagnosis): the joints whose torque is quantized (``nominal.joint_tau_step`` > 0) and whose selected training
    speeds span less than the Stribeck detector needs (``detectors.stribeck_speeds`` empty; ``speed_ratio``: their
    95 % over their 2 % quantile); ``{"refused": message}`` when preparation refuses the log."""
    import numpy as np
    from drake_est.diagnose.detectors import stribeck_speeds
    from drake_est.diagnose.nominal import joint_tau_step
    prep = probe_state_check_speeds.prepared_log(family, spec)
    if isinstance(prep, dict):
        return prep
    out = {}
    for j, jd in prep.joints.items():
        v = np.abs(jd.v[jd.rows][jd.train])
        step = joint_tau_step(prep, j)
        if step > 0 and v.size and not stribeck_speeds(v).size:
            lo = float(np.quantile(v, 0.02))
            out[str(j)] = {"adc_step": float(step),
                           "speed_ratio": float(np.quantile(v, 0.95) / lo) if lo > 0 else None}
    return out


def _record(got, a, kw):
    """The record of one marking (None: the held-out blocks separated the final model from the curve)."""
    if got is None:
        return None
    return {"joint": int(a[3]), **got}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it marked a law, store the rows and those
    of the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="marked",
                          row_class=row_class, compare_off=True)


def main(argv=None):
    probe_state_check_speeds.screen_probe_main(list(sys.argv[1:] if argv is None else argv), __doc__, keys_cli, run,
                                               measure=guarded_joints, what=WHAT,
                                               desc="prepare (quantized, Stribeck untestable)")


if __name__ == "__main__":
    main()
