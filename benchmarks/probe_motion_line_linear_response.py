"""The hundred-and-sixth round's probe: the free function of the state that a time-periodic candidate at a line of
the motion must beat is also offered a free linear response to the joint's acceleration.

A time-periodic candidate at a line of the motion (``detectors.time_periodic_at_motion_line``) must predict the
held-out residual given a free function of its joint's state (``core.motion_line_state_test``): every misfit of the
model's laws of the state repeats with the motion.  A filter of the motion does too: fresh loop spec 44020 (an elastic
gear, out of the vocabulary, at 100 Hz on multisine moves over 300 s) names a disturbance at 0.149 Hz, on the
multisine's 0.150 Hz line, which given the state's function lowers the held-out RMSE by 6.4 % in the search's first
round and given the function and a 30-lag linear response to the acceleration (``core.linear_response_nuisance``) by
0.2 %.  The rule (``core.MOTION_LINE_LINEAR_RESPONSE_RULE``; rule file:
``benchmarks/results/diagnose_motion_line_linear_response_round106_rule.txt``) offers that response to the state's
function once its own blocks are chosen (``core.motion_line_state_extra``, ``competition.state_nuisance(after=...)``),
joined only where it lowers the held-out error further.

The candidate exists only on the joints of ``core.motion_line_gate``, so the rule can only change a log whose gate is
not empty.  ``--screen OUT.json [--lane=I/N] K ...`` generates and prepares the kept logs ``K`` (no diagnosis) and lists
those with a gated joint; ``--keys screened SCREEN.json ...`` prints them.  ``bench_diagnose_testbench.py
--kept-with-count motion_line_gate --only FILE`` lists the same for the logs of an ``--only`` file, and ``--keys gate
G.json ...`` prints those.  ``--keys all`` prints every kept row of the family (what a fresh block's screen takes);
``--keys involved`` those that name a time-periodic disturbance, report one as a rival or set one aside.  The rule is
counted as acting where the state test sets a candidate aside that the test without the response keeps.

    python benchmarks/probe_motion_line_linear_response.py --keys all | tr ' ' '\\n' | awk '$1 >= 44200' > ka.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_motion_line_linear_response.py --screen S.json $(cat ka.txt)
    python benchmarks/probe_motion_line_linear_response.py --keys screened S.json > kg.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_motion_line_linear_response.py OUT.json $(cat kg.txt)
    python benchmarks/probe_motion_line_linear_response.py --against-off-rows A.json B.json  # the docs' table
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_position_friction_halves import row_class  # noqa: E402,F401
from probe_runner import keys_args, kept_keys, probe_main, run_rule_probe, screened_keys  # noqa: E402
from probe_state_check_speeds import screen_cli  # noqa: E402
from probe_state_check_speeds import screened_keys as probe_screened_keys  # noqa: E402

from drake_est.diagnose import core as _core  # noqa: E402

RULE = "MOTION_LINE_LINEAR_RESPONSE_RULE"
FUNC = "motion_line_state_test"
#: the screen's count
COUNT = "motion_line_gate"
DISTURBANCE = "time_periodic_disturbance"
#: the state test itself, kept before ``run`` wraps it: the record calls it again with the rule off
_ORIGINAL = _core.motion_line_state_test


def involved(r: dict) -> bool:
    """Whether a kept row names a time-periodic disturbance, reports one as a rival or sets one aside (where a
    candidate at a line of the motion is most likely to have taken part in the search)."""
    return DISTURBANCE in r.get("got", "") or any(DISTURBANCE in str(a) for a in (r.get("set_aside") or []))


def keys_cli(argv) -> None:
    """``--keys all``: every kept row of the family; ``--keys involved``: those that are :func:`involved`; ``--keys
    screened S.json ...``: the logs this probe's screens list; ``--keys gate G.json ...``: the logs
    ``bench_diagnose_testbench.py --kept-with-count motion_line_gate`` lists (each ``[--family=F]``, loop unless
    given)."""
    family, rest = keys_args(argv)
    if rest == ["all"]:
        keys = kept_keys(family, lambda r: True)
    elif rest == ["involved"]:
        keys = kept_keys(family, involved)
    elif len(rest) > 1 and rest[0] == "screened":
        keys = probe_screened_keys(rest[1:], family)
    elif len(rest) > 1 and rest[0] == "gate":
        keys = screened_keys(rest[1:], COUNT, family)
    else:
        raise SystemExit("--keys: expected 'all', 'involved', 'screened SCREEN.json ...' or 'gate GATE.json ...'")
    print(" ".join(str(k) for k in keys))


def gated_joints(family: str, spec: dict) -> dict:
    """{joint: 1} for the joints of the log of ``spec`` (of ``family``, as prepared for its kept row) on which
    ``core.motion_line_gate`` offers a time-periodic candidate at a line of the motion with the rule off (the gate
    tests the candidate as a round does, so the rule can only close it); ``{"refused": message}`` when preparation
    refuses the log."""
    from drake_est.threads import single_thread_blas
    from probe_state_check_speeds import prepared_log
    prep = prepared_log(family, spec)
    if isinstance(prep, dict):
        return prep
    was = getattr(_core, RULE)
    setattr(_core, RULE, False)
    try:
        with single_thread_blas():
            return {str(j): 1 for j in _core.motion_line_gate(prep)}
    finally:
        setattr(_core, RULE, was)


def _record(got, a, kw):
    """The record of one state test the rule turned (None otherwise): with the response offered the candidate is
    explained (``got`` not significant), without it the same call keeps it."""
    prep, model, fit, ext, alpha, min_gain = a[:6]
    solve = a[7] if len(a) > 7 else kw.get("solve")
    if got.get("significant") or not _core.MOTION_LINE_LINEAR_RESPONSE_RULE:
        return None
    setattr(_core, RULE, False)
    try:
        off = _ORIGINAL(prep, model, fit, ext, alpha, min_gain, {}, solve)
    finally:
        setattr(_core, RULE, True)
    if not off["significant"]:
        return None
    return {"joint": int(ext.joint), "frequency_hz": float(ext.evidence["frequency_hz"]),
            "at_motion_line_hz": float(ext.evidence["at_motion_line_hz"]),
            "rmse_reduction_given_state": float(off["rmse_reduction"]),
            "rmse_reduction_given_state_and_response": float(got["rmse_reduction"]),
            "model": [x.effect for x in model.exts]}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it turned a state test, store the rows
    and the rows of the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="set_aside",
                          row_class=row_class, compare_off=True)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if against_off_cli(argv) or screen_cli(argv, measure=gated_joints, what="a gated joint",
                                           desc="prepare (motion_line_gate)"):
        return
    probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
