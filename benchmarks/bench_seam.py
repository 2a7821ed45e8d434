"""Seam-tracking benchmark (thesis Ch. 14): filter speed, Diagram real-time factor, accuracy over seeds.

    python benchmarks/bench_seam.py [--seeds 20] [--particles 500] [--json FILE] [--check] [--workers N]
                                    [--speed-only]

* ``filter_steps_per_s``: the bare filter update (correct + predict of the generic ParticleFilter with the
  SE(3) seam model: robot measurement + two laser stripes), 500 particles, one process, on measurements
  recorded along the xy seam; also per CPU second of the process (the machine may be shared) and, as a
  load reference measured in the same run, the generic ``ParticleFilter.gaussian`` step on a 6-state
  linear model with 500 particles.
* ``realtime_factor``: simulated seconds / wall seconds of the closed-loop Diagram (plant, sensors,
  estimator, controller) at a 1 kHz filter rate (and per CPU second).
* accuracy: closed- and open-loop cross-seam RMSE [mm] and orientation RMSE [deg] on the xy seam with two
  stripes over ``--seeds`` seeds (200 mm at 0.1 m/s, 1 kHz): median, 10 % and 90 % quantiles.

``--check`` exits 1 when a target in ``check()`` is missed.
"""
import argparse
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np


def _accuracy(seed, particles):
    os.environ.setdefault("DRAKE_EST_NO_PROGRESS", "1")
    from drake_est.seam.analysis import filter_config_for
    from drake_est.seam.seam import thesis_seam
    from drake_est.seam.simulate import ScenarioConfig, make_scenario, run_loop, tracking_metrics
    scn = make_scenario(thesis_seam("xy"), ScenarioConfig(speed=0.1), seed=seed)
    cfg = filter_config_for(scn, 2, particles)
    mc = tracking_metrics(scn, run_loop(scn, cfg, closed_loop=True, seed=seed))
    mo = tracking_metrics(scn, run_loop(scn, cfg, closed_loop=False, seed=seed))
    return mc, mo


def reference_pf_steps_per_s(particles=500, steps=500):
    from drake_est.estimation.pf import ParticleFilter
    A = np.eye(6) * 0.99
    pf = ParticleFilter.gaussian(lambda x, u, t: x @ A.T, lambda x, u, t: x[..., :3], 1e-4 * np.eye(6),
                                 1e-2 * np.eye(3), np.zeros(6), np.eye(6), n_particles=particles, seed=0)
    x, lw = pf.initial_belief()
    y = np.zeros(3)
    t0 = time.perf_counter()
    for k in range(steps):
        x, lw, _ = pf.correct(x, lw, y, t=k)
        x, lw = pf.predict(x, lw, t=k)
    return steps / (time.perf_counter() - t0)


def q(v):
    v = np.asarray(v, float)
    return {"median": float(np.median(v)), "q10": float(np.percentile(v, 10)), "q90": float(np.percentile(v, 90)),
            "max": float(v.max())}


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--particles", type=int, default=500)
    ap.add_argument("--workers", type=int, default=os.cpu_count())
    ap.add_argument("--json", default=None)
    ap.add_argument("--check", action="store_true")
    ap.add_argument("--speed-only", action="store_true", help="skip the accuracy runs over seeds")
    a = ap.parse_args(argv)
    os.environ.setdefault("DRAKE_EST_NO_PROGRESS", "1")
    from drake_est.progress import progress
    from drake_est.seam.analysis import bare_filter_speed, filter_config_for, simulate_diagram
    from drake_est.seam.seam import thesis_seam
    from drake_est.seam.simulate import ScenarioConfig, make_scenario

    scn = make_scenario(thesis_seam("xy"), ScenarioConfig(speed=0.1), seed=0)
    cfg = filter_config_for(scn, 2, a.particles)
    ref = reference_pf_steps_per_s(a.particles)
    fs, fs_cpu = bare_filter_speed(scn, cfg, steps=1000)
    ref2 = reference_pf_steps_per_s(a.particles)
    _, wall, cpu = simulate_diagram(scn, cfg, seed=0)
    sim_t = (scn.T - 1) * scn.config.dt
    out = {"filter_steps_per_s": fs, "filter_steps_per_cpu_s": fs_cpu,
           "reference_gaussian_pf_steps_per_s": 0.5 * (ref + ref2),
           "filter_over_reference": fs / (0.5 * (ref + ref2)),
           "realtime_factor": sim_t / wall, "realtime_factor_cpu": sim_t / cpu, "particles": a.particles,
           "load_average_1min": os.getloadavg()[0], "cpu_count": os.cpu_count()}
    print(f"filter update: {fs:,.0f} steps per wall second, {fs_cpu:,.0f} steps per CPU second "
          f"(target 5,000 per CPU second); Diagram at 1 kHz: {out['realtime_factor']:.2f}x real time (wall), "
          f"{out['realtime_factor_cpu']:.2f}x (CPU); load average {out['load_average_1min']:.1f}",
          file=sys.stderr)
    if a.speed_only:
        return _report(out, a)
    with ProcessPoolExecutor(a.workers) as ex:
        res = list(progress(ex.map(_accuracy, range(a.seeds), [a.particles] * a.seeds), total=a.seeds,
                            desc="seeds"))
    out["seeds"] = a.seeds
    out["closed_loop_cross_seam_rmse_mm"] = q([r[0]["cross_seam_rmse_mm"] for r in res])
    out["open_loop_cross_seam_rmse_mm"] = q([r[1]["cross_seam_rmse_mm"] for r in res])
    out["orientation_rmse_deg"] = q([r[0]["orientation_rmse_deg"] for r in res])
    out["along_seam_rmse_mm"] = q([r[0]["along_seam_rmse_mm"] for r in res])
    out["n_degenerate_total"] = int(sum(r[0]["n_degenerate"] for r in res))
    return _report(out, a)


def _report(out, a) -> int:
    """Print the figures, write them to ``--json``, and with ``--check`` return 1 when a target is missed."""
    print(json.dumps(out, indent=1))
    if a.json:
        from drake_est.jsonutil import dump_json
        dump_json(out, a.json)
    missed = check(out) if a.check else []
    for m in missed:
        print("MISSED:", m, file=sys.stderr)
    return 1 if missed else 0


def check(out):
    missed = []
    if out["filter_steps_per_cpu_s"] < 5000:
        missed.append(f"filter {out['filter_steps_per_cpu_s']:.0f} steps per CPU second < 5000")
    if out["realtime_factor_cpu"] < 1:
        missed.append(f"Diagram real-time factor (CPU) {out['realtime_factor_cpu']:.2f} < 1")
    if "closed_loop_cross_seam_rmse_mm" not in out:          # --speed-only
        return missed
    if out["closed_loop_cross_seam_rmse_mm"]["median"] >= 0.5:
        missed.append("closed-loop cross-seam RMSE median >= 0.5 mm")
    if out["orientation_rmse_deg"]["median"] >= 0.5:
        missed.append("orientation RMSE median >= 0.5 deg")
    return missed


if __name__ == "__main__":
    sys.exit(main())
