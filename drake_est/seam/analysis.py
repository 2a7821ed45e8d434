"""Seam-tracking runs and analysis tools (thesis Sec. 14.2-14.3).

* :func:`run_tracking` -- one closed-loop run in the Drake Diagram (:mod:`drake_est.systems.seam`) with the
  open loop beside it, plots, the Meshcat replay ``seam.html`` and the numbers of ``track.json``;
* :func:`particle_heatmap` -- particle density of one state coordinate over time (Fig. 14.5);
* :func:`sensor_study` -- error distributions for 0, 1, 2 laser stripes on the xy and yz seams (Fig. 14.8);
* :func:`significance_study` -- Monte-Carlo runs with perturbed filter parameters and linear models of the
  errors, log10 p-values of each parameter (Fig. 14.6).

Monte-Carlo runs use all local cores by default (``workers``) and show a progress bar.
"""
from __future__ import annotations

import math
import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from drake_est.errors import DataError
from drake_est.progress import progress
from drake_est.seam.filter import SeamFilterConfig, deviation_to_pose
from drake_est.seam.seam import Seam, load_seam_csv, thesis_seam
from drake_est.seam.simulate import (LoopResult, ScenarioConfig, compliance_model, make_scenario, run_loop,
                                     tracking_metrics)

SENSOR_LAYOUTS = {0: (), 1: (0.04,), 2: (0.04, 0.08)}


def seam_from_arg(arg: str) -> Seam:
    """``xy`` / ``yz`` (Fig. 14.9) or a CSV file of points."""
    if arg in ("xy", "yz"):
        return thesis_seam(arg)
    return load_seam_csv(arg)


def filter_config_for(scn, sensors: int, particles: int = 500, **kw) -> SeamFilterConfig:
    if sensors not in SENSOR_LAYOUTS:
        raise DataError(f"--sensors must be 0, 1 or 2, got {sensors}")
    return SeamFilterConfig(sensor_distances=SENSOR_LAYOUTS[sensors], n_particles=int(particles),
                            compliance=compliance_model(scn), **kw)


def check_laser_sees_seam(scn, cfg: SeamFilterConfig) -> None:
    """DataError when a laser stripe never meets the seam along the nominal path."""
    from drake_est.seam.filter import laser_measurement, sensor_mount
    for d in cfg.sensor_distances:
        T_S = sensor_mount(d)
        seen = any(laser_measurement(scn.robot.forward_kinematics(scn.q_ref[k]).GetAsMatrix4() @ scn.X_FT, T_S,
                                     scn.seam.points, scn.seam.normals) is not None
                   for k in np.linspace(0, scn.T - 1, 20).astype(int))
        if not seen:
            raise DataError(f"the laser plane of the stripe {d * 1e3:.0f} mm ahead of the tool never meets the "
                            f"seam '{scn.seam.name}'")


# ------------------------------------------------------------------------------------------ one run
def simulate_diagram(scn, cfg, seed: int = 0, closed_loop: bool = True, particle_every: int = 20, meshcat=None,
                     meshcat_period: float = 0.05, realtime_rate: float | None = None):
    """Run the seam-tracking Diagram over the whole scenario; returns (LoopResult, wall time [s], CPU time of
    this process [s]).  With ``meshcat`` the robot, seam, laser stripes and particle cloud are drawn live every
    ``meshcat_period`` [s] of simulated time; ``realtime_rate`` slows the simulator to that multiple of real
    time (to watch it; None: as fast as possible)."""
    from pydrake.systems.analysis import Simulator
    from drake_est.systems.seam import MakeSeamTrackingDiagram

    dt = scn.config.dt
    diagram, h = MakeSeamTrackingDiagram(scn, cfg, closed_loop=closed_loop, seed=seed,
                                         particle_period=particle_every * dt, meshcat=meshcat,
                                         meshcat_period=meshcat_period)
    sim = Simulator(diagram)
    ctx = sim.get_context()
    t_end = (scn.T - 1) * dt
    bar = progress(total=100, desc="seam tracking")
    last = [0]

    def monitor(c):
        p = int(100 * c.get_time() / max(t_end, 1e-12))
        if p > last[0]:
            bar.update(p - last[0])
            last[0] = p
        from pydrake.systems.framework import EventStatus
        return EventStatus.Succeeded()

    sim.set_monitor(monitor)
    if realtime_rate is not None:
        if not realtime_rate > 0:
            raise DataError(f"realtime_rate must be > 0, got {realtime_rate}")
        sim.set_target_realtime_rate(float(realtime_rate))
    sim.Initialize()
    t0, c0 = time.perf_counter(), time.process_time()
    sim.AdvanceTo(t_end)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    bar.close()
    pose = h["log_pose"].FindLog(ctx).data().T.reshape(-1, 4, 4)
    cmd = h["log_cmd"].FindLog(ctx).data().T
    est = h["log_est"].FindLog(ctx).data().T
    T = min(len(pose), scn.T)
    model = h["model"]
    # the estimate port shows the previous update: xi_k|k is logged at step k + 1
    xi = np.vstack([est[1:T], est[T - 1:T]]) if T > 1 else est[:T]
    X_est = np.stack([deviation_to_pose(model.tool_pose(cmd[k]), xi[k]) for k in range(T)])
    parts = h["log_particles"].FindLog(ctx).data().T.reshape(-1, h["pf"].N, 6)
    diag = h["estimator"].GetOutputPort("diagnostics").Eval(h["estimator"].GetMyContextFromRoot(ctx))
    res = LoopResult(pose[:T], X_est, cmd[:T], parts, np.arange(parts.shape[0]) * particle_every,
                     np.full(T, np.nan), int(diag[1]), float("nan"), wall, len(cfg.sensor_distances), closed_loop)
    return res, wall, cpu


def run_tracking(seam_arg: str, sensors: int = 2, particles: int = 500, seed: int = 0, out_dir=".",
                 scenario_config: ScenarioConfig | None = None, html: bool = True, live_meshcat=None,
                 realtime_rate: float | None = None) -> dict:
    """``drake-est track``: the closed loop in the Drake Diagram and the open loop (numpy loop, the same
    model), plots, ``seam.html`` and the numbers of ``track.json``.  ``live_meshcat``: a Meshcat drawn live
    during the run (and given the replay afterwards); ``realtime_rate``: see :func:`simulate_diagram`."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    seam = seam_from_arg(seam_arg)
    scn = make_scenario(seam, scenario_config or ScenarioConfig(), seed=seed)
    cfg = filter_config_for(scn, sensors, particles)
    check_laser_sees_seam(scn, cfg)
    closed, wall, cpu = simulate_diagram(scn, cfg, seed=seed, closed_loop=True, meshcat=live_meshcat,
                                         realtime_rate=realtime_rate)
    opened = run_loop(scn, cfg, closed_loop=False, seed=seed)
    mc, mo = tracking_metrics(scn, closed), tracking_metrics(scn, opened)
    sim_time = (scn.T - 1) * scn.config.dt
    speed, speed_cpu = bare_filter_speed(scn, cfg, seed=seed, steps=min(500, scn.T))
    result = {
        "seam": seam.name, "sensors": int(sensors), "particles": int(particles), "seed": int(seed),
        "steps": int(scn.T), "dt_s": scn.config.dt, "simulated_s": sim_time,
        "cross_seam_rmse_mm": mc["cross_seam_rmse_mm"],
        "open_loop_cross_seam_rmse_mm": mo["cross_seam_rmse_mm"],
        "orientation_rmse_deg": mc["orientation_rmse_deg"],
        "orientation_rmse_deg_xyz_tool": mc["orientation_rmse_deg_xyz"],
        "along_seam_rmse_mm": mc["along_seam_rmse_mm"],
        "estimate_cross_seam_rmse_mm": mc["estimate_cross_seam_rmse_mm"],
        "estimate_along_seam_rmse_mm": mc["estimate_along_seam_rmse_mm"],
        "max_deflection_mm": max_deflection_mm(scn),
        "filter_steps_per_s": speed,
        "filter_steps_per_cpu_s": speed_cpu,
        "realtime_factor": sim_time / wall,
        "realtime_factor_cpu": sim_time / max(cpu, 1e-9),
        "diagram_wall_s": wall,
        "diagram_cpu_s": cpu,
        "n_degenerate": mc["n_degenerate"],
        "compressed_knots": int(scn.compressed.knots.shape[0]),
        "compression_max_error_mm": 1e3 * scn.compressed.max_error,
    }
    plot_run(scn, closed, opened, out / "tracking.png")
    particle_heatmap(scn, closed, out / "heatmap.png")
    if html:
        write_meshcat_html(scn, closed, cfg, out / "seam.html", meshcat=live_meshcat)
    return result


def max_deflection_mm(scn) -> float:
    """Largest tool displacement caused by the process force along the nominal path [mm]."""
    from drake_est.seam.simulate import deflection
    ks = np.linspace(0, scn.T - 1, 30).astype(int)
    d = []
    for k in ks:
        q = scn.q_ref[k]
        q2 = q + deflection(scn.robot, scn.X_FT, q, scn.force[k], scn.config.stiffness)
        a = scn.robot.forward_kinematics(q).GetAsMatrix4() @ scn.X_FT
        b = scn.robot.forward_kinematics(q2).GetAsMatrix4() @ scn.X_FT
        d.append(np.linalg.norm(a[:3, 3] - b[:3, 3]))
    return 1e3 * float(max(d))


def bare_filter_speed(scn, cfg, seed: int = 0, steps: int = 500) -> float:
    """Filter steps per second (correct + predict, one core) on measurements recorded along the path:
    (per wall-clock second, per CPU second of this process -- the two differ on a loaded machine)."""
    from drake_est.seam.filter import filter_step, make_seam_filter
    from drake_est.seam.simulate import measure_all, true_tool_pose
    pf, model = make_seam_filter(scn.robot, scn.X_FT, scn.compressed, cfg, seed=seed)
    Y, U = [], []
    for k in range(steps):
        q = scn.q_ref[k]
        y = measure_all(scn, model, true_tool_pose(scn, q, scn.force[k])[0], q, scn.force[k], seed, k)
        Y.append(y)
        U.append(np.concatenate([q, y[6:9]]))
    x, logw = pf.initial_belief()
    filter_step(pf, x, logw, Y[0], U[0], 0)              # compile
    t0, c0 = time.perf_counter(), time.process_time()
    for k in range(steps):
        x, logw, *_ = filter_step(pf, x, logw, Y[k], U[k], k)
    return steps / (time.perf_counter() - t0), steps / max(time.process_time() - c0, 1e-9)


# ------------------------------------------------------------------------------------------- plots
def _errors(scn, res):
    T = res.X_true.shape[0]
    d = res.X_true[:, :3, 3] - scn.X_ref[:T, :3, 3]
    return (d * scn.cross[:T]).sum(1)


def plot_run(scn, closed: LoopResult, opened: LoopResult, path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    t = np.arange(closed.X_true.shape[0]) * scn.config.dt
    fig, ax = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    ax[0].plot(t, 1e3 * _errors(scn, opened), label="open loop")
    ax[0].plot(t, 1e3 * _errors(scn, closed), label="closed loop (PF estimate)")
    ax[0].set_ylabel("cross-seam error [mm]")
    ax[0].legend()
    e = closed.X_est[:, :3, 3] - closed.X_true[:, :3, 3]
    for j, n in enumerate("xyz"):
        ax[1].plot(t, 1e3 * e[:, j], label=n)
    ax[1].set_ylabel("estimate error [mm]")
    ax[1].legend()
    ax[2].plot(t, np.linalg.norm(scn.force, axis=1))
    ax[2].set_ylabel("|f| [N]")
    ax[2].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def particle_heatmap(scn, res: LoopResult, path, coordinate: int = 0, bins: int = 60) -> dict:
    """Fig. 14.5: density of the particles' coordinate ``coordinate`` of xi (0..2: dp [mm], 3..5: dtheta
    [mrad]) over time, with the true deviation as a black line.  Returns the heat map array summary."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from drake_est.seam.filter import pose_to_deviation
    P = res.particles[:, :, coordinate] * 1e3
    steps = res.particle_steps[:P.shape[0]]
    steps = steps[steps < res.X_true.shape[0]]
    P = P[:steps.size]
    true = np.array([1e3 * pose_to_deviation(
        scn.robot.forward_kinematics(res.q_cmd[k]).GetAsMatrix4() @ scn.X_FT, res.X_true[k])[coordinate]
        for k in steps])
    lo, hi = np.percentile(np.concatenate([P.ravel(), true]), [0.5, 99.5])
    edges = np.linspace(lo - 1e-9, hi + 1e-9, bins + 1)
    H = np.stack([np.histogram(p, edges)[0] for p in P], axis=1)
    fig, ax = plt.subplots(figsize=(8, 3.5))
    ax.imshow(H, origin="lower", aspect="auto", cmap="viridis",
              extent=[steps[0], steps[-1], edges[0], edges[-1]])
    ax.plot(steps, true, "k", lw=1.5, label="true")
    ax.set_xlabel("time step")
    ax.set_ylabel(["dp_x", "dp_y", "dp_z", "dth_x", "dth_y", "dth_z"][coordinate] + (" [mm]" if coordinate < 3 else " [mrad]"))
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return {"frames": int(P.shape[0]), "bins": int(bins)}


# ------------------------------------------------------------------------------------------ meshcat
def write_meshcat_html(scn, res: LoopResult, cfg, path, meshcat=None, frames: int = 150,
                       clouds: int = 40) -> Path:
    """Self-contained Meshcat replay of a run, written with ``meshcat.StaticHtml()``: the deflected robot,
    the seam, the laser stripes (fans moving with the true tool, a dot where each meets the seam), the
    true and estimated tool and the particle cloud, all animated over time (Meshcat's recording: transforms
    and ``visible`` properties per frame, ``frames`` frames).  The particle cloud is up to ``clouds``
    snapshots of the logged clouds (every ``particle_every`` steps of the run), each shown from its step
    until the next one, in the frame of the nominal tool pose that moves every frame.  Scene paths:
    :mod:`drake_est.seam.viz`."""
    from pydrake.geometry import Meshcat, MeshcatVisualizer, MeshcatVisualizerParams
    from drake_est.robots import add_irb140
    from drake_est.seam import viz
    from drake_est.seam.simulate import deflection

    if frames < 2:
        raise DataError(f"frames must be >= 2, got {frames}")
    if meshcat is not None:      # a live view's last particle cloud is not part of the replay
        meshcat.Delete(f"{viz.PREFIX}/particles/live")
    meshcat = meshcat or Meshcat()
    T = res.X_true.shape[0]
    dt = scn.config.dt
    duration = max((T - 1) * dt, dt)
    # recording rate: every replay frame gets its own animation frame (and at least 30 frames/s)
    fps = max(30.0, 2.0 * (frames - 1) / duration)
    builder, plant, sg, _ = add_irb140(None, time_step=0.0)
    vis = MeshcatVisualizer.AddToBuilder(builder, sg, meshcat, MeshcatVisualizerParams(publish_period=1.0 / fps))
    diagram = builder.Build()
    ctx = diagram.CreateDefaultContext()
    pctx = plant.GetMyMutableContextFromRoot(ctx)
    knots, normals = scn.seam.points, scn.seam.normals
    dists = tuple(cfg.sensor_distances)
    depths = [viz.stripe_depth(res.X_true[0], d, knots, normals) for d in dists]
    viz.draw_static(meshcat, knots, dists, depths, X_FT=scn.X_FT)
    viz.look_at_seam(meshcat, knots)
    ks = np.unique(np.linspace(0, T - 1, frames).astype(int))

    def nominal(k):
        return scn.robot.forward_kinematics(res.q_cmd[k]).GetAsMatrix4() @ scn.X_FT

    # particle snapshots: at most `clouds`, evenly over the logged ones; snapshot i is visible on the frames
    # from its step to the next snapshot's
    steps = np.asarray(res.particle_steps[:res.particles.shape[0]], int)
    keep = np.flatnonzero(steps < T)
    clouds = min(int(clouds), ks.size)
    if keep.size > clouds:
        keep = keep[np.unique(np.linspace(0, keep.size - 1, clouds).round().astype(int))]
    for i, j in enumerate(keep):
        viz.set_particles(meshcat, res.particles[j], name=str(i))
    shown = np.searchsorted(steps[keep], ks, side="right") - 1 if keep.size else np.full(ks.size, -1)

    vis.StartRecording()
    for n, k in enumerate(ks):
        t = k * dt
        q = res.q_cmd[k] + deflection(scn.robot, scn.X_FT, res.q_cmd[k], scn.force[k], scn.config.stiffness)
        plant.SetPositions(pctx, q + scn.kin_offsets)
        ctx.SetTime(t)
        diagram.ForcedPublish(ctx)
        viz.set_frame(meshcat, viz.frame_poses(res.X_true[k], nominal(k), res.X_est[k], dists, knots, normals),
                      time_in_recording=t)
        for i in range(keep.size):        # key frames only where a snapshot's visibility changes
            vis_now = bool(shown[n] == i)
            if n == 0 or vis_now != bool(shown[n - 1] == i):
                meshcat.SetProperty(f"{viz.PREFIX}/particles/{i}", "visible", vis_now, time_in_recording=t)
    vis.StopRecording()
    vis.PublishRecording()
    path = Path(path)
    path.write_text(meshcat.StaticHtml())
    return path


# ------------------------------------------------------------------------------------- Monte Carlo
def _mc_job(args):
    seam_kind, sensors, seed, particles, overrides, quick = args
    os.environ.setdefault("DRAKE_EST_NO_PROGRESS", "1")
    sc = ScenarioConfig(speed=0.2 if quick else 0.1)      # 200 mm in 1 s (quick) or 2 s
    scn = make_scenario(thesis_seam(seam_kind), sc, seed=seed)
    cfg = filter_config_for(scn, sensors, particles, **overrides)
    res = run_loop(scn, cfg, closed_loop=False, seed=seed)
    m = tracking_metrics(scn, res)
    T = res.X_true.shape[0]
    # estimation errors in the world x, y, z and the tool-frame rotations (Fig. 14.8 axes)
    from drake_est.seam.filter import pose_error
    e = np.array([np.concatenate(pose_error(res.X_est[k], res.X_true[k])) for k in range(T)])
    k0 = int(0.5 / sc.dt)
    return {"rms_xyz_mm": (1e3 * np.sqrt(np.mean(e[k0:, :3] ** 2, axis=0))).tolist(),
            "rms_rot_deg": np.degrees(np.sqrt(np.mean(e[k0:, 3:] ** 2, axis=0))).tolist(),
            "metrics": m}


def run_jobs(jobs, workers: int | None = None, desc: str = "Monte Carlo"):
    """Run ``_mc_job`` over ``jobs`` on ``workers`` processes (default: all local cores), with progress."""
    workers = workers or os.cpu_count() or 1
    if workers <= 1:
        return [_mc_job(j) for j in progress(jobs, desc=desc)]
    with ProcessPoolExecutor(workers) as ex:
        return list(progress(ex.map(_mc_job, jobs), desc=desc, total=len(jobs)))


def sensor_study(n_seeds: int = 20, particles: int = 500, quick: bool = False, workers=None) -> dict:
    """Fig. 14.8: estimation-error distributions for 0, 1, 2 laser stripes on the xy and yz seams (open loop,
    the same filter parameters everywhere), ``n_seeds`` runs each."""
    jobs = [(kind, s, seed, particles, {}, quick) for kind in ("xy", "yz") for s in (0, 1, 2)
            for seed in range(n_seeds)]
    res = run_jobs(jobs, workers, "seam-sensors")
    out = {}
    for (kind, s, seed, *_), r in zip(jobs, res):
        out.setdefault(f"{kind}_{s}", []).append(r)
    return out


SIGNIFICANCE_PARAMS = ("sigma_laser", "d0", "k_d", "sigma_robot", "sigma_p0", "sigma_r0", "init_p")


def significance_study(n_runs: int = 40, seam: str = "xy", sensors: int = 2, particles: int = 300,
                       quick: bool = False, seed: int = 0, workers=None) -> dict:
    """Fig. 14.6: ``n_runs`` runs with every parameter in SIGNIFICANCE_PARAMS multiplied by a log-uniform
    factor in [1/3, 3]; a linear model (least squares) of each error on the log-factors; two-sided p-values
    of the coefficients (t test).  Returns factors, errors, coefficients and log10 p-values."""
    from scipy import stats
    rng = np.random.default_rng([seed, 14, 6])
    base = SeamFilterConfig()
    F = rng.uniform(-1.0, 1.0, (n_runs, len(SIGNIFICANCE_PARAMS))) * math.log(3.0)
    jobs = [(seam, sensors, seed * 1000 + i, particles,
             {p: getattr(base, p) * math.exp(F[i, j]) for j, p in enumerate(SIGNIFICANCE_PARAMS)}, quick)
            for i in range(n_runs)]
    res = run_jobs(jobs, workers, "seam-significance")
    E = np.array([r["rms_xyz_mm"] + r["rms_rot_deg"] for r in res])
    names = ["x [mm]", "y [mm]", "z [mm]", "rot x [deg]", "rot y [deg]", "rot z [deg]"]
    A = np.column_stack([np.ones(n_runs), F])
    coef, *_ = np.linalg.lstsq(A, E, rcond=None)
    dof = n_runs - A.shape[1]
    if dof < 1:
        raise DataError(f"n_runs must exceed {A.shape[1]} for the linear models, got {n_runs}")
    resid = E - A @ coef
    s2 = (resid ** 2).sum(0) / dof
    # coefficient variances diag((A^T A)^-1) = squared row norms of R^-1, by triangular solves on A's QR factor
    from scipy.linalg import solve_triangular
    R = np.linalg.qr(A, mode="r")
    var = (solve_triangular(R, np.eye(R.shape[0])) ** 2).sum(1)
    cond = np.linalg.cond(A)
    t = coef / np.sqrt(np.maximum(np.outer(var, s2), 1e-300))
    p = 2 * stats.t.sf(np.abs(t), dof)
    return {"params": list(SIGNIFICANCE_PARAMS), "errors": names, "coef": coef[1:].tolist(),
            "log10_p": np.log10(np.maximum(p[1:], 1e-300)).tolist(), "n_runs": int(n_runs),
            "design_condition_number": float(cond), "E": E.tolist()}
