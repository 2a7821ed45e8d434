"""``drake-est demo --fleet``: the whole fleet path on a small synthetic fleet (about a minute)."""
from __future__ import annotations

import json
import time
from pathlib import Path


def run_fleet_demo(out_dir, robots: int = 6, days: int = 10, seed: int = 0, workers: int | None = None,
                   echo=print) -> dict:
    """Synthesize a small fleet, diagnose it on a local Dask cluster, write the report and compare
    the warnings with the planted truth.  Returns the truth check."""
    from drake_est.fleet import FleetStore, build_report, check_against_truth, fleet_trends, run_fleet, synth_fleet
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.time()
    s = synth_fleet(out / "fleet", robots=robots, days=days, seed=seed, truth_path=out / "truth.json")
    echo(f"synthesized {s['logs']} logs ({robots} robots x {days} days; {s['planted']} planted changes, "
         f"{s['corrupt']} corrupt logs) in {time.time() - t0:.0f} s")
    c = run_fleet(out / "fleet", out / "fleet.db", workers=workers)
    echo(f"diagnosed {c['ok']} logs, {c['failed']} failed (recorded with their reason), "
         f"{c['logs_per_s']:.2f} logs/s")
    with FleetStore(out / "fleet.db", write=False) as st:
        rep = build_report(st, out / "report")
        chk = check_against_truth(fleet_trends(st), json.loads((out / "truth.json").read_text()))
    for w in rep["warnings"]:
        echo(f"  {w['rank']}. {w['text']}")
    echo(f"planted (not told to the diagnosis): " + "; ".join(
        f"{c['robot']} {('joint ' + str(c['joint'])) if c['joint'] else ''} {c['cause']} from {c['date']}"
        for c in json.loads((out / "truth.json").read_text())["changes"]))
    echo(f"{chk['found']}/{chk['planted']} planted changes found with robot, joint, cause and date; "
         f"{chk['healthy_robot_warnings']} warnings on {chk['healthy_robots']} healthy robots; done in "
         f"{time.time() - t0:.0f} s; report {out / 'report' / 'index.html'}")
    chk.pop("details", None)
    return chk
