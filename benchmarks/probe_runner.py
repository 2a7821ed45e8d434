"""The loop that every probe of a diagnosis rule runs: switch the rule on, wrap the core function where it acts so
that each firing is recorded, diagnose each kept log given, and store the rows of the logs where it fired beside
their kept rows (a log where it never fired gets the kept row's diagnosis: the rule changes nothing else).

Used by ``probe_time_laws_readings_likelihood.py`` (sixty-eighth round), ``probe_pair_rescue.py`` (seventieth) and
``probe_held_back_rival.py`` (seventy-first).
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_diagnose_testbench as B  # noqa: E402

FAMILIES = ("loop", "testbench")


def kept_rows(family: str, keys) -> dict:
    """{k: (kept JSON, kept row)} of ``family``'s kept logs; exits with a one-line message when a key has none."""
    if family not in FAMILIES:
        raise SystemExit(f"--family must be loop or testbench, got {family!r}")
    kept = {k: v for (f, _, k), v in B.kept_rows_naming("any").items() if f == family}
    missing = [k for k in keys if k not in kept]
    if missing:
        raise SystemExit(f"no kept {family} row for k = {missing[0]} ({len(missing)} such)")
    return kept


def run_rule_probe(out_path: str, keys, family: str, *, rule: str, func: str, record, hits_key: str,
                   row_class=None, compare_off: bool = False, module: str = "core") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with ``<module>.<rule>`` set True and ``<module>.<func>`` wrapped
    (``module``: a module of :mod:`drake_est.diagnose`, ``core`` unless given):
    ``record(result, args, kwargs)`` returns what to store of one call (None: the rule did not fire there).  The logs
    where it fired are listed under ``touched`` (``hits_key``: the records) and their rows stored with ``kept_json`` and
    ``kept_row``; ``compare_off``: such a log is diagnosed again with the rule off, its rows stored under ``rows_off``
    (the same machine's last digits), its refusals under ``refused_off``.  ``row_class(family, kept_row)``: a class
    counted under ``classes_examined``.
    Writes ``out_path`` every ten logs (``examined`` says how far a stopped run got) and at the end."""
    import importlib
    mod = importlib.import_module(f"drake_est.diagnose.{module}")
    kept = kept_rows(family, keys)
    make = B.loop_cases if family == "loop" else B.cases
    was_on, original = getattr(mod, rule), getattr(mod, func)
    hits = []

    def counted(*a, **kw):
        got = original(*a, **kw)
        rec = record(got, a, kw)
        if rec is not None:
            hits.append(rec)
        return got

    res = {"rule": rule, "family": family, "examined": 0, "keys_examined": [], "touched": [], "rows": [],
           "refused": []}
    if row_class is not None:
        res["classes_examined"] = {}
    if compare_off:
        res["rows_off"], res["refused_off"] = [], []
    setattr(mod, func, counted)
    try:
        for m, k in enumerate(keys):
            spec = make(k + 1)[k]
            hits.clear()
            rows = []
            setattr(mod, rule, True)
            B._run_family(family, [spec], rows, k, res["refused"])
            res["examined"] += 1
            res["keys_examined"].append(k)
            c = row_class(family, kept[k][1]) if row_class is not None else None
            if c is not None:
                res["classes_examined"][c] = res["classes_examined"].get(c, 0) + 1
            if hits:
                res["touched"].append({"k": k, **({"class": c} if c is not None else {}), hits_key: list(hits)})
                for r in rows:
                    r["kept_json"], r["kept_row"] = kept[k][0], kept[k][1]
                    res["rows"].append(r)
                if compare_off:
                    setattr(mod, rule, False)
                    B._run_family(family, [spec], res["rows_off"], k, res["refused_off"])
            if m % 10 == 9:
                B._write_json(res, out_path)
    finally:
        setattr(mod, func, original)
        setattr(mod, rule, was_on)
    B._write_json(res, out_path)
    return res


def keys_args(argv) -> tuple:
    """(family, the other arguments) of a probe's ``--keys ... [--family=F]`` command line (``argv[0]`` is
    ``--keys``); the family is ``loop`` unless given."""
    family, rest = "loop", []
    for a in argv[1:]:
        if a.startswith("--family="):
            family = a.split("=", 1)[1]
        else:
            rest.append(a)
    return family, rest


def kept_keys(family: str, predicate, results_dir=None) -> list:
    """The spec numbers of ``family``'s kept rows for which ``predicate(row)`` holds, sorted (a probe's screen of the
    kept rows it can touch)."""
    return sorted(k for (f, _, k), (_, r) in B.kept_rows_naming("any", results_dir).items()
                  if f == family and predicate(r))


def named_keys_cli(argv, named_keys) -> None:
    """``--keys named [--family=F]``: print ``named_keys(family)``."""
    family, rest = keys_args(argv)
    if rest != ["named"]:
        raise SystemExit("--keys: expected 'named'")
    print(" ".join(str(k) for k in named_keys(family)))


def screened_keys(paths, count: str, family: str = "loop") -> list:
    """The spec numbers of ``family`` that the screens ``paths`` (``bench_diagnose_testbench.py --kept-with-count
    COUNT`` JSONs) list as touched, sorted; exits when a file is a screen of another count."""
    import json
    out = set()
    for p in paths:
        d = json.load(open(p))
        if d.get("count") != count:
            raise SystemExit(f"{p}: not an {count} screen (count = {d.get('count')!r})")
        out |= {int(k) for f, k, _ in d["touched"] if f == family}
    return sorted(out)


def screen_keys_cli(argv, count: str) -> None:
    """``--keys SCREEN.json ... [--family=F]``: print :func:`screened_keys` of the ``count`` screens given."""
    family, paths = keys_args(argv)
    if not paths:
        raise SystemExit("--keys: give the screens' JSON files")
    print(" ".join(str(k) for k in screened_keys(paths, count, family)))


def probe_main(argv, doc: str, keys_cli, run) -> None:
    """The command line every probe shares: ``--keys ...`` (``keys_cli(argv)`` prints the keys), ``--table-row`` and
    ``--summary`` (:func:`probe_jitter_second_differences.report_cli`), else ``[--family=F] OUT.json K...`` given to
    ``run(out_path, keys, family)``."""
    from probe_jitter_second_differences import report_cli
    argv = list(argv)
    if argv and argv[0] == "--keys":
        keys_cli(argv)
        return
    if report_cli(argv):
        return
    family = "loop"
    if argv and argv[0].startswith("--family="):
        family = argv.pop(0).split("=", 1)[1]
    if len(argv) < 2:
        raise SystemExit(doc)
    try:
        keys = [int(x) for x in argv[1:]]
    except ValueError as e:
        raise SystemExit(f"expected spec numbers after OUT.json: {e}")
    res = run(argv[0], keys, family)
    print(f"examined {res['examined']}, rule fired in {len(res['touched'])}, diagnosed {len(res['rows'])}")
