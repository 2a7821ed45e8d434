"""``drake-est check LOG``: load a log with all checks and summarize it (what a user runs first)."""
from __future__ import annotations

import numpy as np


def register(sub):
    p = sub.add_parser("check", help="validate a log file and print a summary")
    p.add_argument("log", help="CSV or NPZ log (t, q1..qN, tau1..tauN, ...)")
    p.add_argument("--robot", default=None,
                   help="irb140 or a URDF path: refuse positions far outside its joint limits (degrees?); "
                        "generic (default): warn when positions look like degrees")
    p.add_argument("--drop-invalid", action="store_true", help="drop rows with NaN/inf (counted) instead of failing")
    p.set_defaults(func=run)


def run(args) -> int:
    from drake_est.cli._common import load_log_checked

    log = load_log_checked(args.log, args.robot, "check", nan_policy="drop" if args.drop_invalid else "raise")
    print(f"{args.log}: {log.n_samples} samples, {log.duration:.2f} s at {log.sample_rate:.1f} Hz, joints {log.joints}")
    for i, j in enumerate(log.joints):
        q = log.q[:, i]
        line = f"  joint {j}: q in [{q.min():.3f}, {q.max():.3f}], |dq| max {np.abs(log.dq[:, i]).max():.3f}"
        if log.tau is not None:
            line += f", tau in [{log.tau[:, i].min():.3f}, {log.tau[:, i].max():.3f}]"
        print(line)
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
