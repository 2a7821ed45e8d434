"""benchmarks/fresh_block_docs.py: the docs' lines of a fresh closed-loop block from its JSON."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import fresh_block_docs as F  # noqa: E402

RESULTS = ROOT / "benchmarks" / "results"
DOCS = (ROOT / "docs" / "readme" / "diagnose_testbench.md").read_text()


@pytest.mark.parametrize("block", [41200, 41300])
def test_table_rows_are_the_docs_rows(block):
    """The three table rows written for the blocks 41200-41399 by hand are the ones the tool writes."""
    name = f"diagnose_testbench_loop_heldout{block}.json"
    d = json.load(open(RESULTS / name))
    for line in F.table_rows(d, name, "1794349"):
        assert line in DOCS, line


def test_paragraph_counts_and_cases():
    name = "diagnose_testbench_loop_heldout41200.json"
    d = json.load(open(RESULTS / name))
    text = F.paragraph(d, name, "1794349")
    assert text.startswith("**Fresh specs 41200-41299**, run once with 1794349")
    assert "89 / 100 correct, **0 wrong names**, 2 missed" in text
    # the two misses and every out-of-vocabulary log that ends as "none" are listed by spec number
    for k in (41237, 41294, 41204, 41226, 41248, 41270, 41292, 41225, 41247, 41249, 41293):
        assert str(k) in text
    assert "41237, a position friction beside a time-periodic disturbance at 1000 Hz with Student-t noise" in text
    assert "the position friction missed" in text
    assert "15 / 15 null logs clean." in text


def test_wrong_name_and_dirty_null_log_are_listed():
    """A wrong name and a null log that is not clean are written into the paragraph (a made-up block)."""
    base = {"k": 1, "family": "loop", "robot": "generic", "sample_rate": 250.0, "duration": 300.0,
            "noise": "quantized", "noise_std": 0.05, "samples": 75000, "wrong": [], "missed": [],
            "oov_unexplained": True, "correct": True, "unexplained": [], "seconds": 1.0}
    rows = [dict(base, k=5, truth="asymmetric_coulomb+stribeck", got="abrupt_change+stribeck",
                 wrong=["abrupt_change"], correct=False),
            dict(base, k=6, truth="none", got="unexplained", unexplained=["acceleration"], noise="gaussian",
                 duration=120.0)]
    d = dict(B_counts(rows), rows=rows)
    text = F.paragraph(d, "x.json", "abc1234")
    assert "**1 wrong name**" in text
    assert "**5**, an asymmetric level beside Stribeck at 250 Hz with a quantized torque over 300 s" in text
    assert "0 / 1 null logs clean (6 at 250 Hz: `unexplained` (acceleration))" in text


def B_counts(rows):
    import bench_diagnose_testbench as B
    return B._counts(rows)


def test_bad_json_exits_2(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    got = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "fresh_block_docs.py"), "--sha", "x", str(bad)],
                         capture_output=True, text=True)
    assert got.returncode == 2
    assert "not a testbench JSON" in got.stderr and "Traceback" not in got.stderr


def test_refused_logs_are_counted_and_named():
    """A block with a refused spec says how many, which and why, and counts the logs that ran (41800-41899: 41886 had
    too few samples in a half; the correct count is the JSON's, which the hundred-and-third round's fold of 41808
    raised from 94 to 95)."""
    name = "diagnose_testbench_loop_heldout41800.json"
    d = json.load(open(RESULTS / name))
    text = F.paragraph(d, name, "b50e034")
    assert text.startswith("**Fresh specs 41800-41899**")
    correct = sum(r["correct"] for r in d["rows"])
    assert correct == 95
    assert f"1 refused (41886: too few samples in the training or validation half), so 99 logs; {correct} / 99 correct" in text
    assert F.table_rows(d, name, "b50e034")[0].startswith("| 41800-41899, b50e034, run once")


def test_every_table_line_of_the_docs_stands_on_its_own_line():
    """A table row or header spliced into a sentence (as a scripted edit once put round 103's table inside its "Rule"
    paragraph) does not render as a table: every line of the docs' sources that holds a table cell of a JSON or the
    header starts with '|'."""
    bad = []
    for path in sorted((ROOT / "docs" / "readme").glob("*.md")):
        for n, line in enumerate(path.read_text().splitlines(), 1):
            if ("| `diagnose_" in line or "| JSON |" in line) and not line.startswith("|"):
                bad.append(f"{path.name}:{n}")
    assert bad == []
