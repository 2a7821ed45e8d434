"""The ninety-seventh round's probe: the ninety-sixth round's rule (held-out rows beyond the training positions are
not used to judge a model) with a guard: a law of a joint's position on a joint where such rows were dropped must not
hold its held-out gain in a few of the paired groups.

The ninety-sixth round's rule mended fresh spec 37492 but gave 5586 (an elastic gear at 1000 Hz) a wrong name once
every kept row was screened: the dropped rows were where the spurious load extrapolated badly.  The guard
(``core.BEYOND_POSITIONS_CONCENTRATED_GAIN_RULE``, where it acts:
``core.position_law_gain_concentrated_beside_dropped_rows``; rule file
``benchmarks/results/diagnose_beyond_positions_concentrated_gain_round97_rule.txt``) can only act where the
ninety-sixth round's rule drops rows: the logs its screens listed (``--keys listed``: every log its lanes a-j
examined).  This probe diagnoses them with both switches on; where the guard fires the log is diagnosed again with
the guard off (the ninety-sixth round's rule alone).  A log where it never fires gets the ninety-sixth round's rule-on
row of its lane (its ``rows``).  ``--against-kept A.json ...`` judges the round against the kept rows (both rules
off: the ninety-sixth round's lanes' ``rows_off``).

    python benchmarks/probe_beyond_positions_concentrated_gain.py --keys listed > kl.txt     # then alternate keys into ka.txt, kb.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_beyond_positions_concentrated_gain.py OUT_a.json $(cat ka.txt)
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_beyond_positions_concentrated_gain.py OUT_b.json $(cat kb.txt)
    python benchmarks/probe_beyond_positions_concentrated_gain.py --against-off-rows OUT_a.json OUT_b.json
    python benchmarks/probe_beyond_positions_concentrated_gain.py --against-kept OUT_a.json OUT_b.json
"""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from probe_held_back_rival import against_off, against_off_cli, against_off_of, against_off_row  # noqa: E402,F401
from probe_position_friction_halves import row_class  # noqa: E402
from probe_runner import keys_args, probe_main, run_rule_probe  # noqa: E402

RULE = "BEYOND_POSITIONS_CONCENTRATED_GAIN_RULE"
FUNC = "position_law_gain_concentrated_beside_dropped_rows"
RESULTS = Path(__file__).resolve().parent / "results"
ROUND96_LANES = "diagnose_beyond_training_positions_round96_lane_*.json"


def round96_lanes(results_dir=None) -> list:
    """[(name, JSON)] of the ninety-sixth round's lanes, in name order."""
    root = Path(results_dir) if results_dir else RESULTS
    return [(f.name, json.loads(f.read_text())) for f in sorted(root.glob(ROUND96_LANES))]


def listed_keys(family: str = "loop", results_dir=None) -> list:
    """Every key of ``family`` that the ninety-sixth round's lanes examined (its screens listed them, or they are its
    design logs), sorted."""
    return sorted({k for _, d in round96_lanes(results_dir) if d["family"] == family for k in d["keys_examined"]})


def keys_cli(argv) -> None:
    """``--keys listed [--family=F]``: print :func:`listed_keys`."""
    family, rest = keys_args(argv)
    if rest != ["listed"]:
        raise SystemExit("--keys: expected 'listed'")
    print(" ".join(str(k) for k in listed_keys(family)))


def _record(got, a, kw):
    """The record of one firing: the law, its joint and where its gain lies (None: the guard did not fire)."""
    from drake_est.diagnose import core
    if got is None or not getattr(core, RULE):
        return None
    ext = a[3]
    return {"effect": ext.effect, "joint": int(ext.joint), "groups": got["groups"],
            "groups_holding_gain": got["groups_holding_gain"], "share_of_gain": got["share_of_gain"]}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose ``keys`` with the ninety-sixth round's rule and the guard on; where the guard fired, store the rows
    and those of the same logs with the guard off (the ninety-sixth round's rule still on)."""
    from drake_est.diagnose import nominal
    was = nominal.BEYOND_TRAINING_POSITIONS_RULE
    nominal.BEYOND_TRAINING_POSITIONS_RULE = True
    try:
        return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="vetoed",
                              row_class=row_class, compare_off=True, module="core")
    finally:
        nominal.BEYOND_TRAINING_POSITIONS_RULE = was


def against_kept(paths, results_dir=None) -> dict:
    """The round judged against the kept rows (both rules off) over every log the probes ``paths`` examined: a log
    where the guard fired gets its probe row, any other its ninety-sixth round's rule-on lane row; its rule-off lane
    row stands for both rules off.  The same keys as :func:`probe_held_back_rival.against_off_of`, computed on those
    pairs (``fired``: every log examined)."""
    on, off = {}, {}
    for _, d in round96_lanes(results_dir):
        for r in d["rows"]:
            on[r["k"]] = r
        for r in d["rows_off"]:
            off[r["k"]] = r
    examined, fired_rows = [], {}
    for p in paths:
        d = json.load(open(p))
        examined += d["keys_examined"]
        for r in d["rows"]:
            fired_rows[r["k"]] = r
    missing = [k for k in examined if k not in on or k not in off]
    if missing:
        raise SystemExit(f"no ninety-sixth round lane row for k = {missing[0]} ({len(missing)} such)")
    rows = [{**(fired_rows.get(k) or on[k]), "kept_row": off[k]} for k in examined]
    out = against_off_of([{"examined": len(examined), "rows": rows, "rows_off": [off[k] for k in examined]}])
    out["guard_fired"] = sorted(fired_rows)
    return out


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "--against-kept":
        if len(argv) < 2:
            raise SystemExit("--against-kept: give the probe's JSON files")
        s = against_kept(argv[1:])
        print(against_off_row("against the kept rows", s))
        print(json.dumps({k: s[k] for k in ("wrong_gained", "wrong_lost", "missed_off", "missed_on",
                                            "null_findings_gained", "oov_unexplained_lost", "outright_lost",
                                            "verdict_changed", "guard_fired")}, indent=1))
        return
    if not against_off_cli(argv):
        probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
