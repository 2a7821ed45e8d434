"""Fold the rows of a rerun of kept benchmark logs into the kept block JSONs, and bring the docs' tables up to date.

A gated rerun (``bench_diagnose_testbench.py --rerun-kept ...``) writes JSONs of rows; a row that differs from its
kept row (on ``ROW_OUTCOME``) replaces it in its block JSON (``benchmarks/results/diagnose_testbench*.json``), whose
summary is then recomputed (``summarize``).  In ``docs/readme/diagnose_testbench.md`` every table row that names a
changed block JSON (a run row, an ``unexplained`` row, an ambiguity row) is rewritten with the new counts; a run row
whose counts change keeps its label, to which ``--label`` text is appended (e.g. "thirty-seventh round's rerun rows:
2406, 2409" says why a "run once" row no longer holds its first run's counts).  Prints what changed; ``--dry-run``
writes nothing.

    python benchmarks/fold_rerun_rows.py /work/refresh/out/c00_0.json /work/refresh/out/c00_1.json \\
        --label "refreshed by the thirty-eighth round's rerun"

Afterwards: ``python benchmarks/bench_diagnose_testbench.py --results-row`` into docs/readme/_results.md,
``python docs/build_readme.py``, and the doc tests (tests/test_diagnose_testbench.py).
"""
import argparse
import json
import os
import re
import sys
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_diagnose_testbench as b  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "readme" / "diagnose_testbench.md"
PAT = re.compile(r"`(diagnose_testbench_loop_heldout\d*(?:_[a-z0-9_]+)?\.json)`")


def differing_rows(rerun_jsons) -> dict:
    """{(family, robot, k): (kept JSON name, new row)} of the rerun rows that differ from their kept rows."""
    kept = b.kept_rows_naming("any")
    rows = [r for p in rerun_jsons for r in json.loads(Path(p).read_text())["rows"]]
    new = {(r["family"], r["robot"], r["k"]): r for r in rows}
    missing = [k for k in new if k not in kept]
    if missing:
        raise SystemExit(f"{len(missing)} rerun rows have no kept row, e.g. {missing[0]}")
    # the bench's own comparison (ROW_OUTCOME, ``unexplained`` as a set: its order is not an outcome)
    diffs = b.row_differences(kept, list(new.values()))
    return {(x["family"], x["robot"], x["k"]): (x["json"], new[(x["family"], x["robot"], x["k"])]) for x in diffs}


def fold(changes: dict, dry_run: bool = False) -> dict:
    """Replace the changed rows in their block JSONs and recompute their summaries; {JSON name: [k, ...]}."""
    from drake_est.jsonutil import dump_json
    by_file = {}
    for key, (name, r) in changes.items():
        by_file.setdefault(name, {})[key] = r
    for name, rows in sorted(by_file.items()):
        p = ROOT / "benchmarks" / "results" / name
        d = json.loads(p.read_text())
        n = 0
        for i, r in enumerate(d["rows"]):
            key = (r["family"], r["robot"], r["k"])
            if key in rows:
                d["rows"][i] = rows[key]
                n += 1
        if n != len(rows):
            raise SystemExit(f"{name}: {len(rows)} rows to replace, {n} found")
        s = b.summarize(d["rows"])
        for k in list(d):
            if k in s:
                d[k] = s[k]
        if not dry_run:
            dump_json(d, p)
    return {name: sorted(k for _, _, k in rows) for name, rows in by_file.items()}


def update_tables(files: dict, label: str | None, dry_run: bool = False) -> list:
    """Rewrite the docs' table rows that name one of ``files``; returns [(old line, new line)]."""
    lines = DOC.read_text().split("\n")
    changed = []
    for i, line in enumerate(lines):
        st = line.strip()
        m = PAT.search(st) if st.startswith("| ") else None
        if m is None or m.group(1) not in files:
            continue
        f = m.group(1)
        h = b.summarize(json.loads((ROOT / "benchmarks" / "results" / f).read_text())["rows"])
        run = re.match(r"^\| (.+) \(`" + re.escape(f) + r"`\) \| ", st)
        if run:
            counts = b.count_cells(h)
            if st.endswith(counts):
                continue
            lab = run.group(1) + (f"; {label}: {', '.join(map(str, files[f]))}" if label else "")
            new = f"| {lab} (`{f}`)" + counts
        else:
            u, a = b.unexplained_line(f"`{f}`", h), b.ambiguity_line(f"`{f}`", h)
            cells = st.count("|")
            fits = [x for x in (u, a) if x.count("|") == cells]
            if st in (u, a) or len(fits) != 1:
                continue
            new = fits[0]
        if new != st:
            changed.append((st, new))
            lines[i] = new
    if not dry_run:
        DOC.write_text("\n".join(lines))
    return changed


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rerun_json", nargs="+")
    ap.add_argument("--label", default=None, help="appended to a changed run row's label, with the rows' k")
    ap.add_argument("--dry-run", action="store_true")
    a = ap.parse_args(argv)
    changes = differing_rows(a.rerun_json)
    for (fam, _, k), (name, r) in sorted(changes.items()):
        print(f"{fam} {k} ({name}): now {r['got']} correct={r['correct']} wrong={r['wrong']} missed={r['missed']}")
    files = fold(changes, a.dry_run)
    for old, new in update_tables(files, a.label, a.dry_run):
        print(f"- {old}\n+ {new}")
    print(f"{len(changes)} rows differ, in {len(files)} block JSONs" + (" (dry run)" if a.dry_run else ""))


if __name__ == "__main__":
    main()
