"""``drake-est synth``: write a simulated IRB 140 log with a hidden effect (ground truth beside it)."""
from __future__ import annotations

from pathlib import Path

from drake_est.errors import DrakeEstError
from drake_est.jsonutil import dump_json


def register(sub):
    from drake_est.synth import EFFECTS

    p = sub.add_parser("synth", help="simulate an IRB140 experiment with hidden effects; write a CSV log",
                       description="Simulate the IRB 140 in Drake under a tracking controller with a hidden effect "
                       "and write a log in the drake_est data format. The ground truth goes to OUT.truth.json.")
    p.add_argument("--effect", action="append", default=None,
                   help=f"hidden effect (repeatable): none, {', '.join(EFFECTS)}")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--joints", default=None, help="comma-separated 1-based joints that move (default depends on effect)")
    p.add_argument("--duration", type=float, default=None, help="simulated seconds (default 300, 900 with the energy effect); the first second, the controller's start-up, is not logged")
    p.add_argument("--rate", type=float, default=100.0, help="sample rate [Hz] (default 100)")
    p.add_argument("--experiment", choices=["sweep", "excitation"], default=None, help="trajectory type")
    p.add_argument("--noise", type=float, default=None, help="torque noise std [N m] (default random 0.2-0.6)")
    p.add_argument("--out", required=True, help="output log (.csv or .npz)")
    p.set_defaults(func=run)


def parse_joints(text):
    if text is None:
        return None
    try:
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise DrakeEstError(f"--joints must be comma-separated integers like 1,2, got '{text}'") from None


def run(args) -> int:
    from drake_est.data import save_log
    from drake_est.synth import synthesize

    from drake_est.cli._common import check_number

    effects = args.effect or ["none"]
    check_number("--duration", args.duration, 5, 1e5, unit="s")
    check_number("--rate", args.rate, 10, 5000, unit="Hz")
    check_number("--noise", args.noise, 0, 1e3, unit="N m")
    check_number("--seed", args.seed, 0, 2**32 - 1, integer=True)
    if args.duration is not None and args.duration < 5:
        raise DrakeEstError(f"--duration {args.duration} s is too short (at least 5 s)")
    if args.noise is not None and not args.noise >= 0:
        raise DrakeEstError(f"--noise {args.noise} N m must be >= 0")
    if Path(args.out).is_dir():
        raise DrakeEstError(f"--out {args.out} is a folder; give a file name ending in .csv or .npz")
    if args.rate <= 0 or args.rate > 5000:
        raise DrakeEstError(f"--rate {args.rate} Hz is outside (0, 5000]")
    log, truth = synthesize(effects if len(effects) > 1 else effects[0], seed=args.seed, joints=parse_joints(args.joints),
                            duration=args.duration, sample_rate=args.rate, experiment=args.experiment,
                            noise_std=args.noise, progress=True)
    out = save_log(log, args.out)
    tpath = Path(str(out) + ".truth.json")
    keep = {k: v for k, v in truth.items() if k not in ("friction_torque", "q_true", "dq_true", "truth_model")}
    dump_json(keep, tpath)
    print(f"wrote {out} ({log.n_samples} samples, {log.duration:.0f} s, joints {truth['joints']} moving, "
          f"effects: {', '.join(truth['effects']) or 'none'}); ground truth in {tpath}")
    return 0

