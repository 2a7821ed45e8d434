"""Cost of the live Meshcat view in the seam-tracking Diagram (thesis Ch. 14).

    python benchmarks/bench_seam_meshcat.py [--repeats 3] [--particles 500] [--period 0.05] [--json FILE]
                                            [--check]

Simulates the closed-loop Diagram (xy seam, two stripes, 1 kHz, 200 mm at 0.1 m/s: ~2.4 s simulated) built
(a) without Meshcat and (b) with a live Meshcat (robot + overlay publishing every ``--period`` s of
simulated time, no browser connected), alternately ``--repeats`` times, and reports the CPU time of this
process and the wall time of ``Simulator.AdvanceTo`` for each, their medians and the ratios (b)/(a).
Without a Meshcat the Diagram holds no visualization system at all, so (a) is the plain Diagram.
``--check`` exits 1 when the median CPU-time ratio exceeds 1.25.
"""
import argparse
import json
import os
import sys
import time

import numpy as np


def one_run(scn, cfg, meshcat, period):
    from pydrake.systems.analysis import Simulator
    from drake_est.systems.seam import MakeSeamTrackingDiagram
    diagram, _ = MakeSeamTrackingDiagram(scn, cfg, seed=0, meshcat=meshcat, meshcat_period=period)
    sim = Simulator(diagram)
    sim.Initialize()
    t_end = (scn.T - 1) * scn.config.dt
    t0, c0 = time.perf_counter(), time.process_time()
    sim.AdvanceTo(t_end)
    return time.perf_counter() - t0, time.process_time() - c0, t_end


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--particles", type=int, default=500)
    ap.add_argument("--period", type=float, default=0.05)
    ap.add_argument("--json", default=None)
    ap.add_argument("--check", action="store_true")
    a = ap.parse_args(argv)
    os.environ.setdefault("DRAKE_EST_NO_PROGRESS", "1")
    from pydrake.geometry import Meshcat
    from drake_est.seam.analysis import filter_config_for
    from drake_est.seam.seam import thesis_seam
    from drake_est.seam.simulate import ScenarioConfig, make_scenario

    scn = make_scenario(thesis_seam("xy"), ScenarioConfig(speed=0.1), seed=0)
    cfg = filter_config_for(scn, 2, a.particles)
    meshcat = Meshcat()
    one_run(scn, cfg, None, a.period)                  # warm-up (compiled kernels, caches)
    rows = {"none": [], "meshcat": []}
    for _ in range(a.repeats):
        for name, m in (("none", None), ("meshcat", meshcat)):
            wall, cpu, sim_s = one_run(scn, cfg, m, a.period)
            rows[name].append({"wall_s": wall, "cpu_s": cpu})
    med = {k: {q: float(np.median([r[q] for r in v])) for q in ("wall_s", "cpu_s")} for k, v in rows.items()}
    out = {"simulated_s": sim_s, "particles": a.particles, "meshcat_period_s": a.period, "repeats": a.repeats,
           "browser_connected": meshcat.GetNumActiveConnections() > 0, "runs": rows, "median": med,
           "cpu_ratio_meshcat_over_none": med["meshcat"]["cpu_s"] / med["none"]["cpu_s"],
           "wall_ratio_meshcat_over_none": med["meshcat"]["wall_s"] / med["none"]["wall_s"],
           "realtime_factor_cpu_none": sim_s / med["none"]["cpu_s"],
           "realtime_factor_cpu_meshcat": sim_s / med["meshcat"]["cpu_s"],
           "load_average": list(os.getloadavg())}
    print(json.dumps({k: v for k, v in out.items() if k != "runs"}))
    if a.json:
        from drake_est.jsonutil import dump_json
        dump_json(out, a.json)
    if a.check and out["cpu_ratio_meshcat_over_none"] > 1.25:
        print("live Meshcat costs more than 25 % CPU time", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
