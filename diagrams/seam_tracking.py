"""Closed-loop seam tracking on the IRB 140 (thesis Ch. 14) in a Drake Diagram.

The compliant IRB 140 (``MultibodyPlant`` kinematics, joint springs deflecting the arm by K^-1 J^T f under
friction-stir-welding forces of ~2 kN, plus joint offsets the model does not know) follows a seam of thesis
Fig. 14.9; encoders, a force sensor and one or two laser stripes ahead of the tool feed the seam-tracking
particle filter (SE(3), generic ``ParticleFilter``), whose estimate a tracking controller uses to correct the
commanded joints.  The open loop (same model, no correction) is run beside it.

    python diagrams/seam_tracking.py [--duration 10] [--out seam_tracking.png] [--seam xy|yz|FILE]
                                     [--sensors 2] [--particles 500] [--seed 0] [--meshcat]
                                     [--realtime-rate R]

``--duration`` is the time to traverse the 200 mm seam.  Writes the figure, ``<out stem>.json`` next to it
(``cross_seam_rmse_mm`` closed loop, ``open_loop_cross_seam_rmse_mm``, ``orientation_rmse_deg``,
``filter_steps_per_s``, ``realtime_factor``, ...), the particle heat map and the Meshcat replay ``seam.html``.
With ``--meshcat`` a live Meshcat is served as well: the robot, the seam, the laser stripes and the particle
cloud update during the simulation (every 0.05 s of simulated time; ``--realtime-rate 1`` to watch it at
real time).
"""
import argparse
import json
import shutil
from pathlib import Path


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=10.0, help="seconds to traverse the seam")
    ap.add_argument("--out", default="seam_tracking.png")
    ap.add_argument("--seam", default="xy")
    ap.add_argument("--sensors", type=int, default=2, choices=[0, 1, 2])
    ap.add_argument("--particles", type=int, default=500)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--meshcat", action="store_true", help="serve a live Meshcat (prints its URL)")
    ap.add_argument("--realtime-rate", type=float, default=None, help="simulate at this multiple of real time")
    a = ap.parse_args(argv)

    from drake_est.jsonutil import dump_json
    from drake_est.seam.analysis import run_tracking, seam_from_arg
    from drake_est.seam.simulate import ScenarioConfig

    seam = seam_from_arg(a.seam)
    out = Path(a.out)
    folder = out.parent
    folder.mkdir(parents=True, exist_ok=True)
    live = None
    if a.meshcat:
        from pydrake.geometry import Meshcat
        live = Meshcat()
        print("Meshcat:", live.web_url())
    res = run_tracking(a.seam, sensors=a.sensors, particles=a.particles, seed=a.seed, out_dir=folder,
                       scenario_config=ScenarioConfig(speed=seam.length / a.duration), live_meshcat=live,
                       realtime_rate=a.realtime_rate)
    if (folder / "tracking.png").resolve() != out.resolve():
        shutil.move(str(folder / "tracking.png"), str(out))
    dump_json(res, out.with_suffix(".json"))
    print(json.dumps({k: res[k] for k in ("cross_seam_rmse_mm", "open_loop_cross_seam_rmse_mm",
                                          "orientation_rmse_deg", "filter_steps_per_s", "realtime_factor")}))


if __name__ == "__main__":
    main()
