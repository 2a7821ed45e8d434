"""The docs' lines for a fresh closed-loop block: the paragraph of ``docs/readme/diagnose_testbench.md`` that counts
it and lists its misses, out-of-vocabulary logs that end as "none" and null logs that are not clean, and its rows of
the three tables (runs, the "unexplained" verdict, the ambiguity), from the block's JSON
(``bench_diagnose_testbench.py --family loop --start N --n-loop 100 --json F``).

What it cannot write: the reading of a wrong name (why the log was named so, and what mends it), which is a finding
of its own and is written by hand after the paragraph's "wrong name" list; and the per-block count of wrong names
("Fresh blocks 700-...: as in the twentieth round's list, then ..."), which is appended by hand.

    python benchmarks/fresh_block_docs.py --sha 639745a benchmarks/results/diagnose_testbench_loop_heldout41400.json
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_diagnose_testbench as B  # noqa: E402

#: how the paragraphs name each effect
PHRASE = {
    "position_dependent_load": "a load", "stribeck": "Stribeck", "asymmetric_coulomb": "an asymmetric level",
    "position_dependent_friction": "a position friction", "time_periodic_disturbance": "a time-periodic disturbance",
    "energy_dependent_friction": "an energy drift", "abrupt_change": "an abrupt change",
    "motor_position_ripple": "a motor-position ripple", "compliance": "compliance", "backlash": "backlash",
    "sensor_delay": "a sensor delay"}
NOISE = {"gaussian": "", "student_t": " with Student-t noise", "quantized": " with a quantized torque"}


def _phrase(effect: str) -> str:
    return PHRASE.get(effect, effect.replace("_", " "))


def conditions(c: dict, short: bool = False) -> str:
    """" at 250 Hz with a quantized torque over 300 s" (the duration only when it is not 120 s; ``short``: "quantized"
    for the noise, as the out-of-vocabulary lists have it)."""
    noise = NOISE.get(c.get("noise"), f" with {c.get('noise')} noise")
    if short and c.get("noise") == "quantized":
        noise = " quantized"
    out = f" at {c['sample_rate']:g} Hz{noise}"
    if c.get("duration") and abs(c["duration"] - 120.0) > 1e-9:
        out += f" over {c['duration']:g} s"
    return out


def planted(c: dict) -> str:
    """The planted effects in words: "a load beside Stribeck"."""
    effs = [_phrase(e) for e in c["truth"].split(" (not visible")[0].split("+") if e and e != "none"]
    return " beside ".join(effs) if effs else "nothing"


def _the(effect: str) -> str:
    """"the load", "the Stribeck law"."""
    p = _phrase(effect)
    if p == "Stribeck":
        return "the Stribeck law"
    return "the " + p.split(" ", 1)[1] if p.startswith(("a ", "an ")) else "the " + p


def _join(items) -> str:
    items = list(items)
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def _missed(c: dict) -> str:
    got = "ends as \"none\"" if c["got"] == "none" else f"reported as `{c['got']}`"
    missed = [_the(e) for e in c.get("missed", [])]
    what = f", {_join(missed)} missed" if c["got"] != "none" and missed else ""
    return f"{c['k']}, {planted(c)}{conditions(c)}: {got}{what}"


def _oov(cases) -> str:
    groups = {}
    for c in cases:
        groups.setdefault(c["truth"].split(" (")[0], []).append(c)
    parts = []
    for truth, cs in groups.items():
        name = _phrase(truth) if len(cs) == 1 else _phrase(truth).replace("a sensor delay", "sensor delays")
        parts.append(name + " " + _join(f"{c['k']}{conditions(c, short=True)}" for c in cs))
    return "; ".join(parts)


def _none_or(items: list, fmt) -> str:
    return f" ({'; '.join(fmt(c) for c in items)})" if items else ""


def _dirty(r: dict) -> str:
    """A null log that is not clean: "41618 at 10 Hz: `unexplained` (acceleration)"."""
    what = f" ({', '.join(r['unexplained'])})" if r["got"] == "unexplained" and r.get("unexplained") else ""
    return f"{r['k']}{conditions(r)}: `{r['got']}`{what}"


def _refused(d: dict) -> str:
    """"1 refused (41886: too few samples in the training or validation half), so 99 logs; " ("" when none)."""
    import re
    got = d.get("refused") or []
    if not got:
        return ""

    def why(x):
        m = re.search(r"joint \d+: (.*)\)$", x["reason"])
        return m.group(1) if m else x["reason"]
    listed = "; ".join(f"{x['k']}: {why(x)}" for x in got)
    return f"{len(got)} refused ({listed}), so {d['logs']} logs; "


def block_range(d: dict) -> tuple:
    ks = [r["k"] for r in d["rows"]] + [x["k"] for x in d.get("refused") or []]
    return min(ks), max(ks)


def paragraph(d: dict, name: str, sha: str) -> str:
    """The block's paragraph (without the reading of a wrong name)."""
    lo, hi = block_range(d)
    oov_none = [c for c in d["oov_not_unexplained_cases"] if c["got"] == "none"]
    oov_other = [c for c in d["oov_not_unexplained_cases"] if c["got"] != "none"]
    dirty = [r for r in d["rows"] if B.row_kind(r) == "null" and r["got"] != "none"]
    w = d["wrong_names"]
    text = (f"**Fresh specs {lo}-{hi}**, run once with {sha} (`{name}`, the same way): {_refused(d)}"
            f"{d['correct']} / {d['logs']} "
            f"correct, **{w} wrong name{'' if w == 1 else 's'}**, {d['missed']} missed"
            f"{_none_or(d['missed_cases'], _missed)}, {d['oov_unexplained_right']} / {d['oov_logs']} out-of-vocabulary "
            f"`unexplained`")
    if oov_none or oov_other:
        bits = []
        if oov_none:
            bits.append(_oov(oov_none) + " end" + ("s" if len(oov_none) == 1 else "") + " as \"none\"")
        bits += [f"{c['k']}, {planted(c)}{conditions(c)}, is reported as `{c['got']}`" for c in oov_other]
        text += f" ({'; '.join(bits)})"
    text += f", {d['null_logs_clean']} / {d['null_logs']} null logs clean"
    text += _none_or(dirty, _dirty)
    if w:
        text += "; " + "; ".join(f"**{c['k']}**, {planted(c)}{conditions(c)}, is reported as `{c['got']}`"
                                 for c in d["wrong_name_cases"])
    return text + "."


def table_rows(d: dict, name: str, sha: str) -> list:
    """The block's rows of the runs table, the "unexplained" table and the ambiguity table."""
    lo, hi = block_range(d)
    run = f"| {lo}-{hi}, {sha}, run once (`{name}`)" + B.count_cells(d)
    return [run, B.unexplained_line(f"`{name}`", d), B.ambiguity_line(f"`{name}`", d)]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sha", required=True, help="the commit whose code ran the block")
    ap.add_argument("json", nargs="+", help="the blocks' JSON files")
    a = ap.parse_args(argv)
    for p in a.json:
        try:
            d = json.load(open(p))
            d["rows"]
        except (OSError, ValueError, KeyError) as e:
            print(f"fresh_block_docs: {p}: not a testbench JSON ({e})", file=sys.stderr)
            return 2
        name = Path(p).name
        print(paragraph(d, name, a.sha))
        print()
        for line in table_rows(d, name, a.sha):
            print(line)
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
