"""The seventy-sixth round's probe: the time-shift test of the "unexplained" verdict has no ADC guard wherever it runs.

The time-shift test (:func:`drake_est.diagnose.unexplained._time_shift`) regresses the rounding error of a quantized
torque out (:func:`~drake_est.diagnose.unexplained.quantization_nuisance`); since the fourteenth round it has no
ADC guard only where the derivative window spans at most 0.1 s.  The rule (``unexplained.TIME_SHIFT_NO_ADC_GUARD``;
rule: ``benchmarks/results/diagnose_time_shift_guard_round76_rule.txt``) lifts the guard for this test wherever it
runs (windows up to 0.2 s).  In the benchmark's generators the only logs with a quantized torque and such a window
are the 50 Hz ones (7-sample window, 0.12 s): ``--keys touchable`` lists the kept rows with a quantized torque at
50 Hz.  The rule fires where ``residual_structure`` reports something it would not report with the rule off (each
call is made again with the rule off and the two lists of entries compared).

    python benchmarks/probe_time_shift_guard.py --keys touchable > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_time_shift_guard.py OUT.json $(cat kt.txt)
    python benchmarks/probe_time_shift_guard.py --against-off A.json B.json     # judged against the rule-off rows
    python benchmarks/probe_time_shift_guard.py --against-off-rows A.json B.json
    python benchmarks/probe_time_shift_guard.py --unexplained A.json B.json     # who gained or lost an entry

``--rule=TIME_SHIFT_GUARD_LIFTED_IN_RANGE`` (before the other arguments): the seventy-seventh round's rule instead,
the guard lifted only where the test's delay estimate lies within the shifts it tried
(``benchmarks/results/diagnose_time_shift_guard_round77_rule.txt``).
"""
from __future__ import annotations

import functools
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_time_shift_null_rate  # noqa: E402
import probe_position_laws_speed_curve as speed_curve  # noqa: E402
from probe_held_back_rival import (AGAINST_OFF_HEADER, against_off, against_off_cli,  # noqa: E402,F401
                                   against_off_row)
from probe_runner import probe_main, run_rule_probe  # noqa: E402

#: the sample rate [Hz] where the generators' quantized logs have a derivative window of 0.1-0.2 s
RATE_HZ = 50.0


def touchable(row) -> bool:
    """Whether the rule can change the kept row: a quantized torque at :data:`RATE_HZ`."""
    return row.get("noise") == "quantized" and row.get("sample_rate") == RATE_HZ


touchable_keys = functools.partial(speed_curve.touchable_keys, touchable=touchable)
keys_cli = functools.partial(speed_curve.keys_cli, touchable=touchable)


kind_of = speed_curve.B.row_kind


def row_class(family: str, r: dict) -> str:
    """The probe's class of a kept row (``classes_examined``): its kind (``bench_diagnose_testbench.row_kind``: null,
    oov or vocab), whatever the family."""
    return kind_of(r)


def _entries(found) -> list:
    """(joint, variable) of each entry of a ``residual_structure`` result, in its order."""
    return [(int(d["joint"]), d["variable"]) for d in found]


#: the switches of ``drake_est.diagnose.unexplained`` this probe can turn on (``--rule=NAME``): the seventy-sixth
#: round's and the seventy-seventh's (the guard lifted where the delay estimate lies within the shifts tried), the
#: rules the fresh-log benchmark compares too
RULES = bench_time_shift_null_rate.RULES


def run(out_path: str, keys, family: str = "loop", rule: str = RULES[0]) -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule ``rule`` (one of :data:`RULES`) on; where it fired,
    store the rows and the rows of the same logs with the rule off."""
    from drake_est.diagnose import unexplained as U
    if rule not in RULES:
        raise SystemExit(f"--rule must be one of {', '.join(RULES)}, got {rule!r}")
    original = U.residual_structure

    def record(got, a, kw):
        # the same call with the rule off: fired where the reported entries differ
        was = getattr(U, rule)
        setattr(U, rule, False)
        try:
            off = original(*a, **{k: v for k, v in kw.items() if k != "tests_out"})
        finally:
            setattr(U, rule, was)
        on_e, off_e = _entries(got), _entries(off)
        if on_e == off_e:
            return None
        return {"on": on_e, "off": off_e,
                "time_shift": [{"joint": int(d["joint"]), "p_value": float(d["p_value"]),
                                "share": float(d["share_of_residual_variance"]),
                                "torque_delay_s": float(d.get("torque_delay_s", float("nan")))}
                               for d in got if d["variable"] == "time_shift_torque_vs_position"]}

    return run_rule_probe(out_path, keys, family, rule=rule, func="residual_structure",
                          record=record, hits_key="entries", row_class=row_class, compare_off=True,
                          module="unexplained")


def unexplained_changes(paths) -> dict:
    """Per kind of log (null, out of vocabulary, vocabulary): the fired logs that gain or lose an ``unexplained``
    entry with the rule on, against their rule-off rows; ``oov_none_off``: the examined out-of-vocabulary logs that
    end without `unexplained` with the rule off (the rule-off row where it fired, else the kept row, which the rule
    leaves as it is)."""
    out = {"null_gained": [], "null_lost": [], "oov_gained": [], "oov_lost": [], "vocab_gained": [],
           "vocab_lost": [], "examined": {}, "oov_none_off": 0}
    kept = speed_curve.B.kept_rows_naming("any")
    for p in paths:
        d = json.load(open(p))
        for c, n in d.get("classes_examined", {}).items():
            out["examined"][c] = out["examined"].get(c, 0) + n
        off = {r["k"]: r for r in d.get("rows_off", [])}
        for k in d["keys_examined"]:
            o = off.get(k) or kept[(d["family"], "generic", k)][1]
            out["oov_none_off"] += kind_of(o) == "oov" and not o["oov_unexplained"]
        for r in d["rows"]:
            o = off.get(r["k"])
            if o is None:
                continue
            kind = kind_of(r)
            if bool(r["unexplained"]) and not o["unexplained"]:
                out[f"{kind}_gained"].append(r["k"])
            if o["unexplained"] and not r["unexplained"]:
                out[f"{kind}_lost"].append(r["k"])
    return out


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["--unexplained"]:
        print(json.dumps(unexplained_changes(argv[1:]), indent=1))
    elif not against_off_cli(argv):
        rule = RULES[0]
        if argv and argv[0].startswith("--rule="):
            rule = argv.pop(0).split("=", 1)[1]
        probe_main(argv, __doc__, keys_cli, functools.partial(run, rule=rule))


if __name__ == "__main__":
    main()
