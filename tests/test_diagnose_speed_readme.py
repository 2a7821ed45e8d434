"""The README's diagnosis-speed table is printed from the kept JSON (benchmarks/results/diagnose_speed.json)."""
from __future__ import annotations

import json
from pathlib import Path

from conftest import bench_module

ROOT = Path(__file__).resolve().parents[1]


def test_readme_speed_table_matches_the_kept_json():
    readme_table = bench_module("bench_diagnose_speed").readme_table
    out = json.loads((ROOT / "benchmarks/results/diagnose_speed.json").read_text())
    text = (ROOT / "docs/readme/diagnose.md").read_text()
    for line in readme_table(out):
        assert line in text, line
    # the acceptance of issue 16, on the kept numbers: one log < 10 s (the open-loop testbench and IRB 140 logs),
    # ten logs < 60 s on 2 cores (two worker processes at once); the slowest closed-loop log with two effects took
    # more than 10 s on the nineteenth round's (slower) machine: that goal is not asserted, but the docs must say
    # it is not met whenever the kept JSON misses it
    assert out["generic_total_wall_s"] < 60 and out["generic_max_cpu_s"] < 10 and out["irb140_wall_s"] < 10
    assert out["n_loop_logs"] == 10 and out["pool_workers"] == 2
    assert out["generic_pool_wall_s"] < 60
    # ten closed-loop logs on two workers: met on the earlier sessions' machines, 60.1 s on the fifty-sixth's; the docs
    # must say so whenever the kept JSON misses it
    flat = " ".join(text.split()).lower()
    said10 = "ten closed-loop logs on two worker processes do not meet the 60 s goal" in flat
    assert (out["loop_pool_wall_s"] < 60) == (not said10)
    said = "a single closed-loop log with two effects does not meet the 10 s goal" in flat
    # "one log on 2 cores": the slowest closed-loop log's wall time on the threads of one diagnosis when the JSON has
    # that run (its reports equal the one-thread ones, checked by the benchmark), else its one-thread CPU time
    slowest = out.get("loop_max_wall_threads_s", out["loop_max_cpu_s"])
    assert (slowest < 10) == (not said)
    # the same code's time depends on the machine (1.6-1.8x between two sessions' 2-core machines): the JSON names it
    assert out.get("cpu_model"), "the kept speed JSON names no processor"
    assert out["cpu_model"] in text, "the speed section does not name the kept run's processor"
    if "threads" in out:
        assert out["threads"] == 2 and out.get("reports_identical_across_threads") is True
        assert all("wall_threads_s" in r for r in out["rows"])
    # every log got the names of its planted effects
    for r in out["rows"]:
        planted = r["log"].split(" seed ")[0].split(" ", 1)[1]
        want = set() if planted == "none" else set(planted.replace("synth irb140 ", "").split("+"))
        if r["log"].startswith("synth"):
            want = {"motor_position_ripple"}
        assert set(r["findings"]) == want, r


def test_results_row_speed_numbers_are_the_kept_json():
    """The "Results at a glance" speed row quotes the kept JSON's figures."""
    out = json.loads((ROOT / "benchmarks/results/diagnose_speed.json").read_text())
    row = next(x for x in (ROOT / "docs/readme/_results.md").read_text().splitlines()
               if x.startswith("| diagnosis alone (no re-simulation)"))
    for key in ("generic_total_cpu_s", "generic_max_cpu_s", "generic_pool_wall_s", "loop_total_cpu_s",
                "loop_max_cpu_s", "loop_pool_wall_s") + (("loop_max_wall_threads_s",) if "threads" in out else ()):
        assert f"{out[key]:.1f} s" in row, key


def test_the_speed_prose_quotes_the_kept_json():
    """The speed section's "Met on ..." paragraph and the roadmap's speed line quote the kept JSON's figures."""
    out = json.loads((ROOT / "benchmarks/results/diagnose_speed.json").read_text())
    slow, one, pool = (f"{out[k]:.1f} s" for k in ("loop_max_wall_threads_s", "loop_max_cpu_s", "loop_pool_wall_s"))
    text = " ".join((ROOT / "docs/readme/diagnose.md").read_text().split())
    assert (f"takes {slow} on two threads and {one} CPU on one; the ten closed-loop logs take {pool} on two worker "
            f"processes, the ten open-loop testbench logs {out['generic_pool_wall_s']:.1f} s") in text
    road = " ".join((ROOT / "docs/readme/_roadmap.md").read_text().split())
    assert (f"log {slow} on two threads, {one} on one; the ten on two worker processes {pool})") in road
    assert out["cpu_model"] in road
