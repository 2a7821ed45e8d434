"""The kept rounds' lanes and screens for a fresh closed-loop block: which keys each round's probe must see, and the
commands that run them.

Every kept round whose rule can only change some rows has a probe (``benchmarks/probe_*.py``) whose ``--keys`` mode
selects those rows from the kept JSONs.  When a fresh block is folded in (``bench_diagnose_testbench.py --family loop
--start N``), each round must see the block's rows it selects: a lane (the probe run on them, rule on) or a screen
(a cheap pass that lists the few rows worth a lane; its lane then runs on the listed keys).  This script reads each
probe's own ``--keys`` selection, keeps the keys in ``[--start, --end)``, names the next lane or screen of each round
(letters after the last JSON of that kind: ``y``, ``z``, ``za``, ..., ``zz``, ``zza``) and prints the commands, or runs
them (``--run``: two worker queues, screens first, then the lanes on what the screens listed).  The docs and the
tests that read the lanes follow each round's section in ``docs/readme/diagnose_testbench.md``:
``fresh_block_lane_docs.py`` writes the routine ones from the plan (``--json``) and the JSONs, and stops where a
reading must be written by hand.

    python benchmarks/fresh_block_lanes.py --start 41400 --end 41600             # the keys and commands
    python benchmarks/fresh_block_lanes.py --start 41400 --end 41600 --json k.json  # the keys per round, as JSON
    python benchmarks/fresh_block_lanes.py --start 41400 --end 41600 --run       # run them here (OPENBLAS 1 thread)
"""
from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import NamedTuple

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"


class Round(NamedTuple):
    """One kept round's probe: ``script`` (in ``benchmarks/``) and its ``--keys`` mode ``keys``; ``prefix`` of its
    JSONs in ``benchmarks/results``; ``screens``: how many screens a block gets (0: a lane on the keys themselves; 2:
    the keys split over two screens, ``--lane=0/2`` and ``--lane=1/2``); ``same_letter``: the lane after a screen takes
    the screen's letter (the ninety-first round); the lane after screens runs only where they list keys; ``args``:
    the probe's arguments before the output JSON (e.g. ``--rule=...``); ``lane_of``: another round's screens give this
    round's lane keys (the ninety-seventh round reads the ninety-sixth's); ``note``: printed beside the round."""
    number: int
    script: str
    keys: str
    prefix: str
    screens: int = 0
    same_letter: bool = False
    args: tuple = ()
    lane_of: int | None = None
    note: str = ""


#: the kept rounds with a probe for fresh blocks, newest first (the order the docs keep their sections in)
ROUNDS = (
    Round(108, "probe_change_beside_drift.py", "touchable", "diagnose_change_beside_drift_round108"),
    Round(106, "probe_motion_line_linear_response.py", "all", "diagnose_motion_line_linear_response_round106",
          screens=1, note="its screen takes the gate of every log of the block"),
    Round(105, "probe_time_law_beside_stribeck_both_ways.py", "touchable",
          "diagnose_time_law_beside_stribeck_both_ways_round105"),
    Round(104, "probe_time_law_rival_named.py", "touchable", "diagnose_time_law_rival_named_round104"),
    Round(103, "probe_time_law_beside_untestable_stribeck.py", "touchable",
          "diagnose_time_law_beside_untestable_stribeck_round103"),
    Round(102, "probe_time_law_beside_stribeck_filter_slope.py", "touchable",
          "diagnose_time_law_beside_stribeck_filter_slope_round102"),
    Round(101, "probe_rescue_filter_slope.py", "touchable", "diagnose_rescue_filter_slope_round101"),
    Round(100, "probe_change_refined_before_position_law.py", "touchable",
          "diagnose_change_refined_before_position_law_round100"),
    Round(99, "probe_ripple_split_locked.py", "touchable", "diagnose_ripple_split_locked_round99", screens=1),
    Round(98, "probe_speed_curve_adc_guarded.py", "touchable", "diagnose_speed_curve_adc_guarded_round98", screens=1),
    Round(97, "probe_beyond_positions_concentrated_gain.py", "", "diagnose_beyond_positions_concentrated_gain_round97",
          lane_of=96, note="the keys the ninety-sixth round's screens of the block list"),
    Round(96, "probe_beyond_training_positions.py", "all", "diagnose_beyond_training_positions_round96", screens=2,
          note="switched off: its lane runs on and off"),
    Round(95, "probe_ripple_before_position_law.py", "touchable", "diagnose_ripple_where_law_falls_round95",
          args=("--rule=where_law_falls",)),
    Round(93, "probe_load_untested_direction.py", "candidates", "diagnose_load_untested_direction_round93",
          screens=1),
    Round(92, "probe_set_aside_time_law.py", "touchable", "diagnose_set_aside_time_law_round92"),
    Round(91, "probe_state_check_speeds.py", "candidates", "diagnose_state_check_speeds_round91", screens=1,
          same_letter=True),
    Round(90, "probe_closed_rival.py", "touchable", "diagnose_closed_rival_round90"),
    Round(89, "probe_position_friction_dissipation.py", "touchable", "diagnose_position_friction_dissipation_round89"),
    Round(88, "probe_disturbance_stationary.py", "named", "diagnose_disturbance_stationary_round88"),
    Round(74, "probe_position_law_as_accepted.py", "touchable", "diagnose_position_law_as_accepted_round74"),
)


def letter_order(x: str) -> tuple:
    """Sort key of a lane or screen letter: ``a`` .. ``z``, then ``za`` .. ``zz``, then ``zza`` .. (by length, then
    alphabetically); digits and words (``0``, ``1``, ``testbench``) are not letters of fresh blocks."""
    return (len(x), x)


def next_letter(x: str | None) -> str:
    """The letter after ``x``: the last character moved on (``m`` -> ``n``), ``z`` extended (``z`` -> ``za``,
    ``zz`` -> ``zza``); ``a`` when there is none."""
    if not x:
        return "a"
    if x[-1] < "z":
        return x[:-1] + chr(ord(x[-1]) + 1)
    return x + "a"


def letters(prefix: str, kind: str, results=RESULTS) -> list:
    """The letters of ``benchmarks/results/<prefix>_<kind>_<letter>.json`` (``kind``: lane or screen), in order."""
    pat = re.compile(rf"^{re.escape(prefix)}_{kind}_(z*[a-z])\.json$")      # not ``testbench`` nor ``0``, ``1``
    return sorted((m.group(1) for f in results.glob(f"{prefix}_{kind}_*.json") if (m := pat.match(f.name))),
                  key=letter_order)


def probe_keys(rnd: Round, start: int, end: int, python=sys.executable) -> list:
    """The kept closed-loop keys in ``[start, end)`` that ``rnd``'s probe selects (its ``--keys`` command line)."""
    out = subprocess.run([python, str(HERE / rnd.script), "--keys", rnd.keys], capture_output=True, text=True,
                         check=True, cwd=HERE.parent).stdout
    return [k for k in (int(x) for x in out.split()) if start <= k < end]


def block_plan(start: int, end: int, results=RESULTS, python=sys.executable) -> list:
    """Per round of :data:`ROUNDS` (those whose keys come from another round after it): ``{"round", "script",
    "prefix", "note", "args", "keys", "screens": [(letter, lane share)], "lane": letter or None,
    "lane_after_screens": bool}`` (and ``"lane_of"``).  A round with no
    key in the block gets no lane or screen."""
    plan, by_number = [], {}
    for rnd in ROUNDS:
        if rnd.lane_of is not None:
            continue
        keys = probe_keys(rnd, start, end, python)
        item = {"round": rnd.number, "script": rnd.script, "prefix": rnd.prefix, "note": rnd.note,
                "args": list(rnd.args), "keys": keys, "screens": [], "lane": None, "lane_after_screens": False}
        if keys and rnd.screens:
            last = (letters(rnd.prefix, "screen", results) or [None])[-1]
            for i in range(rnd.screens):
                last = next_letter(last)
                item["screens"].append((last, f"{i}/{rnd.screens}" if rnd.screens > 1 else None))
            item["lane_after_screens"] = True
            item["lane"] = (item["screens"][-1][0] if rnd.same_letter
                            else next_letter((letters(rnd.prefix, "lane", results) or [None])[-1]))
        elif keys:
            item["lane"] = next_letter((letters(rnd.prefix, "lane", results) or [None])[-1])
        plan.append(item)
        by_number[rnd.number] = item
    for rnd in ROUNDS:
        if rnd.lane_of is None:
            continue
        src = by_number[rnd.lane_of]
        plan.append({"round": rnd.number, "script": rnd.script, "prefix": rnd.prefix, "note": rnd.note,
                     "args": list(rnd.args), "keys": [],
                     "screens": [], "lane": (next_letter((letters(rnd.prefix, "lane", results) or [None])[-1])
                                             if src["screens"] else None),
                     "lane_after_screens": bool(src["screens"]), "lane_of": rnd.lane_of})
    return plan


def commands(plan) -> tuple:
    """(screen and lane commands that need no screen, lane commands that read the screens): shell lines, run from the
    repository root."""
    first, second = [], []
    py = "OPENBLAS_NUM_THREADS=1 python benchmarks/"
    for it in plan:
        pre = it["prefix"]
        args = " ".join(it["args"])
        args = f" {args}" if args else ""
        keys = " ".join(str(k) for k in it["keys"])
        for letter, share in it["screens"]:
            lane = f" --lane={share}" if share else ""
            first.append(f"{py}{it['script']} --screen benchmarks/results/{pre}_screen_{letter}.json{lane} {keys}")
        if it["lane"] is None:
            continue
        out = f"benchmarks/results/{pre}_lane_{it['lane']}.json"
        if it["lane_after_screens"]:
            # the lane on the keys the screens list (its own, or another round's), run only where they list some
            src = next(x for x in plan if x["round"] == it.get("lane_of", it["round"]))
            spre = src["prefix"]
            scr = " ".join(f"benchmarks/results/{spre}_screen_{x}.json" for x, _ in src["screens"])
            listed = f"$(python benchmarks/{src['script']} --keys screened {scr})"
            second.append(f"K=\"{listed}\"; if [ -n \"$K\" ]; then {py}{it['script']}{args} {out} $K; fi")
        else:
            first.append(f"{py}{it['script']}{args} {out} {keys}")
    return first, second


def run(lines, workers: int = 2) -> list:
    """Run the shell ``lines`` from the repository root, one at a time on each of ``workers`` queues; the lines that
    failed, with their exit status.  ``python`` in a line is the interpreter running this script (its directory
    first on PATH: a virtual environment that is not activated)."""
    from concurrent.futures import ThreadPoolExecutor
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1",
           "PATH": os.pathsep.join([os.path.dirname(sys.executable), os.environ.get("PATH", "")])}

    def queue(q):
        bad = []
        for line in q:
            rc = subprocess.run(["bash", "-c", line], cwd=HERE.parent,
                                env=env).returncode
            if rc:
                bad.append((rc, line))
        return bad
    with ThreadPoolExecutor(workers) as ex:
        return [b for got in ex.map(queue, [lines[i::workers] for i in range(workers)]) for b in got]


#: a fresh block's size: bench_diagnose_testbench.py --start N --n-loop 100
BLOCK = 100


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--start", type=int, required=True, help="first spec of the fresh block(s)")
    ap.add_argument("--end", type=int, required=True, help="one past the last spec")
    ap.add_argument("--json", default=None, help="write the plan (keys, letters) here")
    ap.add_argument("--run", action="store_true", help="run the commands (two queues), screens before their lanes")
    a = ap.parse_args(argv)
    if a.end <= a.start:
        print(f"fresh_block_lanes: --end ({a.end}) must lie after --start ({a.start})", file=sys.stderr)
        return 2
    if a.start % BLOCK or a.end % BLOCK:
        # fresh blocks are runs of BLOCK specs; --end is one past the last spec (an --end of 44999 left spec 44999 out)
        print(f"fresh_block_lanes: --start ({a.start}) and --end ({a.end}, one past the last spec) must be multiples of "
              f"{BLOCK}, the fresh blocks' size (did you mean --end {-(-a.end // BLOCK) * BLOCK}?)", file=sys.stderr)
        return 2
    plan = block_plan(a.start, a.end)
    for it in plan:
        what = ", ".join([f"screen {x}" for x, _ in it["screens"]] + ([f"lane {it['lane']}"] if it["lane"] else []))
        n = f"{len(it['keys'])} keys" if it.get("lane_of") is None else f"the keys round {it['lane_of']} lists"
        note = f" ({it['note']})" if it["note"] else ""
        print(f"# round {it['round']:3d}: {n}: {what or 'nothing to run'}{note}")
    first, second = commands(plan)
    print("\n".join(first + second))
    if a.json:
        Path(a.json).write_text(json.dumps(plan, indent=1) + "\n")
    if a.run:
        bad = run(first) + run(second)
        for rc, line in bad:
            print(f"fresh_block_lanes: exit {rc}: {line}", file=sys.stderr)
        return 1 if bad else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
