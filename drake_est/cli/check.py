"""``drake-est check LOG``: load a log with all checks and summarize it (what a user runs first)."""
from __future__ import annotations

import numpy as np


def register(sub):
    p = sub.add_parser("check", help="validate a log file and print a summary")
    p.add_argument("log", help="CSV or NPZ log (t, q1..qN, tau1..tauN, ...)")
    p.add_argument("--robot", default=None, help="irb140 to check positions against its joint limits")
    p.add_argument("--drop-invalid", action="store_true", help="drop rows with NaN/inf (counted) instead of failing")
    p.set_defaults(func=run)


def run(args) -> int:
    from drake_est.data import load_log

    from drake_est.errors import DataError

    limits = None
    if args.robot is not None and args.robot != "irb140":
        raise DataError(f"--robot must be 'irb140' (the only robot with known joint limits), got '{args.robot}'")
    if args.robot == "irb140":
        from drake_est.robots import irb140_metadata

        limits = irb140_metadata().limits_dict()
    log = load_log(args.log, limits=limits, nan_policy="drop" if args.drop_invalid else "raise")
    print(f"{args.log}: {log.n_samples} samples, {log.duration:.2f} s at {log.sample_rate:.1f} Hz, joints {log.joints}")
    for i, j in enumerate(log.joints):
        q = log.q[:, i]
        line = f"  joint {j}: q in [{q.min():.3f}, {q.max():.3f}], |dq| max {np.abs(log.dq[:, i]).max():.3f}"
        if log.tau is not None:
            line += f", tau in [{log.tau[:, i].min():.3f}, {log.tau[:, i].max():.3f}]"
        print(line)
        if args.robot is None and log.meta.get("axis_type") != "prismatic" and 2 * np.pi < np.abs(q).max() <= 400 \
                and np.ptp(q) > 2 * np.pi:
            print(f"  note: joint {j} spans {np.ptp(q):.1f} over more than one revolution in rad; if its positions "
                  f"are in degrees, convert them to radians (the format wants rad)")
    dt = float(np.median(np.diff(log.t)))
    if dt >= 0.5:
        print(f"  note: the median sample interval is {dt:.3g} s; if the time column is in milliseconds, "
              f"divide it by 1000 (the format wants seconds)")
    if log.channels:
        print(f"  other channels: {', '.join(log.channels)}")
    excl = log.meta.get("excluded_rows")
    if excl:
        print(f"  excluded rows: {excl}")
    info = log.meta.get("derivatives")
    if info:
        print(f"  derivatives: {info['method']} window {info['window_samples']} samples ({info['window_s']:.3f} s)"
              + (", resampled to a uniform grid" if info["resampled"] else ""))
    return 0
