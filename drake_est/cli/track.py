"""``drake-est track``: closed-loop seam tracking on the IRB 140 (thesis Ch. 14) in a Drake Diagram."""
from __future__ import annotations

from pathlib import Path


def register(sub):
    p = sub.add_parser("track", help="simulate closed-loop seam tracking with the particle filter (thesis Ch. 14)",
                       description="Simulate the IRB 140 following a seam under friction-stir-welding forces, "
                       "the seam-tracking particle filter fusing encoders and laser stripes, and a tracking "
                       "controller; write plots, seam.html (Meshcat replay) and track.json.")
    p.add_argument("--seam", required=True, help="xy or yz (thesis Fig. 14.9) or a CSV file of x,y,z points [m]")
    p.add_argument("--sensors", type=int, choices=[0, 1, 2], default=2, help="laser stripes ahead of the tool")
    p.add_argument("--particles", type=int, default=500, help="number of particles (default 500)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--speed", type=float, default=None, help="travel speed [m/s] (default 0.02)")
    p.add_argument("--meshcat", action="store_true",
                   help="also serve a live Meshcat (prints its URL): robot, seam, laser stripes and particle cloud "
                        "update during the run (every 0.05 s of simulated time); the replay is loaded into it "
                        "afterwards")
    p.add_argument("--realtime-rate", type=float, default=None,
                   help="run the simulation at this multiple of real time (e.g. 1 to watch it live; default: as "
                        "fast as possible; track.json's realtime_factor then measures the slowed run)")
    p.add_argument("--out", required=True, help="output folder")
    p.set_defaults(func=run)


def run(args) -> int:
    from drake_est.errors import DataError
    from drake_est.jsonutil import dump_json
    from drake_est.seam.analysis import run_tracking
    from drake_est.seam.simulate import ScenarioConfig

    from drake_est.cli._common import check_number

    if args.particles < 2:
        raise DataError(f"--particles must be >= 2, got {args.particles}")
    check_number("--particles", args.particles, 2, 100_000, integer=True)   # memory and time stay bounded
    check_number("--seed", args.seed, 0, 2**32 - 1, integer=True)
    # the simulated duration is the seam length / speed: bounded below; the robot's joint speeds bound it above
    check_number("--speed", args.speed, 1e-3, 0.5, unit="m/s")
    check_number("--realtime-rate", args.realtime_rate, 1e-2, 1e2)
    sc = ScenarioConfig() if args.speed is None else ScenarioConfig(speed=args.speed)
    live = None
    if args.meshcat:
        from pydrake.geometry import Meshcat
        live = Meshcat()
        print(f"Meshcat: {live.web_url()}")
    res = run_tracking(args.seam, sensors=args.sensors, particles=args.particles, seed=args.seed,
                       out_dir=args.out, scenario_config=sc, live_meshcat=live,
                       realtime_rate=args.realtime_rate)
    out = Path(args.out)
    dump_json(res, out / "track.json")
    print(f"cross-seam RMSE {res['cross_seam_rmse_mm']:.3f} mm closed loop, "
          f"{res['open_loop_cross_seam_rmse_mm']:.3f} mm open loop; orientation RMSE "
          f"{res['orientation_rmse_deg']:.3f} deg; filter {res['filter_steps_per_s']:.0f} steps/s; "
          f"real-time factor {res['realtime_factor']:.2f} (wall), {res['realtime_factor_cpu']:.2f} (CPU time)")
    print(f"wrote {out / 'track.json'}, {out / 'seam.html'}, {out / 'tracking.png'}, {out / 'heatmap.png'}")
    return 0
