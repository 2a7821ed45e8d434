"""``drake-est synth-fleet --robots N --days D --out DIR``: a synthetic fleet with planted changes."""
from __future__ import annotations


def register(sub):
    p = sub.add_parser("synth-fleet", help="write a synthetic fleet of daily logs with planted slow changes "
                                           "(truth kept apart in DIR.truth.json)")
    p.add_argument("--robots", type=int, default=50, help="number of robots (default 50)")
    p.add_argument("--days", type=int, default=30, help="days, one log per robot and day (default 30)")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--duration", type=float, default=20.0, help="seconds per log (default 20)")
    p.add_argument("--irb140", type=int, default=None, help="IRB 140 robots (default robots // 25, at least 1)")
    p.add_argument("--truth", default=None, help="truth JSON (default DIR.truth.json beside the folder)")
    p.set_defaults(func=run)


def run(args) -> int:
    from drake_est.errors import DataError
    from drake_est.fleet.synth_fleet import synth_fleet
    from drake_est.cli._common import check_number

    check_number("--duration", args.duration, 5, 3600, unit="s")
    if args.duration < 5:
        raise DataError(f"--duration must be at least 5 s, got {args.duration}")
    check_number("--robots", args.robots, 3, 10_000, integer=True)
    check_number("--days", args.days, 8, 3650, integer=True)
    check_number("--seed", args.seed, 0, 2**32 - 1, integer=True)
    check_number("--irb140", args.irb140, 0, args.robots, integer=True)
    s = synth_fleet(args.out, robots=args.robots, days=args.days, seed=args.seed, duration=args.duration,
                    truth_path=args.truth, n_irb140=args.irb140)
    print(f"synth-fleet: {s['logs']} logs of {s['robots']} robots x {s['days']} days in {s['out']} "
          f"(manifest {s['manifest']}); {s['planted']} planted changes and {s['corrupt']} corrupt logs, "
          f"truth in {s['truth']}")
    return 0
