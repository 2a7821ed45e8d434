"""``drake-est spectrum LOG --signal tau1 --position q1 --schedule dq1 --out DIR``

LPV spectral analysis (thesis Ch. 10) of one signal of a log as a function of a position
column, with amplitude and phase depending on a scheduling column (usually the velocity).
Writes ``spectrum.png`` (least-squares LPV periodogram, found components marked),
``amplitude.png`` (amplitude functions with confidence bands over the histogram of the schedule,
Figs. 10.5-10.6) and ``spectrum.json`` (dominant frequencies, amplitudes, explained variance).
Frequencies are reported per radian of the position, per revolution of it, and per motor
revolution when a gear ratio is known (``--gear-ratio``, or from the robot named in the log's
metadata); the detection itself never uses the gear ratio.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from drake_est.errors import DataError


def register(sub):
    p = sub.add_parser("spectrum", help="LPV spectral analysis of a signal vs position with velocity-dependent "
                                        "amplitude (thesis Ch. 10)")
    p.add_argument("log", help="log file (.csv or .npz, drake_est format)")
    p.add_argument("--signal", required=True, help="column to analyse, e.g. tau1")
    p.add_argument("--position", required=True, help="sampling-location column, e.g. q1 [rad]")
    p.add_argument("--schedule", default=None, help="scheduling column, e.g. dq1 [rad/s] (default: none)")
    p.add_argument("--out", default="spectrum-out", help="output folder (default ./spectrum-out)")
    p.add_argument("--n-components", type=int, default=3, help="components to extract (default 3)")
    p.add_argument("--n-basis", type=int, default=6, help="basis functions over the schedule (default 6)")
    p.add_argument("--f-max", type=float, default=None,
                   help="highest frequency to scan, cycles per unit position (default: sampling-density limit, capped)")
    p.add_argument("--base", choices=("inertia-coulomb-viscous", "coulomb-viscous", "none"), default=None,
                   help="regressors removed jointly: [ddq, sign(v), v] (default when the position is a joint q<j> "
                        "and a schedule is given: the joint's inertia must not leak into the spectrum), "
                        "[sign(v), v] (default for other positions with a schedule) or none")
    p.add_argument("--gear-ratio", type=float, default=None, help="motor revolutions per position revolution, "
                   "only for reporting cycles per motor revolution")
    p.add_argument("--drop-invalid", action="store_true", help="drop rows with NaN/inf (counted) instead of failing")
    p.add_argument("--level", type=float, default=0.95, help="confidence level of the bands (default 0.95)")
    p.add_argument("--robot", default="generic",
                   help="irb140 or a URDF path: refuse joint positions far outside its limits (degrees?); generic "
                        "(default): warn when joint positions look like degrees")
    p.set_defaults(func=run)


def _unit(column: str) -> str:
    """Units of the drake_est data format's joint columns (rad, rad/s, N m; m, m/s, N for linear axes)."""
    for pattern, unit in ((r"^q\d+$", " [rad or m]"), (r"^dq\d+$", " [rad/s or m/s]"), (r"^ddq\d+$", " [rad/s^2]"),
                          (r"^tau\d+$", " [N m or N]")):
        if re.match(pattern, column):
            return unit
    return ""


def _gear_from_meta(log, position):
    m = re.match(r"^q(\d+)$", position)
    if not m or str(log.meta.get("robot", "")).lower() != "irb140":
        return None
    try:
        from drake_est.robots import irb140_metadata

        return float(irb140_metadata().gear_ratios[int(m.group(1)) - 1])
    except Exception:  # noqa: BLE001 - metadata is optional for reporting
        return None


def run(args) -> int:
    from drake_est.spectral.detect import find_periodic_components
    from drake_est.spectral.plots import plot_amplitude_functions, plot_scan

    for name, val in (("--f-max", args.f_max), ("--gear-ratio", args.gear_ratio)):
        if val is not None and not (np.isfinite(val) and val > 0):
            raise DataError(f"{name} must be a finite number > 0, got {val}")
    from drake_est.cli._common import check_number

    check_number("--n-components", args.n_components, 1, 50, integer=True)
    check_number("--n-basis", args.n_basis, 1, 100, integer=True)
    check_number("--gear-ratio", args.gear_ratio, 0, 1e5, lo_strict=True)
    if not 0 < args.level < 1:
        raise DataError(f"--level must be in (0, 1), e.g. 0.95, got {args.level}")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise DataError(f"--out {args.out} exists and is not a folder")
    from drake_est.cli._common import load_log_checked

    log = load_log_checked(args.log, args.robot, "spectrum", nan_policy="drop" if args.drop_invalid else "raise",
                           require_tau=False)

    def column(opt, name):
        try:
            return np.asarray(log.column(name), dtype=float)
        except DataError as err:
            raise DataError(f"{opt} {name}: {err}") from None

    y = column("--signal", args.signal)
    x = column("--position", args.position)
    v = None if args.schedule is None else column("--schedule", args.schedule)
    if np.ptp(x) <= 0.02:
        raise DataError(f"position column '{args.position}' barely moves (range {np.ptp(x):.3g}); "
                        "a spectrum over position needs a column that sweeps a range")
    if v is not None and np.ptp(v) <= 0:
        raise DataError(f"scheduling column '{args.schedule}' is constant; drop --schedule")
    joint_pos = re.match(r"^q(\d+)$", args.position)
    if args.base is None:
        base_kind = "none" if v is None else ("inertia-coulomb-viscous" if joint_pos else "coulomb-viscous")
    else:
        base_kind = args.base
    base = None
    if base_kind != "none":
        if v is None:
            raise DataError(f"--base {base_kind} needs --schedule (the velocity)")
        base = np.column_stack([np.sign(v), v])
    if base_kind == "inertia-coulomb-viscous":
        if not joint_pos:
            raise DataError("--base inertia-coulomb-viscous needs a joint position column q<j> (for its acceleration)")
        base = np.column_stack([base, column("--position", f"ddq{joint_pos.group(1)}")])
    pc = find_periodic_components(x, y, schedule=v, n_components=args.n_components, n_basis=args.n_basis,
                                  f_max=args.f_max, base=base)
    gear = args.gear_ratio or _gear_from_meta(log, args.position)
    out.mkdir(parents=True, exist_ok=True)
    if gear:
        scale, unit = 2 * np.pi / gear, "cycles per motor revolution"
    else:
        scale, unit = 1.0, f"cycles per rad of {args.position}"
    B = np.ones((x.size, 1)) if base is None else np.column_stack([np.ones(x.size), base])
    resid = y - B @ np.linalg.lstsq(B, y, rcond=None)[0]
    plot_scan(pc, out / "spectrum.png", unit_scale=scale, unit_label=unit,
              title=f"{args.signal} vs {args.position}: LPV least-squares spectrum", classic=(x, resid))
    files = ["spectrum.png"]
    if v is not None:
        labels = [f"{f * scale:.4g} {'/motor rev' if gear else '/rad'}" for f in pc.freqs]
        plot_amplitude_functions(pc.model, v, out / "amplitude.png", level=args.level, labels=labels,
                                 v_label=f"{args.schedule}{_unit(args.schedule)}",
                                 amp_label=f"amplitude of {args.signal}{_unit(args.signal)}")
        files.append("amplitude.png")
    result = {
        "log": str(args.log), "signal": args.signal, "position": args.position, "schedule": args.schedule,
        "base": base_kind, "n_samples": int(x.size), "gear_ratio": gear,
        "frequency_unit": unit,
        "components": pc.summary(gear_ratio=gear),
        "total_explained_fraction": pc.total_explained_fraction,
        "base_explained_fraction": pc.base_explained_fraction,
        "files": files,
    }
    from drake_est.jsonutil import dump_json

    dump_json(result, out / "spectrum.json")
    for c in result["components"]:
        f = c.get("frequency_per_motor_rev", c["frequency_per_unit"])
        print(f"{f:10.4f} {unit}: RMS amplitude {c['rms_amplitude']:.4g}, explains "
              f"{100 * c['explained_fraction']:.1f} % of the residual variance")
    print(f"wrote {out / 'spectrum.json'} and {', '.join(files)}")
    return 0
