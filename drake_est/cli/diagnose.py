"""``drake-est diagnose LOG [LOG2 ...] [--robot irb140|generic|PATH.urdf] [--joints 1,2] [--out DIR] [--seed N]
[--threads N]``

Model-discrepancy diagnosis of a measured log: the nominal model's held-out residual, the
effects found (each with its statistical evidence and held-out gain), the extended model, and
a report (``DIR/report.json``, ``DIR/report.md`` and PNG plots)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from drake_est.errors import DataError


def register(sub):
    p = sub.add_parser("diagnose", help="find what the nominal model gets wrong in a log, name the cause, "
                                        "extend the model and measure the held-out gain")
    p.add_argument("log", nargs="+", help="log file(s) (.csv or .npz, drake_est format: t, q<j>, tau<j>); several "
                                          "logs of one machine are diagnosed together, whole logs held out")
    p.add_argument("--robot", default="generic",
                   help="irb140, generic (default: each joint an independent axis) or a URDF path")
    p.add_argument("--joints", default=None, help="comma-separated 1-based joints to diagnose (default: all)")
    p.add_argument("--out", default=None, help="output folder (default: a new ./diagnosis-N folder)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--threads", default=None,
                   help="threads for the candidates of each round (default: DRAKE_EST_DIAG_THREADS, else up to 4, at "
                        "most the cores); the findings do not depend on it")
    p.add_argument("--no-simulation", action="store_true", help="skip the windowed forward simulations")
    p.add_argument("--drop-invalid", action="store_true", help="drop rows with NaN/inf (counted) instead of failing")
    p.set_defaults(func=run)


def _joints(text):
    if text is None:
        return None
    try:
        js = [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise DataError(f"--joints must be comma-separated joint numbers like 1,2 (got '{text}')") from None
    if not js or any(j < 1 for j in js):
        raise DataError(f"--joints must list 1-based joint numbers (got '{text}')")
    return js


def _new_dir(out):
    if out is not None:
        p = Path(out)
        if p.exists() and not p.is_dir():
            raise DataError(f"--out {out} exists and is not a folder")
        return p
    k = 1
    while Path(f"diagnosis-{k}").exists():
        k += 1
    return Path(f"diagnosis-{k}")


def run(args) -> int:
    from drake_est.diagnose import diagnose

    joints = _joints(args.joints)
    from drake_est.diagnose.parallel import check_threads
    threads = None if args.threads is None else check_threads(args.threads, "--threads")
    out = _new_dir(args.out)
    from drake_est.cli._common import load_log_checked

    paths = args.log if isinstance(args.log, list) else [args.log]
    seen = {}
    for p in paths:
        key = Path(p).resolve()
        if key in seen:
            raise DataError(f"log {p} is given twice (as {seen[key]}); each log may be diagnosed once, whole logs "
                            "are held out")
        seen[key] = p
    logs = [load_log_checked(p, args.robot, "diagnose", nan_policy="drop" if args.drop_invalid else "raise")
            for p in paths]
    for p, lg in zip(paths, logs):
        for c, j in enumerate(lg.joints):
            if (joints is None or j in joints) and lg.tau is not None and not np.ptp(lg.tau[:, c]) > 0:
                raise DataError(f"{p}: column tau{j} is constant ({lg.tau[0, c]:g}): no torque was logged for joint "
                                f"{j}; leave it out with --joints")
    if len(logs) == 1:
        log = logs[0]
    else:
        from drake_est.diagnose import concatenate_logs
        log = concatenate_logs(logs)
    rep = diagnose(log, robot=args.robot, joints=joints, seed=args.seed, simulate=not args.no_simulation,
                   source=" + ".join(str(p) for p in paths), threads=threads)
    rep.write(out)
    print(rep.summary())
    print(f"report: {out / 'report.md'} (numbers in {out / 'report.json'})")
    return 0
