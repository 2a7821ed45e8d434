"""``drake-est fleet diagnose DIR|MANIFEST --store FILE [--scheduler ADDRESS] [--workers N]`` and
``drake-est fleet report --store FILE --out DIR [--truth FILE]``.

Diagnose a fleet's logs in parallel on Dask (a local cluster of processes by default, or an existing
scheduler started with ``dask scheduler`` / ``dask worker``) into an SQLite store, resumably; then
write the static HTML + JSON report with the trends and ranked warnings."""
from __future__ import annotations

import json


def register(sub):
    p = sub.add_parser("fleet", help="diagnose a fleet's logs on Dask into an SQLite store; trend report")
    fs = p.add_subparsers(dest="fleet_command", metavar="{diagnose,report}")
    d = fs.add_parser("diagnose", help="diagnose every log not yet in the store (resumable, idempotent)")
    d.add_argument("source", help="folder (DIR/<robot_id>/<date>.npz|.csv) or manifest CSV "
                                  "(robot_id, time, path[, joints, robot_model])")
    d.add_argument("--store", required=True, help="SQLite store file (created when missing)")
    d.add_argument("--scheduler", default=None, help="address of a running Dask scheduler (tcp://host:8786)")
    d.add_argument("--workers", type=int, default=None, help="local worker processes (default: the local cores)")
    d.add_argument("--seed", type=int, default=0, help="diagnosis seed (part of the settings, default 0)")
    d.add_argument("--limit", type=int, default=None, help="diagnose at most this many new logs")
    d.set_defaults(func=run_diagnose)
    r = fs.add_parser("report", help="static HTML + JSON report with trends and ranked warnings")
    r.add_argument("--store", required=True, help="SQLite store written by 'fleet diagnose'")
    r.add_argument("--out", required=True, help="output folder (index.html, report.json)")
    r.add_argument("--truth", default=None, help="truth JSON of a synthetic fleet: print the acceptance check")
    r.set_defaults(func=run_report)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])


def run_diagnose(args) -> int:
    from drake_est.errors import DataError
    from drake_est.fleet.run import run_fleet
    if args.workers is not None and args.workers < 1:
        raise DataError(f"--workers must be at least 1, got {args.workers}")
    from drake_est.cli._common import check_number

    check_number("--workers", args.workers, 1, 1024, integer=True)
    check_number("--limit", args.limit, 1, None, integer=True)
    check_number("--seed", args.seed, 0, 2**32 - 1, integer=True)
    c = run_fleet(args.source, args.store, scheduler=args.scheduler, workers=args.workers,
                  settings={"seed": args.seed}, limit=args.limit)
    print(f"fleet diagnose: {c['logs']} logs, {c['skipped']} already in the store (skipped), {c['ok']} diagnosed, "
          f"{c['failed']} failed (reasons in the store), {c['unfinished']} unfinished; "
          f"{c['logs_per_s']:.2f} logs/s; store {args.store}")
    for r in c["unfinished_reasons"]:
        print(f"  unfinished: {r}")
    return 0 if c["unfinished"] == 0 else 1


def run_report(args) -> int:
    from pathlib import Path
    from drake_est.errors import DataError
    from drake_est.fleet import FleetStore, build_report, check_against_truth, fleet_trends
    with FleetStore(args.store, write=False) as st:
        rep = build_report(st, args.out)
        print(f"fleet report: {rep['counts']['robots']} robots, {rep['counts']['logs']} logs, "
              f"{len(rep['warnings'])} warnings")
        for w in rep["warnings"][:20]:
            print(f"  {w['rank']:>3}. {w['text']}")
        if args.truth:
            tp = Path(args.truth)
            if not tp.exists():
                raise DataError(f"--truth {tp} not found")
            try:
                truth = json.loads(tp.read_text())
            except (json.JSONDecodeError, UnicodeDecodeError) as err:
                raise DataError(f"--truth {tp} is not valid JSON ({err})") from None
            if not isinstance(truth, dict):
                raise DataError(f"--truth {tp} must hold a JSON object (the truth file of synth-fleet)")
            try:
                chk = check_against_truth(fleet_trends(st), truth)
            except (KeyError, TypeError, ValueError, AttributeError) as err:
                raise DataError(f"--truth {tp} is not a truth file of synth-fleet ({type(err).__name__}: "
                                f"{str(err)[:120]})") from None
            print(f"truth: {chk['found']}/{chk['planted']} planted changes found in the top warnings with robot, "
                  f"joint, cause and date; {chk['healthy_robot_warnings']} warnings on {chk['healthy_robots']} "
                  f"healthy robots; {chk['extra_warnings_on_planted_robots']} other warnings")
            from drake_est.jsonutil import dump_json
            dump_json(chk, Path(args.out) / "truth_check.json")
    print(f"report: {Path(args.out) / 'index.html'} (numbers in report.json)")
    return 0
