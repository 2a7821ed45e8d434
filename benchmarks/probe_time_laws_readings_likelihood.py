"""The sixty-eighth round's probe: laws of the friction in time held back by the ADC guard, judged by the readings.

On a quantized torque the ADC guard (``core._above_quantization``) keeps a candidate only where it changes the
held-out prediction by more than half a step; a drift of the friction over minutes changes it by less on every
sample, so 51 kept closed-loop rows at 50 Hz (an energy drift over 600 s, mostly a quantized torque) end as "none"
with F-tests of p = 0.  This probe sets ``core.TIME_LAWS_BY_READINGS_LIKELIHOOD = True`` (a law in time held back by
the guard is kept when the likelihood of the quantized readings favours it: ``core.time_law_beyond_rounding``) and,
for each kept closed-loop log it is given, generates and diagnoses it, counts how often the rule kept a candidate the
guard held back, and where it did stores the row beside its kept row (a log where it never did gets the kept row's
diagnosis: the rule changes nothing else).

    python benchmarks/probe_time_laws_readings_likelihood.py --keys --noise quantized --seed 68 > ks.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_time_laws_readings_likelihood.py OUT.json $(cat ks.txt)
    python benchmarks/probe_time_laws_readings_likelihood.py --table-row A.json B.json

    python benchmarks/probe_time_laws_readings_likelihood.py --keys --family testbench > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_time_laws_readings_likelihood.py --family=testbench OUT.json $(cat kt.txt)

``--keys`` options: ``--family`` (loop, testbench), ``--noise`` (quantized), ``--missed EFFECT`` (only kept rows missing it), ``--truth none|oov|any``,
``--sample-rate HZ``, ``--seed`` (a seeded random order).  Writes OUT.json every ten logs (``examined`` says how far
a stopped run got).  Rows are sorted as in the sixty-seventh round's probe (``probe_jitter_second_differences``).
"""
from __future__ import annotations

import os
import random
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_diagnose_testbench as B  # noqa: E402
from probe_jitter_second_differences import classify, summary, table_row  # noqa: E402,F401  (re-exported for the docs test)
from probe_runner import probe_main, run_rule_probe  # noqa: E402

OOV = ("backlash", "compliance", "sensor_delay")


def sample_keys(noise: str | None = "quantized", missed: str | None = None, truth: str = "any",
                sample_rate: float | None = None, seed: int = 68, family: str = "loop") -> list:
    """Kept logs of ``family`` with this ``noise``, ``missed`` effect, ``truth`` class (``none``: null logs, ``oov``: out
    of the vocabulary, ``any``) and ``sample_rate`` [Hz], in a seeded random order."""
    ks = []
    for (f, _, k), (_, r) in B.kept_rows_naming("any", sample_rate=sample_rate).items():
        if f != family or (noise is not None and r.get("noise", "gaussian") != noise):
            continue
        if missed is not None and missed not in r["missed"]:
            continue
        if truth == "none" and r["truth"] != "none":
            continue
        if truth == "oov" and r["truth"] not in OOV:
            continue
        ks.append(k)
    ks.sort()
    return random.Random(seed).sample(ks, len(ks))


def _kept_by_rule(got, a, kw):
    """The record of one candidate the rule kept (None: it kept none)."""
    if got is None:
        return None
    ext = a[2]
    return {"effect": ext.effect, "joint": int(ext.joint),
            "heldout_loglik_gain_profiled": got["heldout_loglik_gain_profiled"],
            "rounding_lr_bound": got["rounding_lr_bound"]}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` (``loop``: the closed-loop generator; ``testbench``: the
    open-loop one) with the rule on; store the rows of the logs where it let a candidate through."""
    return run_rule_probe(out_path, keys, family, rule="TIME_LAWS_BY_READINGS_LIKELIHOOD",
                          func="time_law_beyond_rounding", record=_kept_by_rule, hits_key="kept_by_rule")


def _keys_cli(argv):
    import argparse
    ap = argparse.ArgumentParser()
    ap.add_argument("--keys", action="store_true")
    ap.add_argument("--noise", default="quantized")
    ap.add_argument("--missed", default=None)
    ap.add_argument("--truth", choices=("any", "none", "oov"), default="any")
    ap.add_argument("--sample-rate", type=float, default=None)
    ap.add_argument("--seed", type=int, default=68)
    ap.add_argument("--family", choices=("loop", "testbench"), default="loop")
    a = ap.parse_args(argv)
    noise = None if a.noise == "any" else a.noise
    print(" ".join(str(k) for k in sample_keys(noise, a.missed, a.truth, a.sample_rate, a.seed, a.family)))


def main(argv=None):
    probe_main(sys.argv[1:] if argv is None else argv, __doc__, _keys_cli, run)


if __name__ == "__main__":
    main()
