"""Confusion matrices of the diagnosis on logs from three generators (``--family``, default all three):

* ``testbench``: :mod:`drake_est.diagnose.testbench` (open-loop square-wave speed levels, torque = model +
  noise): every effect alone, pairs, one-third size, Stribeck with several vs, time-periodic disturbances at
  several frequencies, null logs with Gaussian, Student-t and quantized noise, 10-1000 Hz, and the
  out-of-vocabulary effects (backlash, delay) that must end as "unexplained";
* ``loop``: :mod:`drake_est.diagnose.testbench_loop` (a simulated axis under a PID position loop, point-to-point
  and multisine references, the logged torque is the controller's command; its own shapes of every effect and
  its own out-of-vocabulary effects: backlash, compliance, sensor_delay).  An effect that the generator finds
  not visible in the log (its visibility rule) is optional: not required, and not wrong when named;
* ``synth``: :func:`drake_est.synth.synthesize` (Drake IRB 140), single-joint effects of synth's vocabulary on
  joint 1, each log diagnosed with ``robot="generic"`` and with ``robot="irb140"``.

(One-speed logs, where ripple and time-periodic are ambiguous, are in
tests/test_diagnose_multilog.py, not here.)  The ``got`` label of a finding reported "ambiguous between A and
B" is ``ambiguous(A|B)``.

A log counts as: ``correct`` (every planted vocabulary effect named or part of an "ambiguous between"
pair, no other name; out-of-vocabulary: no name and a non-empty ``unexplained``), ``wrong`` (a name not
planted), ``missed`` (a planted effect not named).

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/bench_diagnose_testbench.py [--family testbench,loop,synth]
           [--n 150] [--n-loop 100] [--n-synth 8] [--json out.json]
       python benchmarks/bench_diagnose_testbench.py --from-json out.json   (counts, matrices, README table again)
       python benchmarks/bench_diagnose_testbench.py --rerun-kept time_periodic_disturbance [--lane 0/2]
           [--sample-rate 10] --json r.json
           (every kept row whose planted effects or findings name the effect, diagnosed again with this code and
           compared with the kept row; --from-json r0.json,r1.json merges the lanes' differences)
"""
from __future__ import annotations

import argparse
import json
import os
import time
from collections import Counter

import numpy as np

os.environ.setdefault("DRAKE_EST_NO_PROGRESS", "1")

SINGLE = ["stribeck", "time_periodic_disturbance", "motor_position_ripple", "position_dependent_friction",
          "position_dependent_load", "asymmetric_coulomb", "abrupt_change", "energy_dependent_friction"]
PAIRS = [("stribeck", "motor_position_ripple"), ("time_periodic_disturbance", "asymmetric_coulomb"),
         ("position_dependent_friction", "abrupt_change"), ("stribeck", "time_periodic_disturbance")]
OOV = ["backlash", "delay"]
#: the closed-loop generator's own pairs and out-of-vocabulary effects
LOOP_PAIRS = [("stribeck", "position_dependent_load"), ("time_periodic_disturbance", "position_dependent_friction"),
              ("motor_position_ripple", "abrupt_change"), ("asymmetric_coulomb", "stribeck")]
LOOP_OOV = ["backlash", "compliance", "sensor_delay"]
#: synth's single-joint vocabulary (joint 1)
SYNTH = ["none", "position_dependent_friction", "motor_position_ripple", "asymmetric_coulomb", "abrupt_change",
         "energy_dependent_friction", "none", "motor_position_ripple"]
FAMILY_ORDER = ["testbench", "loop", "synth"]


def cases(n: int):
    """n randomized log specs cycling through the families (seeded)."""
    fam = ([("single", (e,)) for e in SINGLE] + [("pair", p) for p in PAIRS] + [("third", (e,)) for e in SINGLE[:4]]
           + [("null", ())] * 3 + [("oov", (e,)) for e in OOV])
    out = []
    for k in range(n):
        kind, effs = fam[k % len(fam)]
        rng = np.random.default_rng(500 + k)
        size = 1.0 / 3.0 if kind == "third" else 1.0
        spec = {"effects": {e: size for e in effs}, "seed": 1000 + k,
                "sample_rate": float(rng.choice([10.0, 50.0, 100.0, 250.0, 1000.0])),
                "duration": float(rng.choice([120.0, 120.0, 300.0])),
                "noise": ["gaussian", "student_t", "quantized"][k % 3],
                "noise_std": float(rng.uniform(0.02, 0.1)), "speeds": 6}
        if spec["sample_rate"] >= 1000:
            spec["duration"] = 120.0
        if "energy_dependent_friction" in effs:
            spec["duration"] = 600.0
            spec["sample_rate"] = min(spec["sample_rate"], 50.0)
        if "stribeck" in effs:
            spec["effects"]["_vs"] = float(rng.choice([0.05, 0.1, 0.2]))
        if "time_periodic_disturbance" in effs:
            spec["effects"]["_f_hz"] = float(min(rng.choice([0.7, 3.0, 11.0, 37.0]), 0.3 * spec["sample_rate"]))
        out.append(spec)
    return out


def loop_cases(n: int):
    """n randomized specs for the closed-loop generator (seeded; its own pairs and third-size effects)."""
    fam = ([("single", (e,)) for e in SINGLE] + [("pair", p) for p in LOOP_PAIRS]
           + [("third", (e,)) for e in SINGLE[4:]] + [("null", ())] * 3 + [("oov", (e,)) for e in LOOP_OOV])
    out = []
    for k in range(n):
        kind, effs = fam[k % len(fam)]
        rng = np.random.default_rng(7000 + k)
        size = 1.0 / 3.0 if kind == "third" else 1.0
        spec = {"effects": {e: size for e in effs}, "seed": 3000 + k,
                "sample_rate": float(rng.choice([10.0, 50.0, 100.0, 250.0, 1000.0])),
                "duration": float(rng.choice([120.0, 120.0, 300.0])),
                "noise": ["gaussian", "student_t", "quantized"][(k // len(fam) + k) % 3],
                "noise_std": float(rng.uniform(0.03, 0.15))}
        if spec["sample_rate"] >= 1000:
            spec["duration"] = 120.0
        if "energy_dependent_friction" in effs:
            spec["duration"] = 600.0
            spec["sample_rate"] = min(spec["sample_rate"], 50.0)
        if "time_periodic_disturbance" in effs:
            spec["effects"]["_f_hz"] = float(min(rng.choice([0.5, 2.0, 6.0, 15.0, 40.0]), 0.3 * spec["sample_rate"]))
        out.append(spec)
    return out


def loop_log(spec, effects=None, **kw):
    """(Log, truth) of a closed-loop spec: a dict of :func:`loop_cases` or its index k (``loop_cases(k + 1)[k]``),
    with its own effects or ``effects`` instead (``kw``: e.g. ``reference_ulps``, passed to the generator)."""
    from drake_est.diagnose.testbench_loop import generate
    if not isinstance(spec, dict):
        spec = loop_cases(int(spec) + 1)[int(spec)]
    return generate(spec["effects"] if effects is None else effects, seed=spec["seed"], duration=spec["duration"],
                    sample_rate=spec["sample_rate"], noise=spec["noise"], noise_std=spec["noise_std"], **kw)


def synth_cases(n: int):
    """n specs for :func:`drake_est.synth.synthesize`: synth's single-joint effects on joint 1 (seeded)."""
    out = []
    for k in range(n):
        eff = SYNTH[k % len(SYNTH)]
        rng = np.random.default_rng(9000 + k)
        spec = {"effects": {} if eff == "none" else {eff: 1.0}, "seed": 5000 + k,
                "sample_rate": float(rng.choice([50.0, 100.0, 250.0])), "duration": 121.0,
                "noise_std": float(rng.uniform(0.1, 0.5))}
        if eff == "energy_dependent_friction":
            spec.update(duration=501.0, sample_rate=25.0)
        out.append(spec)
    return out


def judge(spec, d, optional=()):
    """Score one diagnosis against the planted effects; ``optional`` effects (planted but not visible in the
    log, by the generator's visibility rule) are neither required nor wrong when named."""
    optional = set(optional)
    planted = {e for e in spec["effects"] if not e.startswith("_")}
    oov_all = set(OOV) | set(LOOP_OOV)
    vocab = planted - oov_all - optional
    allowed = vocab | (optional - oov_all)
    named = set()
    for f in d["findings"]:
        named |= set(f.get("ambiguous_between", [f["effect"]]))
    wrong = sorted({f["effect"] for f in d["findings"]} - allowed
                   if not any(f.get("ambiguous_between") for f in d["findings"]) else
                   {f["effect"] for f in d["findings"]
                    if not (set(f.get("ambiguous_between", [f["effect"]])) & allowed)})
    missed = sorted(vocab - named)
    oov = (planted & oov_all) - optional
    unexpl_ok = (not oov) or bool(d["unexplained"])
    return {"wrong": wrong, "missed": missed, "oov_unexplained": unexpl_ok,
            "correct": not wrong and not missed and unexpl_ok}


def _matrix(conf) -> str:
    truths = sorted({t for t, _ in conf})
    gots = sorted({g for _, g in conf})
    L = ["| planted \\ diagnosed | " + " | ".join(gots) + " |", "|---" * (len(gots) + 1) + "|"]
    for t in truths:
        L.append(f"| {t} | " + " | ".join(str(conf.get((t, g), "")) for g in gots) + " |")
    return "\n".join(L)


def _planted(r) -> set:
    """The planted effects of a row that the log shows (its truth label without the "(not visible: ...)" part)."""
    return {e for e in r["truth"].split(" (not visible")[0].split("+") if e and e != "none"}


def row_kind(r) -> str | None:
    """``oov`` (an out-of-vocabulary effect planted and visible), ``null`` (nothing planted), ``vocab`` (no visible
    out-of-vocabulary effect, among them logs whose planted effects are all not visible), or None for a label with an
    out-of-vocabulary effect beside a "(not visible ...)" part (counted in none of the three)."""
    oov_all = set(OOV) | set(LOOP_OOV)
    if set(r["truth"].split("+")) & oov_all:
        return "oov"
    if r["truth"] == "none":
        return "null"
    return None if _planted(r) & oov_all else "vocab"


def _counts(rows) -> dict:
    conf = Counter((r["truth"], r["got"]) for r in rows)
    oov = [r for r in rows if row_kind(r) == "oov"]
    null = [r for r in rows if row_kind(r) == "null"]
    vocab = [r for r in rows if row_kind(r) == "vocab"]
    return {"logs": len(rows), "correct": sum(r["correct"] for r in rows),
            "wrong_names": sum(bool(r["wrong"]) for r in rows), "missed": sum(bool(r["missed"]) for r in rows),
            "oov_logs": len(oov), "oov_unexplained_right": sum(r["oov_unexplained"] and not r["wrong"] for r in oov),
            "oov_not_unexplained": sum(not r["oov_unexplained"] for r in rows),
            "null_logs": len(null), "null_logs_clean": sum(r["got"] == "none" for r in null),
            # the "unexplained" verdict on logs whose planted effects are all in the vocabulary (none out of it,
            # not null): structure the final model leaves although the generator planted nothing else
            "vocab_logs": len(vocab), "vocab_logs_with_unexplained": sum(bool(r.get("unexplained")) for r in vocab),
            "logs_with_ambiguous_finding": sum("ambiguous(" in r["got"] for r in rows),
            "correct_all_named_outright": sum(bool(r["correct"]) and _named_outright(r) for r in rows),
            "not_visible_effects": sum(len(r.get("not_visible", {})) for r in rows),
            "wrong_name_cases": [_case(r) for r in rows if r["wrong"]],
            "missed_cases": [dict(_case(r), missed=r["missed"]) for r in rows if r["missed"]],
            "oov_not_unexplained_cases": [_case(r) for r in rows if not r["oov_unexplained"]],
            "median_seconds_per_log": float(np.median([r["seconds"] for r in rows])) if rows else None,
            "confusion": {f"{t} -> {g}": c for (t, g), c in sorted(conf.items())},
            "matrix_markdown": _matrix(conf)}


def _named_outright(r) -> bool:
    """Every planted vocabulary effect of the row is named as a finding of its own, not only inside an
    ``ambiguous(A|B)`` finding (effects the generator marks not visible are not required)."""
    planted = _planted(r) - set(OOV) - set(LOOP_OOV)
    plain = {g for g in r["got"].split("+") if not g.startswith("ambiguous(")}
    return planted <= plain


def ambiguity_line(label, s) -> str:
    """A row of the ambiguity table of the diagnosis docs: logs, correct, correct with every planted effect named
    outright, logs with an ambiguous finding, wrong names, missed (tests/test_diagnose_testbench.py checks it)."""
    return (f"| {label} | {s['logs']} | {s['correct']} | {s['correct_all_named_outright']} | "
            f"{s['logs_with_ambiguous_finding']} | {s['wrong_names']} | {s['missed']} |")


def unexplained_line(label, s) -> str:
    """A row of the table of the "unexplained" verdict: out-of-vocabulary logs reported unexplained (and no
    wrong name), null logs clean, logs with only vocabulary effects that also get an "unexplained" entry
    (tests/test_diagnose_testbench.py checks it)."""
    return (f"| {label} | {s['oov_unexplained_right']} / {s['oov_logs']} | {s['null_logs_clean']} / {s['null_logs']} | "
            f"{s['vocab_logs_with_unexplained']} / {s['vocab_logs']} |")


def _case(r) -> dict:
    keys = ("k", "family", "robot", "truth", "got", "sample_rate", "duration", "noise", "noise_std", "samples")
    return {k: r[k] for k in keys if k in r}


def family_of(r) -> str:
    """The family key of a row: testbench, loop, synth/generic, synth/irb140 (rows of older JSON files have no
    family: testbench)."""
    fam = r.get("family", "testbench")
    return f"{fam}/{r.get('robot', 'generic')}" if fam == "synth" else fam


def summarize(rows) -> dict:
    """Counts, the confusion (truth -> what the diagnosis said) and markdown matrices from the per-log rows:
    overall and per family (``per_family``)."""
    out = _counts(rows)
    fams = sorted({family_of(r) for r in rows}, key=lambda f: (FAMILY_ORDER.index(f.split("/")[0]), f))
    out["per_family"] = {f: _counts([r for r in rows if family_of(r) == f]) for f in fams}
    out["rows"] = rows
    return out


def readme_table(summary, source="diagnose_testbench.json") -> list:
    """The README table rows (per family, then all) for a summary: tests/test_diagnose_testbench.py checks that
    docs/readme/diagnose_testbench.md holds exactly these lines for the kept JSON."""
    L = [f"| family (`{source}`) | logs | correct | wrong name | missed | out-of-vocabulary -> unexplained | "
         "null logs clean |", "|---|---|---|---|---|---|---|"]
    items = list(summary["per_family"].items()) + [("all", summary)]
    for name, s in items:
        L.append(f"| {name}" + count_cells(s))
    return L


def count_cells(s) -> str:
    """The count cells of a run-table row for a summary ``s``: `` | logs | correct | wrong | missed | oov | null |``."""
    return (f" | {s['logs']} | {s['correct']} | {s['wrong_names']} | {s['missed']} | "
            f"{s['oov_unexplained_right']} / {s['oov_logs']} | {s['null_logs_clean']} / {s['null_logs']} |")


def _print(summary):
    skip = ("rows", "matrix_markdown", "per_family")
    print(json.dumps({k: v for k, v in summary.items() if k not in skip}, indent=1))
    for fam, s in summary["per_family"].items():
        print(f"\n### {fam}: {s['correct']}/{s['logs']} correct, {s['wrong_names']} wrong names, {s['missed']} missed, "
              f"out-of-vocabulary unexplained {s['oov_unexplained_right']}/{s['oov_logs']}, "
              f"null clean {s['null_logs_clean']}/{s['null_logs']}\n")
        print(s["matrix_markdown"])
    print("\n### all\n")
    print(summary["matrix_markdown"])
    print()
    print("\n".join(readme_table(summary)))


def _label(effects, not_visible=()):
    vis = sorted(e for e in effects if not e.startswith("_") and e not in not_visible)
    lab = "+".join(vis) or "none"
    if not_visible:
        lab += " (not visible: " + "+".join(sorted(not_visible)) + ")"
    return lab


def _got(d):
    got = "+".join(sorted(f["effect"] if not f.get("ambiguous_between") else
                          "ambiguous(" + "|".join(f["ambiguous_between"]) + ")" for f in d["findings"]))
    return got or ("unexplained" if d["unexplained"] else "none")


def untestable_effects(d) -> list:
    """The vocabulary effects that the report's ``next_experiment`` entries declare untestable in this log ("stribeck
    untestable: ...", "stribeck with vs below ... untestable: ...", "asymmetric_coulomb untestable: ..."): the
    report names the experiment that would test them (issue 16 item 4)."""
    out = set()
    for e in d.get("next_experiment") or []:
        head = str(e.get("reason", "")).split(":")[0].split()
        if head and "untestable" in head and head[0] in set(SINGLE):
            out.add(head[0])
    return sorted(out)


def _row(k, family, robot, spec, log, d, dt, not_visible=None):
    nv = dict(not_visible or {})
    j = judge(spec, d, optional=nv)
    truth_name = _label(spec["effects"], nv)
    r = {"k": k, "family": family, "robot": robot, "truth": truth_name, "got": _got(d), "seconds": dt,
         "samples": int(log.n_samples), "sample_rate": spec.get("sample_rate"), "duration": spec.get("duration"),
         "noise": spec.get("noise", "gaussian"), "noise_std": spec.get("noise_std"),
         "unexplained": [u.get("variable") for u in d["unexplained"]],
         "set_aside": [x.get("effect") for x in d.get("set_aside") or []],
         # rows since the sixty-seventh round: what the report declares untestable, with the experiment to run
         "untestable": untestable_effects(d), **j}
    # the inertia backfit's move, per joint where it moved J ([J identified by prepare, J after the backfit]; rows
    # since the thirty-sixth round): a change to core.backfit_inertia can only touch the logs that record one
    params = (d.get("nominal") or {}).get("parameters") or {}
    backfit = {j: [p["J_before_backfit"], p["J"]] for j, p in params.items() if "J_before_backfit" in p}
    if backfit:
        r["inertia_backfit"] = backfit
    # a large move that the fit beside a free speed curve contradicts, withheld ([J moved to, J beside the curve];
    # rows since the fifty-fourth round)
    withheld = {j: [p["J_backfit_withheld"]["J_moved"], p["J_backfit_withheld"]["J_speed_curve"]]
                for j, p in params.items() if "J_backfit_withheld" in p}
    if withheld:
        r["inertia_backfit_withheld"] = withheld
    if nv:
        r["not_visible"] = nv
    return r


#: the robot models each family's logs are diagnosed with
FAMILY_ROBOTS = {"testbench": ["generic"], "loop": ["generic"], "synth": ["generic", "irb140"]}


def family_log(family, spec):
    """(Log, truth) of one spec of ``family`` (testbench, loop or synth)."""
    if family == "testbench":
        from drake_est.diagnose.testbench import generate
        return generate(spec["effects"], seed=spec["seed"], duration=spec["duration"],
                        sample_rate=spec["sample_rate"], speeds=spec["speeds"], noise=spec["noise"],
                        noise_std=spec["noise_std"])
    if family == "loop":
        return loop_log(spec)
    from drake_est.synth import synthesize
    effs = [e for e in spec["effects"]] or "none"
    return synthesize(effs, seed=spec["seed"], joints=[1], duration=spec["duration"],
                      sample_rate=spec["sample_rate"], noise_std=spec["noise_std"])


def _run_family(family, specs, rows, start=0, refused=None):
    """Diagnose every spec of one family; rows get k = start + index.  A log that the diagnosis refuses with a
    one-line DataError (e.g. too few steady samples) is listed in ``refused`` (k, reason), not scored."""
    from drake_est.diagnose import diagnose
    from drake_est.errors import DataError
    from drake_est.progress import progress
    for k, spec in enumerate(progress(specs, desc=family), start=start):
        log, truth = family_log(family, spec)
        nv = truth["not_visible"] if family == "loop" else None
        for robot in FAMILY_ROBOTS[family]:
            t0 = time.perf_counter()
            try:
                d = diagnose(log, robot=robot, seed=0, simulate=False).to_dict()
            except DataError as e:
                if refused is None:
                    raise
                refused.append({"k": k, "family": family, "robot": robot, "reason": str(e)})
                print(f"{family:9s} {robot:7s} {k:3d} refused: {e}", flush=True)
                continue
            dt = time.perf_counter() - t0
            r = _row(k, family, robot, spec, log, d, dt, nv)
            rows.append(r)
            print(f"{family:9s} {robot:7s} {k:3d} {r['truth']:50s} -> {r['got']:50s} "
                  f"{'ok' if r['correct'] else 'FAIL'} {spec['sample_rate']:6.0f} Hz {spec['duration']:4.0f} s "
                  f"{spec.get('noise', 'gaussian'):9s} {dt:5.1f}s", flush=True)


#: what a row of a kept JSON is compared on when a log is diagnosed again (--rerun-kept)
ROW_OUTCOME = ("got", "correct", "wrong", "missed", "oov_unexplained", "unexplained")


def kept_jsons(results_dir=None) -> list:
    """The kept benchmark JSONs of this script in ``benchmarks/results`` (the plain names: not the earlier
    rounds' ``*_roundN*.json`` nor ``_before``/``_first``/``_second``/``_third`` copies)."""
    import re
    from pathlib import Path
    d = Path(results_dir) if results_dir else Path(__file__).resolve().parent / "results"
    return sorted(f for f in d.glob("diagnose_testbench*.json")
                  if not re.search(r"_round|_before|_first|_second|_third", f.name))


def kept_rows_naming(effect: str, results_dir=None, sample_rate: float | None = None) -> dict:
    """{(family, robot, k): (JSON name, row)} of the kept rows whose planted effects, findings or set-aside
    findings (rows since the seventeenth round) name ``effect`` (``"any"``: every row), at ``sample_rate`` [Hz] only
    when given."""
    out = {}
    for f in kept_jsons(results_dir):
        for r in json.load(open(f)).get("rows", []):
            if sample_rate is not None and r["sample_rate"] != sample_rate:
                continue
            if effect == "any" or effect in r["truth"] or effect in r["got"] or effect in r.get("set_aside", []):
                out[(r["family"], r["robot"], r["k"])] = (f.name, r)
    return out


def _wrong(n) -> str:
    """"N wrong names" (singular for one)."""
    return f"{n} wrong name" + ("" if n == 1 else "s")


def results_row(results_dir=None) -> str:
    """The README's "Results at a glance" row of this benchmark, read off the kept JSONs (every kept row with the
    latest code that ran it, per family) and the latest closed-loop block JSON (its fresh block, run once):
    tests/test_diagnose_testbench.py checks that docs/readme/_results.md holds exactly this line."""
    import re
    kept = kept_rows_naming("any", results_dir)
    s = summarize([r for _, r in kept.values()])
    fam = s["per_family"]
    t, lp = fam["testbench"], fam["loop"]
    synth = [x for f, x in fam.items() if f.startswith("synth/")]
    sc, sl, sw = (sum(x[k] for x in synth) for k in ("correct", "logs", "wrong_names"))
    last = max(k for f, _, k in kept if f == "loop")
    blocks = sorted((int(re.search(r"heldout(\d+)", f.name).group(1)), f) for f in kept_jsons(results_dir)
                    if re.fullmatch(r"diagnose_testbench_loop_heldout\d+\.json", f.name))
    lo, lf = blocks[-1]
    # the latest block as first run (run once): its *_roundN_first.json copy where a later change replaced rows
    first = sorted(lf.parent.glob(f"diagnose_testbench_loop_heldout{lo}_round*_first.json"))
    lf = first[0] if first else lf
    b = summarize(json.load(open(lf))["rows"])
    return (f"| diagnosis on generators other than synth and on synth ({s['logs']:,} kept logs: open-loop testbench "
            f"{t['logs']} — single effects, pairs, ⅓-size effects, Stribeck, time-periodic disturbances, "
            f"backlash/delay, Gaussian/Student-t/quantized null logs, 10–1000 Hz; closed-loop axis, specs 0-{last} — "
            f"PID loop, p2p/multisine, its own effect shapes, backlash/compliance/sensor delay; synth {sl}) | — | "
            f"open-loop testbench **{_wrong(t['wrong_names'])}**, {t['correct']}/{t['logs']} correct, "
            f"{t['oov_unexplained_right']}/{t['oov_logs']} out-of-vocabulary `unexplained`, "
            f"{t['null_logs_clean']}/{t['null_logs']} null logs clean; closed loop, each log with the latest code "
            f"that ran it: **{_wrong(lp['wrong_names'])}**, {lp['correct']:,}/{lp['logs']:,} correct, "
            f"{lp['missed']} missed, {lp['oov_unexplained_right']}/{lp['oov_logs']} out-of-vocabulary `unexplained`, "
            f"{lp['null_logs_clean']}/{lp['null_logs']} null logs clean; synth {sc}/{sl} correct, {_wrong(sw)}; "
            f"latest fresh block ({lo}-{lo + 99}, run once): {b['correct']}/{b['logs']} correct, "
            f"{_wrong(b['wrong_names'])}, {b['oov_unexplained_right']}/{b['oov_logs']} out-of-vocabulary "
            f"`unexplained`, {b['null_logs_clean']}/{b['null_logs']} null logs clean. Zero wrong names does not "
            f"reliably carry over to fresh specs: see the roadmap | `python benchmarks/bench_diagnose_testbench.py` "
            f"(a fresh block: `--family loop --start N --n-loop 100`; this row: `--results-row`) |")


def row_differences(kept: dict, rows) -> list:
    """The rows of a run again whose outcome (:data:`ROW_OUTCOME`; ``unexplained`` as a set) differs from the
    kept row of the same (family, robot, k): [{json, family, robot, k, field: [kept, new]...}]."""
    out = []
    for r in rows:
        key = (r["family"], r["robot"], r["k"])
        if key not in kept:
            continue
        name, old = kept[key]
        d = {}
        for fld in ROW_OUTCOME:
            a, b = old.get(fld), r.get(fld)
            if fld == "unexplained":
                a, b = sorted(set(a or [])), sorted(set(b or []))
            if a != b:
                d[fld] = [a, b]
        if d:
            out.append({"json": name, "family": r["family"], "robot": r["robot"], "k": r["k"], **d})
    return out


def read_only_file(path) -> set:
    """The logs an ``--only`` file names: one ``FAMILY K`` per line (``#`` starts a comment)."""
    out = set()
    for n, line in enumerate(open(path), 1):
        line = line.split("#")[0].split()
        if not line:
            continue
        if len(line) != 2 or line[0] not in FAMILY_ORDER or not line[1].isdigit():
            raise SystemExit(f"--only {path}, line {n}: expected 'FAMILY K' with FAMILY one of "
                             f"{', '.join(FAMILY_ORDER)}, got '{' '.join(line)}'")
        out.add((line[0], int(line[1])))
    return out


def _rerun_kept(effect: str, lane: str | None, sample_rate: float | None = None, only: set | None = None):
    """Diagnose again the kept logs whose rows name ``effect`` (``"any"``: all), at ``sample_rate`` only when given
    and among ``only`` {(family, k)} when given (lane ``i/n``: every n-th by cost, from i)."""
    kept = kept_rows_naming(effect, sample_rate=sample_rate)
    if only is not None:
        missing = sorted(only - {(f, k) for f, _, k in kept})
        if missing:
            raise SystemExit(f"--only: {len(missing)} logs have no kept row naming '{effect}', e.g. {missing[0]}")
        kept = {key: v for key, v in kept.items() if (key[0], key[2]) in only}
    if not kept:
        raise SystemExit(f"--rerun-kept: no kept row names '{effect}'"
                         + (f" at {sample_rate:g} Hz" if sample_rate is not None else ""))
    i, n = _lane(lane)
    specs = _specs_of(kept)
    jobs = sorted({(fam, k) for fam, _, k in kept}, key=lambda j: (-specs[j[0]][j[1]]["sample_rate"]
                                                                   * specs[j[0]][j[1]]["duration"], j))
    rows, refused = [], []
    for fam, k in jobs[i::n]:
        _run_family(fam, [specs[fam][k]], rows, k, refused)
    rows = [r for r in rows if (r["family"], r["robot"], r["k"]) in kept]
    return _rerun_summary(effect, sample_rate, f"{i}/{n}", rows, refused, row_differences(kept, rows))


def kept_logs_with_count(count: str, lane: str | None = None, sample_rate: float | None = None,
                         results_dir=None, only: set | None = None) -> dict:
    """The kept logs (every kept row, at ``sample_rate`` only when given; lane ``i/n``) whose preparation
    (:func:`drake_est.diagnose.nominal.prepare`, no diagnosis) records ``count`` > 0 for some joint, e.g.
    ``beyond_training_speeds``: the logs a change keyed on it can touch.  ``count`` = ``motion_line_gate``: the logs
    with a joint in :func:`drake_est.diagnose.core.motion_line_gate` (the nominal fit and one candidate, no search);
    ``unsupported_kernels``: the joints :func:`unsupported_kernel_sizes` lists; ``unsupported_changes``: the joints
    :func:`unsupported_change_joints` lists.
    ``only``: {(family, k)}, the logs to prepare (all kept logs when None).  {"logs": n, "touched": [[family, k,
    {joint: count}], ...], "refused": [...]}."""
    from drake_est.diagnose.nominal import prepare
    from drake_est.errors import DataError
    from drake_est.progress import progress
    kept = kept_rows_naming("any", results_dir, sample_rate=sample_rate)
    if only is not None:
        kept = {key: v for key, v in kept.items() if (key[0], key[2]) in only}
    i, n = _lane(lane)
    specs = _specs_of(kept)
    # lanes share out logs, not rows (a synth log has a row per robot)
    robots = {}
    for fam, robot, k in kept:
        robots.setdefault((fam, k), []).append(robot)
    lane_logs = sorted(robots, key=lambda x: (FAMILY_ORDER.index(x[0]), x[1]))[i::n]
    n_rows = sum(len(robots[x]) for x in lane_logs)
    touched, refused = [], []
    for fam, k in progress(lane_logs, desc=f"prepare ({count})"):
        log = family_log(fam, specs[fam][k])[0]
        got = {}
        for robot in sorted(robots[(fam, k)]):
            try:
                prep = prepare(log, robot=robot)
            except DataError as e:
                refused.append([fam, robot, k, str(e)])
                continue
            if count == "motion_line_gate":
                # the joints on which the search offers a time-periodic candidate at a line of the motion (decided
                # once per diagnosis on the data as first prepared: core.motion_line_gate)
                from drake_est.diagnose.core import motion_line_gate
                from drake_est.threads import single_thread_blas
                with single_thread_blas():
                    got.update({str(j): 1 for j in motion_line_gate(prep)})
                continue
            if count == "energy_fixed_point_gate":
                # the joints whose first-round energy candidate still moves the friction power after Algorithm 6's
                # fixed passes (core.energy_fixed_point_gate: where the hundred-and-eighth round's passes act first)
                from drake_est.diagnose.core import energy_fixed_point_gate
                from drake_est.threads import single_thread_blas
                with single_thread_blas():
                    got.update({str(j): round(m, 4) for j, m in energy_fixed_point_gate(prep).items()})
                continue
            if count == "unsupported_kernels":
                # the joints where a number of position kernels beyond the smallest has a kernel the training
                # positions hardly weigh (detectors.supported_sizes; the eighty-third round's rule drops those sizes)
                got.update({str(j): n for j, n in unsupported_kernel_sizes(prep).items()})
                continue
            if count == "unsupported_changes":
                # the joints where some split an abrupt change may take leaves a segment that hardly determines the
                # friction law at the log's extreme speeds (detectors.split_supports; the eighty-fourth round's rule
                # chooses the change time among the others)
                got.update({str(j): 1 for j in unsupported_change_joints(prep)})
                continue
            got.update({str(j): int(jd.counts[count]) for j, jd in prep.joints.items() if jd.counts.get(count)})
        if got:
            touched.append([fam, k, got])
    return _touched_summary({"count": count, "sample_rate": sample_rate, "lane": f"{i}/{n}", "logs": n_rows,
                             "touched": touched, "refused": refused})


def unsupported_kernel_sizes(prep) -> dict:
    """{joint: how many of the position laws' kernel counts (:data:`~drake_est.diagnose.detectors.BFE_SIZES`) a
    joint's training positions do not support} (:func:`~drake_est.diagnose.detectors.supported_sizes` over the
    detectors' :func:`~drake_est.diagnose.detectors.kernel_range`), joints with none left out."""
    import drake_est.diagnose.detectors as det
    out = {}
    for j, jd in prep.joints.items():
        q = jd.q[jd.rows][jd.train]
        span = det.kernel_range(q)
        if span is None:
            continue
        n = len(det.BFE_SIZES) - len(det.supported_sizes(q, *span))
        if n:
            out[j] = n
    return out


def unsupported_change_joints(prep, min_frac: float = 0.1) -> list:
    """The joints where a split that :func:`~drake_est.diagnose.detectors.change_point` may take (segments of at least
    ``min_frac`` of the training rows) leaves a segment below
    :data:`~drake_est.diagnose.detectors.MIN_CHANGE_SUPPORT` at the log's extreme speeds: a prefix's support only grows
    with its length, so the shortest first and last segments decide."""
    import drake_est.diagnose.detectors as det
    out = []
    for j, jd in prep.joints.items():
        v = jd.v[jd.rows]
        speeds = det.extreme_speeds(v)
        vt = v[jd.train]
        n = vt.size
        m = det.change_min_length(jd.train.sum(), min_frac)
        if speeds is None or n < 2 * m:
            continue
        before, after = det.split_supports(vt, speeds)
        if min(before[m], after[n - m]) < det.MIN_CHANGE_SUPPORT:
            out.append(j)
    return out


def _touched_summary(out) -> dict:
    """The JSON of a --kept-with-count run (one lane, or lanes merged with --from-json), printed as it is made."""
    print(f"{out['logs']} kept rows prepared (lane {out['lane']}); {len(out['touched'])} logs record "
          f"{out['count']}: " + ", ".join(f"{f} {k}" for f, k, _ in out["touched"]))
    return out


def _specs_of(kept) -> dict:
    """{family: its specs 0..K}, K the largest k of that family among the ``kept`` rows' keys."""
    kmax = {fam: max(k for f, _, k in kept if f == fam) + 1 for fam, _, _ in kept}
    return {"testbench": cases(kmax.get("testbench", 0)), "loop": loop_cases(kmax.get("loop", 0)),
            "synth": synth_cases(kmax.get("synth", 0))}


def _write_json(out, path) -> None:
    """``out`` to ``path`` (nothing when ``path`` is None)."""
    if path:
        from drake_est.jsonutil import dump_json
        dump_json(out, path)


def _lane(lane):
    if not lane:
        return 0, 1
    try:
        i, n = (int(x) for x in lane.split("/"))
        assert 0 <= i < n
    except (ValueError, AssertionError):
        raise SystemExit(f"--lane: expected I/N with 0 <= I < N, got '{lane}'") from None
    return i, n


def _rerun_summary(effect, sample_rate, lane, rows, refused, diffs) -> dict:
    """The JSON of a --rerun-kept run (one lane, or lanes merged with --from-json), printed as it is made."""
    print(f"{len(rows)} kept rows naming {effect} diagnosed again (lane {lane}); "
          f"{len(diffs)} differ from the kept row")
    for d in diffs:
        print("  ", d)
    return {"effect": effect, "sample_rate": sample_rate, "lane": lane, "logs": len(rows), "rows": rows,
            "refused": refused, "differences": diffs}


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--family", default="testbench,loop,synth", help="comma-separated: testbench, loop, synth")
    ap.add_argument("--n", type=int, default=150, help="logs from the open-loop testbench generator")
    ap.add_argument("--n-loop", type=int, default=100, help="logs from the closed-loop generator")
    ap.add_argument("--n-synth", type=int, default=8, help="synth logs (each diagnosed with generic and irb140)")
    ap.add_argument("--start", type=int, default=0,
                    help="first spec index of the testbench and loop families (e.g. --start 150 --n 150: 150 specs "
                         "never used in development, an out-of-sample check)")
    ap.add_argument("--json", default=None)
    ap.add_argument("--from-json", default=None,
                    help="re-summarize the rows of earlier --json outputs (comma-separated: e.g. one run per family, "
                         "run in parallel, merged into one summary)")
    ap.add_argument("--rerun-kept", default=None, metavar="EFFECT",
                    help="diagnose again every kept row (benchmarks/results) whose planted effects or findings name "
                         "EFFECT and list the rows whose outcome differs")
    ap.add_argument("--lane", default=None, metavar="I/N", help="with --rerun-kept: this process's share of the logs")
    ap.add_argument("--sample-rate", type=float, default=None,
                    help="with --rerun-kept: only the kept rows at this sample rate [Hz] (EFFECT 'any': all of them)")
    ap.add_argument("--only", default=None, metavar="FILE",
                    help="with --rerun-kept: only the logs FILE names, one 'FAMILY K' per line (e.g. the logs a "
                         "change can touch, found without diagnosing them)")
    ap.add_argument("--kept-with-count", default=None, metavar="COUNT",
                    help="prepare every kept log (no diagnosis; --lane, --sample-rate apply) and list those whose "
                         "preparation records COUNT for some joint (e.g. beyond_training_speeds); --only-out FILE "
                         "writes them as an --only file")
    ap.add_argument("--only-out", default=None, metavar="FILE", help="with --kept-with-count: the --only file")
    ap.add_argument("--results-row", action="store_true",
                    help="print the README's results row, read off the kept JSONs, and exit")
    a = ap.parse_args(argv)
    if a.results_row:
        print(results_row())
        return None
    if a.kept_with_count:
        out = kept_logs_with_count(a.kept_with_count, a.lane, a.sample_rate,
                                   only=None if a.only is None else read_only_file(a.only))
        if a.only_out:
            with open(a.only_out, "w") as f:
                f.write("".join(f"{fam} {k}\n" for fam, k, _ in out["touched"]))
        _write_json(out, a.json)
        return out
    if a.rerun_kept:
        out = _rerun_kept(a.rerun_kept, a.lane, a.sample_rate, None if a.only is None else read_only_file(a.only))
        _write_json(out, a.json)
        return out
    if a.from_json:
        parts = [json.load(open(f.strip())) for f in a.from_json.split(",") if f.strip()]
        if parts and all("touched" in d for d in parts):       # --kept-with-count lanes
            out = _touched_summary({
                "count": parts[0]["count"], "sample_rate": parts[0].get("sample_rate"),
                "lane": "+".join(d.get("lane", "?") for d in parts), "logs": sum(d["logs"] for d in parts),
                "touched": sorted((t for d in parts for t in d["touched"]),
                                  key=lambda t: (FAMILY_ORDER.index(t[0]), t[1])),
                "refused": [r for d in parts for r in d["refused"]]})
            _write_json(out, a.json)
            return out
        rows = [r for d in parts for r in d["rows"]]
        if parts and all("differences" in d for d in parts):
            out = _rerun_summary(parts[0]["effect"], parts[0].get("sample_rate"),
                                 "+".join(d.get("lane", "?") for d in parts), rows,
                                 [r for d in parts for r in d["refused"]],
                                 [x for d in parts for x in d["differences"]])
            _write_json(out, a.json)
            return out
        summary = summarize(rows)
        _print(summary)
        _write_json(summary, a.json)
        return summary
    fams = [f.strip() for f in a.family.split(",") if f.strip()]
    for f in fams:
        if f not in FAMILY_ORDER:
            raise SystemExit(f"--family: unknown family '{f}' (choose from {', '.join(FAMILY_ORDER)})")
    rows, refused = [], []
    if "testbench" in fams:
        _run_family("testbench", cases(a.start + a.n)[a.start:], rows, a.start, refused)
    if "loop" in fams:
        _run_family("loop", loop_cases(a.start + a.n_loop)[a.start:], rows, a.start, refused)
    if "synth" in fams:
        _run_family("synth", synth_cases(a.n_synth), rows, 0, refused)
    summary = summarize(rows)
    summary["refused"] = refused
    if refused:
        print(f"{len(refused)} log(s) refused by the diagnosis (not scored): " +
              "; ".join(f"{r['family']} {r['k']}" for r in refused))
    _print(summary)
    _write_json(summary, a.json)
    return summary


if __name__ == "__main__":
    main()
