"""The time-shift test's ADC guard at 50 Hz on fresh closed-loop logs: how often a null log gains an entry, and how
often an out-of-vocabulary log is named `unexplained`, with the guard as kept and under the seventy-sixth and
seventy-seventh rounds' rules.

The benchmark's specs hold about 250 null logs at 50 Hz with a quantized torque, too few to put a false-alarm rate of
about 1 % within a useful interval.  This script generates logs of that kind with seeds outside every benchmark spec
(null: 1,000,000 + i; out of vocabulary: 2,000,000 + i, backlash, compliance and sensor delay in turn; 120 or 300 s,
torque noise drawn like the benchmark's, 0.03-0.15), diagnoses each with the rules off and keeps what the
time-shift test read (``DiagnosisResult.structure_readings``).  Where that reading could be reported without the
guard (p below the Bonferroni level, share above the test's bound, held back by the guard) the log is diagnosed
again with each rule on that lifts the guard there (``unexplained.TIME_SHIFT_NO_ADC_GUARD``: wherever the test
runs; ``unexplained.TIME_SHIFT_GUARD_LIFTED_IN_RANGE``: where the delay estimate lies within the shifts tried);
elsewhere neither rule can change the diagnosis, which is deterministic.

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/bench_time_shift_null_rate.py --kind null --n 200 [--lane 0/2]
           --json out.json
       python benchmarks/bench_time_shift_null_rate.py --summary a.json b.json     # or --table: the docs' table
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_diagnose_testbench as B  # noqa: E402

TS = "time_shift_torque_vs_position"
#: the seed bases of the generated logs (the benchmark's closed-loop specs use 3000 + k, k < 10^5)
SEED_BASE = {"null": 1_000_000, "oov": 2_000_000}
#: the rules compared, each a switch of ``drake_est.diagnose.unexplained``
RULES = ("TIME_SHIFT_NO_ADC_GUARD", "TIME_SHIFT_GUARD_LIFTED_IN_RANGE")


#: the torque noises of the generator (``--noise``)
NOISES = ("quantized", "gaussian", "student_t")


def spec(kind: str, i: int, rate: float = 50.0, noise: str = "quantized") -> dict:
    """The i-th generated spec of ``kind`` (null or oov): 50 Hz, quantized torque unless ``rate`` and ``noise`` say
    otherwise, as the benchmark draws the rest."""
    if kind not in SEED_BASE:
        raise SystemExit(f"--kind must be null or oov, got {kind!r}")
    if noise not in NOISES:
        raise SystemExit(f"--noise must be one of {', '.join(NOISES)}, got {noise!r}")
    if not rate > 0:
        raise SystemExit(f"--rate must be a positive sample rate in Hz, got {rate!r}")
    rng = np.random.default_rng(SEED_BASE[kind] + 500_000 + i)
    effects = {} if kind == "null" else {B.LOOP_OOV[i % len(B.LOOP_OOV)]: 1.0}
    return {"effects": effects, "seed": SEED_BASE[kind] + i, "sample_rate": float(rate),
            "duration": float(rng.choice([120.0, 120.0, 300.0])), "noise": noise,
            "noise_std": float(rng.uniform(0.03, 0.15))}


def time_shift_reading(readings) -> dict | None:
    """The time-shift test's reading of joint 1 (the generated axis), or None where it did not run."""
    return next((r for r in readings if r["variable"] == TS), None)


def could_fire(r, rule: str) -> bool:
    """Whether lifting the guard under ``rule`` could add the time-shift entry: significant, above its share bound,
    held back by the guard (and, for the in-range rule, a delay estimate within the shifts tried)."""
    from drake_est.diagnose.unexplained import delay_within, reportable
    if r is None or not r["adc_guarded"] or not reportable(r["p_value"], r["share"], TS, r["n_tests"]):
        return False
    if rule == "TIME_SHIFT_GUARD_LIFTED_IN_RANGE":
        return delay_within(r["torque_delay_s"], r["largest_shift_s"])
    return True


def _verdict(rep) -> dict:
    return {"findings": list(rep.effects), "unexplained": [u["variable"] for u in rep.result.unexplained]}


def run(kind: str, start: int, n: int, lane: str | None, path: str | None, rate: float = 50.0,
        noise: str = "quantized") -> list:
    """Diagnose the generated logs start .. start+n-1 of ``kind`` (this lane's share); rows written to ``path``
    every ten logs and at the end."""
    from drake_est.diagnose import diagnose, unexplained as U
    from drake_est.errors import DataError
    from drake_est.progress import progress
    i0, m = B._lane(lane)
    rows = []
    for i in progress(range(start + i0, start + n, m), desc=f"time shift, {kind}"):
        s = spec(kind, i, rate, noise)
        log, truth = B.loop_log(s)
        row = {"i": i, "kind": kind, "effect": next(iter(s["effects"]), None), "seed": s["seed"], "rate": rate,
               "noise": noise,
               "duration": s["duration"], "noise_std": s["noise_std"], "visible": list(truth["effects"])}
        try:
            rep = diagnose(log, robot="generic", seed=0, simulate=False)
        except DataError as e:
            row["refused"] = str(e)
            rows.append(row)
            continue
        row["off"] = _verdict(rep)
        r = time_shift_reading(rep.result.structure_readings)
        row["reading"] = r
        for rule in RULES:
            if not could_fire(r, rule):
                row[rule] = row["off"]
                continue
            was = getattr(U, rule)
            setattr(U, rule, True)
            try:
                row[rule] = _verdict(diagnose(log, robot="generic", seed=0, simulate=False))
            finally:
                setattr(U, rule, was)
        rows.append(row)
        if path and len(rows) % 10 == 0:
            Path(path).write_text(json.dumps(rows))
    if path:
        Path(path).write_text(json.dumps(rows))
    return rows


def upper_95(k: int, n: int) -> float:
    """One-sided 95 % Clopper-Pearson upper bound of a rate seen k times in n."""
    from scipy.stats import beta
    return 1.0 if k >= n else float(beta.ppf(0.95, k + 1, n - k))


def summary(rows) -> dict:
    """Per kind and setting (off and each rule): logs with any finding or entry (null) or named `unexplained` (out
    of vocabulary, visible ones only; per rule also the logs that gain or lose `unexplained` or gain a name against
    the rule off, and ``none_off``: those without `unexplained` with the rule off), with the counts of the logs left
    out (refused; planted effect not visible)."""
    out = {}
    for kind in ("null", "oov"):
        rs = [r for r in rows if r["kind"] == kind]
        refused = [r["i"] for r in rs if "refused" in r]
        rs = [r for r in rs if "refused" not in r]
        not_visible = [r["i"] for r in rs if kind == "oov" and not r["visible"]]
        rs = [r for r in rs if kind == "null" or r["visible"]]
        if not rs and not refused:
            continue
        d = {"logs": len(rs), "refused": refused, "not_visible": not_visible}
        for setting in ("off",) + RULES:
            if kind == "null":
                hit = [r["i"] for r in rs if r[setting]["findings"] or r[setting]["unexplained"]]
                d[setting] = {"with_entry_or_finding": hit, "rate": len(hit) / max(len(rs), 1),
                              "upper_95": upper_95(len(hit), len(rs))}
            else:
                hit = [r["i"] for r in rs if r[setting]["unexplained"] and not r[setting]["findings"]]
                named = [r["i"] for r in rs if r[setting]["findings"]]
                d[setting] = {"unexplained": hit, "rate": len(hit) / max(len(rs), 1), "named_something": named}
                if setting != "off":
                    # against the same logs with the rule off: `unexplained` gained where it ended without, or lost
                    d[setting]["gained"] = [r["i"] for r in rs if not r["off"]["unexplained"] and r[setting]["unexplained"]]
                    d[setting]["lost"] = [r["i"] for r in rs if r["off"]["unexplained"] and not r[setting]["unexplained"]]
                    d[setting]["name_gained"] = [r["i"] for r in rs
                                                 if set(r[setting]["findings"]) - set(r["off"]["findings"])]
        if kind == "oov":
            d["none_off"] = [r["i"] for r in rs if not r["off"]["unexplained"]]
        out[kind] = d
    return out


SETTING_NAMES = {"off": "guard as kept (off)", "TIME_SHIFT_NO_ADC_GUARD": "lifted wherever the test runs (76th)",
                 "TIME_SHIFT_GUARD_LIFTED_IN_RANGE": "lifted where the delay is in range (77th, 79th)"}


def table(s: dict) -> str:
    """The docs' table of a :func:`summary`: per setting, the null logs with an entry or a finding (rate and its 95 %
    upper bound) and the visible out-of-vocabulary logs `unexplained` and named."""
    n, o = s.get("null"), s.get("oov")
    lines = [f"| setting | null logs with an entry or finding (of {n['logs'] if n else 0}) | 95 % upper bound | "
             f"out of vocabulary `unexplained` (of {o['logs'] if o else 0} visible) | out of vocabulary, a name |",
             "|---|---|---|---|---|"]
    for k in ("off",) + RULES:
        a = f"{len(n[k]['with_entry_or_finding'])} ({100 * n[k]['rate']:.1f} %)" if n else "-"
        b = f"{100 * n[k]['upper_95']:.2f} %" if n else "-"
        c = f"{len(o[k]['unexplained'])} ({100 * o[k]['rate']:.1f} %)" if o else "-"
        d = ", ".join(f"i = {i}" for i in o[k]["named_something"]) or "none" if o else "-"
        lines.append(f"| {SETTING_NAMES[k]} | {a} | {b} | {c} | {d} |")
    return "\n".join(lines)


def _read(paths) -> list:
    rows = []
    for p in paths:
        try:
            rows += json.loads(Path(p).read_text())
        except (OSError, ValueError) as e:
            raise SystemExit(f"cannot read {p}: {e}")
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kind", default="null")
    ap.add_argument("--rate", type=float, default=50.0, help="sample rate [Hz] of the generated logs (50)")
    ap.add_argument("--noise", default="quantized", help="torque noise: quantized (default), gaussian, student_t")
    ap.add_argument("--start", type=int, default=0)
    ap.add_argument("--n", type=int, default=100)
    ap.add_argument("--lane", default=None, metavar="I/N")
    ap.add_argument("--json", default=None)
    ap.add_argument("--summary", nargs="+", default=None, metavar="JSON")
    ap.add_argument("--table", nargs="+", default=None, metavar="JSON", help="the docs' table of these runs")
    a = ap.parse_args(argv)
    if a.summary:
        print(json.dumps(summary(_read(a.summary)), indent=1))
        return
    if a.table:
        print(table(summary(_read(a.table))))
        return
    if a.kind not in SEED_BASE:
        raise SystemExit(f"--kind must be null or oov, got {a.kind!r}")
    spec(a.kind, 0, a.rate, a.noise)            # a bad option: one line, before any log is generated
    rows = run(a.kind, a.start, a.n, a.lane, a.json, a.rate, a.noise)
    print(json.dumps(summary(rows), indent=1))


if __name__ == "__main__":
    main()
