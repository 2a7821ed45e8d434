"""``drake-est fit-friction LOG --model ... --joint J --out DIR``: identify a friction model
(thesis Ch. 9), print validation metrics, write ``params.json`` and PNG plots."""
from __future__ import annotations

import json
from pathlib import Path

from drake_est.errors import DrakeEstError
from drake_est.jsonutil import to_jsonable

MODEL_CHOICES = ("nominal", "position", "motor", "position+motor", "energy", "position+energy", "coupled")


def register(sub):
    p = sub.add_parser("fit-friction", help="identify a joint friction model from a log (thesis Ch. 9)",
                       description="Fit a friction model to one joint of a log, validate it on the held-out end "
                                   "of the log, and write params.json + PNG plots.")
    p.add_argument("log", help="log file (.csv or .npz, drake_est format: t, q<j>, tau<j>, ...)")
    p.add_argument("--model", default="nominal", choices=MODEL_CHOICES, help="model structure (default nominal)")
    p.add_argument("--joint", type=int, default=None, help="1-based joint number (default: the joint that moves most)")
    p.add_argument("--out", default="friction-fit", help="output folder (default ./friction-fit)")
    p.add_argument("--nominal", default="asymmetric", choices=("coulomb", "viscous", "asymmetric"),
                   help="nominal model: (9.1), (9.2) or direction-dependent (9.3) (default)")
    p.add_argument("--robot", default="auto", choices=("auto", "irb140", "none", "generic"),
                   help="subtract the rigid-body torque ID(q, dq, ddq) of this robot and take gear ratio/coupling "
                        "from its metadata (auto: irb140 when the log has its 6 joints; none = generic: no robot "
                        "model, a warning when positions look like degrees)")
    p.add_argument("--gear-ratio", type=float, default=None, help="motor/arm gear ratio for --model motor")
    p.add_argument("--holdout", type=float, default=0.3, help="fraction at the end held out for validation (0.3)")
    p.add_argument("--v-min", type=float, default=None, help="drop |v| <= this [rad/s] (default 5%% of max |v|)")
    p.add_argument("--a-max", type=float, default=None,
                   help="drop |a| >= this [rad/s^2] (default 5x median |a|; not applied to excitation logs, "
                        "where fewer than half the moving samples are steady and the full ID is subtracted)")
    p.add_argument("--n-position", type=int, default=None, help="number of position basis functions (default: CV)")
    p.add_argument("--width-factor", type=float, default=None, help="basis width / centre spacing (default: CV)")
    p.add_argument("--energy-iters", type=int, default=50, help="Algorithm 6 iterations (default 50)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument("--drop-invalid", action="store_true", help="drop rows with NaN/inf (counted) instead of failing")
    p.set_defaults(func=run)


# the workflow lives in the library (drake_est.cases.friction_fit); names kept here for old imports
from drake_est.cases.friction_fit import _robot, fit_log, format_table, plot_result  # noqa: E402,F401


def run(args) -> int:
    from drake_est.data import load_log

    from drake_est.cli._common import check_number

    # a validation part of at least 5 % (and a training part of at least half) of the log
    check_number("--holdout", args.holdout, 0.05, 0.5)
    for name, val in (("--gear-ratio", args.gear_ratio), ("--v-min", args.v_min), ("--a-max", args.a_max),
                      ("--width-factor", args.width_factor)):
        check_number(name, val, 0, 1e6)
    for name, val, lo, strict in (("--gear-ratio", args.gear_ratio, 0, True), ("--v-min", args.v_min, 0, False),
                                  ("--a-max", args.a_max, 0, True), ("--n-position", args.n_position, 1, False),
                                  ("--width-factor", args.width_factor, 0, True),
                                  ("--energy-iters", args.energy_iters, 1, False)):
        if val is not None and not (val > lo if strict else val >= lo):
            raise DrakeEstError(f"{name} must be {'>' if strict else '>='} {lo}, got {val}")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise DrakeEstError(f"--out {args.out} exists and is not a folder")
    nan_policy = "drop" if args.drop_invalid else "raise"
    from drake_est.cli._common import load_log_checked, warn
    from drake_est.data import degrees_warnings

    if args.robot == "generic":
        args.robot = "none"
    log = load_log(args.log, nan_policy=nan_policy)
    if args.robot == "irb140" or (args.robot == "auto" and log.joints == [1, 2, 3, 4, 5, 6]):
        log = load_log_checked(args.log, "irb140", "fit-friction", nan_policy=nan_policy)  # refuse degrees before ID
    else:
        for w in degrees_warnings(log):
            warn("fit-friction", f"{args.log}: {w}")
    res, info = fit_log(log, model=args.model, joint=args.joint, robot=args.robot, nominal=args.nominal,
                        gear_ratio=args.gear_ratio, holdout=args.holdout, v_min=args.v_min, a_max=args.a_max,
                        n_position=args.n_position, width_factor=args.width_factor,
                        energy_iters=args.energy_iters)
    import numpy as np

    tau_j = log.tau[:, log.joints.index(info["joint"])] if info.get("joint") in log.joints else None
    if tau_j is not None and not np.ptp(tau_j) > 0:
        raise DrakeEstError(f"column tau{info['joint']} is constant ({tau_j[0]:g} N m): no torque was logged for "
                            f"joint {info['joint']}, there is no friction to fit")
    out.mkdir(parents=True, exist_ok=True)
    print(f"joint {info['joint']}: model '{args.model}' ({res.model.n_params} linear parameters"
          f"{', rigid-body torque subtracted (' + info['robot'] + ')' if info['rigid_body_subtracted'] else ''})")
    print(res.selection.summary())
    print(format_table({"training": res.train, "validation": res.validation}))
    params = res.model.params()
    print("parameters: " + ", ".join(f"{k}={v:.4g}" for k, v in params.items()))
    doc = res.to_dict()
    doc["log"] = str(args.log)
    doc["info"] = info
    doc["structure"].pop("energy_history", None)
    from drake_est.jsonutil import dump_json, finite_or_none

    sel = doc.get("selection")
    if isinstance(sel, dict) and "a_max" in sel:
        sel["a_max"] = finite_or_none(sel["a_max"])   # no acceleration limit: null, not Infinity
    from drake_est.jsonutil import nonfinite_to_null

    doc, undefined = nonfinite_to_null(doc)      # e.g. a Fit of a constant validation part: null, listed
    if undefined:
        doc["undefined_numbers"] = undefined
    dump_json(doc, out / "params.json")
    if not args.no_plots:
        plot_result(res, out, title=f"joint {info['joint']}, model {args.model}")
    print(f"wrote {out / 'params.json'}" + ("" if args.no_plots else " and PNG plots"))
    return 0

