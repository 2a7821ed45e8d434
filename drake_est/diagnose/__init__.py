"""Model-discrepancy diagnosis: what the simulation gets wrong, its cause, the extended model
and the held-out gain (thesis Ch. 9-10 and Ch. 7 done automatically).

Example::

    from drake_est.data import load_log
    from drake_est.diagnose import diagnose

    rep = diagnose(load_log("log.csv"), robot="irb140", seed=0)
    print(rep.summary())
    for f in rep.findings:                      # most important first; [] when nothing is found
        print(f["effect"], f["joint"], f["evidence"]["p_value"], f["gain"]["rmse_ratio"])
    rep.write("diagnosis")                      # report.json, report.md, PNG plots

``robot``: ``"generic"`` (default: every logged joint an independent axis, inertia identified with
the nominal friction), ``"irb140"`` (Drake ``MultibodyPlant`` of the IRB 140) or a URDF path.
Effect vocabulary: :data:`VOCABULARY`.  The procedure is in :mod:`drake_est.diagnose.core`.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from drake_est.diagnose.core import ALPHA, MIN_GAIN, run_diagnosis
from drake_est.diagnose.detectors import VOCABULARY
from drake_est.diagnose.report import DiagnosisReport

__all__ = ["diagnose", "diagnose_logs", "concatenate_logs", "DiagnosisReport", "VOCABULARY", "run_demo", "friction_system", "friction_params"]


def diagnose(log, robot: str | None = "generic", joints=None, seed: int = 0, simulate: bool = True,
             alpha: float = ALPHA, min_gain: float = MIN_GAIN, source: str | None = None,
             threads: int | None = None) -> DiagnosisReport:
    """Diagnose a measured log (a :class:`~drake_est.data.Log` or a path to a CSV/NPZ log).

    Parameters
    ----------
    robot : "generic" | "irb140" | path to a URDF.
    joints : 1-based joints to diagnose (default: all logged joints; held joints are skipped).
    seed : seeds every random choice.
    simulate : also run the windowed forward simulations (simulation error, Sec. 3.1).
    alpha, min_gain : significance level of the held-out F-test and the minimum relative held-out
        RMSE reduction for a finding.
    threads : threads for the candidates of each round (default: ``DRAKE_EST_DIAG_THREADS``, else up to 4, at most
        the cores; :mod:`drake_est.diagnose.parallel`).  The findings and every number do not depend on it.
    """
    from drake_est.data import Log, load_log
    if not isinstance(log, Log):
        source = source or str(log)
        log = load_log(log)
    robot = "generic" if robot is None else str(robot)
    from drake_est.threads import single_thread_blas
    # the least-squares problems are small (thousands x tens): one BLAS thread is fastest, and much faster
    # than contended threads on a loaded machine (measured 0.53 s vs 0.025 s per 4291 x 70 lstsq, load 10)
    with single_thread_blas():
        res = run_diagnosis(log, robot=robot, joints=joints, seed=seed, alpha=alpha, min_gain=min_gain,
                            threads=threads)
    rep = DiagnosisReport(res, source=source or str(log.meta.get("file", "<log>")), robot=robot)
    if simulate:
        import time
        from drake_est.diagnose.simulate import simulation_error
        t0 = time.perf_counter()
        rep.simulation = simulation_error(res)
        res.timing["simulation_s"] = time.perf_counter() - t0
    return rep


def concatenate_logs(logs, gap_s: float = 1.0):
    """One :class:`~drake_est.data.Log` of several logs of one machine, one after the other in time (a gap of
    ``gap_s`` between them), derivatives computed per log (:data:`~drake_est.diagnose.nominal.DERIV_WINDOW_S`)
    and a channel ``log_index`` (0, 1, ...).  :func:`diagnose` on it fits one model across the logs and holds
    out whole logs (odd-numbered logs validate)."""
    from drake_est.data import Log
    from drake_est.diagnose.multilog import check_logs
    from drake_est.diagnose.nominal import DERIV_WINDOW_S
    check_logs(logs)      # same joints, not empty, torque logged, no recording twice (one line naming the file)
    joints = list(logs[0].joints)
    parts = []
    t_end = None
    for k, lg in enumerate(logs):
        if lg.dq is None or lg.ddq is None or "derivatives" in lg.meta:
            lg = Log(t=lg.t, q=lg.q, tau=lg.tau, joints=joints,
                     meta={"file": lg.meta.get("file", f"log{k + 1}")}).with_derivatives(window_s=DERIV_WINDOW_S)
        t = lg.t - lg.t[0] + (0.0 if t_end is None else t_end + gap_s)
        t_end = float(t[-1])
        parts.append((t, lg, np.full(t.size, float(k))))
    cat = lambda f: np.concatenate([f(p) for p in parts])  # noqa: E731
    return Log(t=cat(lambda p: p[0]), q=np.vstack([p[1].q for p in parts]), dq=np.vstack([p[1].dq for p in parts]),
               ddq=np.vstack([p[1].ddq for p in parts]), tau=np.vstack([p[1].tau for p in parts]), joints=joints,
               channels={"log_index": cat(lambda p: p[2])},
               meta={"file": " + ".join(str(p[1].meta.get("file", f"log{k + 1}")) for k, p in enumerate(parts)),
                     "n_logs": len(parts), "tau_unit": logs[0].meta.get("tau_unit")})


def diagnose_logs(logs, robot: str | None = "generic", **kw) -> DiagnosisReport:
    """Diagnose several logs of one machine at once (:func:`concatenate_logs`): one model (common friction
    and effects) fitted on the even-numbered logs, judged on the odd-numbered ones (whole logs held out)."""
    from drake_est.data import Log, load_log
    logs = [lg if isinstance(lg, Log) else load_log(lg) for lg in logs]
    return diagnose(concatenate_logs(logs), robot=robot, **kw)


def friction_system(report: DiagnosisReport, sign_eps: float = 0.0):
    """The final (extended) friction model as the same
    :class:`~drake_est.systems.friction.FrictionModel` ``LeafSystem`` that ``fit-friction`` models use
    (ports ``joint_positions`` [rad], ``joint_velocities`` [rad/s] -> ``friction_torques`` [N m]), in
    the robot's coordinates (generic axes: the log's joints in order).  Its models are
    :func:`~drake_est.diagnose.simulate.diagnosed_friction_models`; save them with
    :func:`friction_params` and load them back with ``FrictionModel.from_json``.  A diagnosed energy
    effect keeps its unit-gain energy as discrete state in the Context (starting at 0)."""
    from drake_est.diagnose.simulate import diagnosed_friction_models
    from drake_est.systems.friction import FrictionModel
    res = report.result
    prep = res.prep
    if prep.robot is not None:
        cols, n = dict(prep.robot_cols), prep.robot.n
    else:
        cols, n = {j: c for c, j in enumerate(prep.log.joints)}, len(prep.log.joints)
    models = diagnosed_friction_models(res, res.final_model, res.final_fit, cols)
    return FrictionModel([models.get(index) for index in range(n)], n_joints=n, sign_eps=sign_eps)


def friction_params(report: DiagnosisReport) -> dict:
    """The diagnosed friction model as a ``params.json`` dict (the ``fit-friction`` format:
    ``{"models": {"<1-based joint>": model}, "n_joints": n}``), loadable by ``FrictionModel.from_json``."""
    return friction_system(report).to_params()


def run_demo(out_dir, seed: int = 0, duration: float = 120.0, effect: str = "motor_position_ripple") -> DiagnosisReport:
    """``drake-est demo``: simulate a default IRB 140 joint-1 log with a hidden effect (the effect is
    not told to the diagnosis), save it as CSV, diagnose it and write the report into ``out_dir``."""
    from drake_est.data import save_log
    from drake_est.synth import synthesize
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    log, truth = synthesize(effect, seed=seed, duration=duration)
    path = save_log(log, out / "demo_log.csv")
    rep = diagnose(path, robot="irb140", seed=seed)
    rep.write(out)
    return rep
