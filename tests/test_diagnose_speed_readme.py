"""The README's diagnosis-speed table is printed from the kept JSON (benchmarks/results/diagnose_speed.json)."""
from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_readme_speed_table_matches_the_kept_json():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from bench_diagnose_speed import readme_table
    out = json.loads((ROOT / "benchmarks/results/diagnose_speed.json").read_text())
    text = (ROOT / "docs/readme/diagnose.md").read_text()
    for line in readme_table(out):
        assert line in text, line
    # the acceptance of issue 16, on the kept numbers
    assert out["generic_total_wall_s"] < 60 and out["generic_max_cpu_s"] < 10 and out["irb140_wall_s"] < 10
    assert out["n_loop_logs"] == 10 and out["loop_total_wall_s"] < 60 and out["loop_max_cpu_s"] < 10
    # every log got the names of its planted effects
    for r in out["rows"]:
        planted = r["log"].split(" seed ")[0].split(" ", 1)[1]
        want = set() if planted == "none" else set(planted.replace("synth irb140 ", "").split("+"))
        if r["log"].startswith("synth"):
            want = {"motor_position_ripple"}
        assert set(r["findings"]) == want, r
