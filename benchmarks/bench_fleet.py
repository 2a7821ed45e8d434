"""Fleet benchmark: acceptance on a synthetic fleet, scaling with local workers, store write rate.

    python benchmarks/bench_fleet.py --robots 50 --days 30 --json fleet_bench.json
    python benchmarks/bench_fleet.py --skip-acceptance --scaling-logs 120 --json scaling.json
    python benchmarks/bench_fleet.py --markdown benchmarks/results/fleet_scaling.json   # README table

1. acceptance: ``synth_fleet`` (R robots x D days), ``run_fleet`` with 2 local workers, trends and
   the truth check (every planted change in the top warnings with robot, joint, cause and date +-2 days;
   no warning on a healthy robot); prints the counts.
2. scaling: the same ``scaling-logs`` generic logs diagnosed into fresh stores with a LocalCluster of
   1 and of 2 worker processes, and with a scheduler and 2 workers started as separate processes
   (``dask scheduler`` / ``dask worker``); ``logs_per_s_wall`` is the number of logs over the wall time
   of the whole ``run_fleet`` call (cluster start-up and shut-down included), ``per_log_cpu_s`` the
   mean diagnosis time per log measured inside the workers.
3. store: results written per second by the client (one transaction per log).
4. paper estimate: workers needed for 1,000 robots' daily logs in one hour from the measured per-log
   cost (per worker) and the store's write rate.
BLAS is single-threaded in every worker.  The machine may be shared: report the load average.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _quiet_single_thread_env():
    """Single-threaded BLAS (inherited by the worker processes) and no progress bars; set before numpy
    or drake_est is imported (this module imports them only inside functions)."""
    for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(k, "1")
    os.environ.setdefault("DRAKE_EST_NO_PROGRESS", "1")


def _timed_run(source, store, **kw):
    from drake_est.fleet.run import run_fleet
    t0 = time.perf_counter()
    c = run_fleet(source, store, show_progress=False, **kw)
    c["wall_s"] = time.perf_counter() - t0
    return c


def _throughput(store):
    """(number of logs, sum of their diagnosis times measured in the workers [s]) of a store."""
    import sqlite3
    con = sqlite3.connect(store)
    n, tot = con.execute("SELECT COUNT(*), SUM(elapsed_s) FROM logs").fetchone()
    con.close()
    return n, tot


def acceptance(work: Path, robots, days, workers, seed):
    from drake_est.fleet import FleetStore, check_against_truth, fleet_trends, synth_fleet
    from drake_est.fleet.report import build_report
    t0 = time.perf_counter()
    s = synth_fleet(work / "fleet", robots=robots, days=days, seed=seed, show_progress=False)
    t_synth = time.perf_counter() - t0
    c = _timed_run(work / "fleet", work / "fleet.db", workers=workers)
    t0 = time.perf_counter()
    with FleetStore(work / "fleet.db", write=False) as st:
        rep = build_report(st, work / "report")
        chk = check_against_truth(fleet_trends(st), json.loads(Path(s["truth"]).read_text()))
    t_rep = time.perf_counter() - t0
    # a second run must skip everything
    c2 = _timed_run(work / "fleet", work / "fleet.db", workers=workers)
    chk.pop("details", None)
    return {"robots": robots, "days": days, "logs": s["logs"], "synth_s": t_synth, "diagnose": c,
            "report_s": t_rep, "warnings": len(rep["warnings"]), "check": chk,
            "rerun_skipped": c2["skipped"], "rerun_diagnosed": c2["ok"] + c2["failed"]}


def scaling(work: Path, n_logs, seed):
    from drake_est.fleet import synth_fleet
    days = 10
    robots = max(3, -(-n_logs // days))
    synth_fleet(work / "sfleet", robots=robots, days=days, seed=seed + 1, n_irb140=0, show_progress=False)
    out = {"logs": robots * days}
    for w in (1, 2):
        c = _timed_run(work / "sfleet", work / f"s{w}.db", workers=w)
        n, tot = _throughput(work / f"s{w}.db")
        out[f"local_{w}_workers"] = {"wall_s": c["wall_s"], "logs_per_s_wall": n / c["wall_s"],
                                     "per_log_cpu_s": tot / n}
    out["speedup_2_vs_1_wall"] = out["local_1_workers"]["wall_s"] / out["local_2_workers"]["wall_s"]
    # scheduler and workers in separate processes
    dask = shutil.which("dask") or str(Path(sys.executable).with_name("dask"))
    sched_file = work / "scheduler.json"
    procs = [subprocess.Popen([dask, "scheduler", "--scheduler-file", str(sched_file), "--dashboard-address", ":0",
                               "--port", "0"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        for _ in range(200):
            if sched_file.exists() and sched_file.stat().st_size > 0:
                break
            time.sleep(0.1)
        addr = json.loads(sched_file.read_text())["address"]
        for k in range(2):
            procs.append(subprocess.Popen([dask, "worker", addr, "--nthreads", "1", "--nworkers", "1",
                                           "--name", f"w{k}", "--dashboard-address", ":0"],
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from distributed import Client
        with Client(addr, timeout="30s") as cl:
            cl.wait_for_workers(2, timeout=60)
            c = _timed_run(work / "sfleet", work / "sx.db", client=cl)
        n, tot = _throughput(work / "sx.db")
        out["separate_scheduler_2_workers"] = {"wall_s": c["wall_s"], "logs_per_s_wall": n / c["wall_s"],
                                               "per_log_cpu_s": tot / n}
    finally:
        for p in procs[::-1]:
            p.terminate()
        for p in procs[::-1]:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
    return out


def store_rate(work: Path, n=2000):
    from drake_est.fleet.store import FleetStore
    res = {"entry": {"robot_id": "r", "time": "", "path": "p", "robot_model": "generic", "joints": "1,2"},
           "file_sha256": "", "settings_hash": "s", "settings": {"seed": 0}, "software_version": "x", "status": "ok",
           "findings": [{"effect": "motor_position_ripple", "joint": 1, "heldout_gain": 1.5, "p_value": 1e-9,
                         "parameters": {"rms_amplitude": 1.0}, "evidence": {"F": 10.0}}],
           "parameters": [{"joint": j, "name": nm, "value": 1.0} for j in (1, 2)
                          for nm in ("coulomb_nm", "viscous_nms", "ripple_amplitude_nm")]}
    with FleetStore(work / "rate.db") as st:
        t0 = time.perf_counter()
        for k in range(n):
            res["entry"]["time"] = f"t{k}"
            res["file_sha256"] = f"{k}"
            st.record(res)
        dt = time.perf_counter() - t0
    return {"records": n, "records_per_s": n / dt}


def cluster_size(per_log_s: float, logs_per_hour: float, store_records_per_s: float) -> dict:
    """Paper estimate: worker processes (one core each) and store time for ``logs_per_hour`` logs in one
    hour, from the measured per-log worker time and the store's write rate (one writer)."""
    import math
    work = logs_per_hour * per_log_s
    return {"logs_per_hour": logs_per_hour, "worker_s": work, "workers": work / 3600.0,
            "workers_rounded_up": max(1, math.ceil(work / 3600.0)),
            "store_s": logs_per_hour / store_records_per_s}


def markdown(res: dict) -> str:
    """The README's scaling table and cluster-size estimate, generated from a ``--json`` result."""
    sc, sr = res["scaling"], res["store"]
    one, two, sep = sc["local_1_workers"], sc["local_2_workers"], sc["separate_scheduler_2_workers"]
    base = one["logs_per_s_wall"]
    rows = [("LocalCluster, 1 worker process", one), ("LocalCluster, 2 worker processes", two),
            ("`dask scheduler` + 2 × `dask worker` (separate processes)", sep)]
    lines = ["| cluster | wall time [s] | logs/s (wall) | vs 1 worker | worker time per log [s] |",
             "|---|---|---|---|---|"]
    for name, r in rows:
        lines.append(f"| {name} | {r['wall_s']:.1f} | {r['logs_per_s_wall']:.2f} | "
                     f"{r['logs_per_s_wall'] / base:.2f}× | {r['per_log_cpu_s']:.3f} |")
    n = sc["logs"]
    fixed1 = one["wall_s"] - n * one["per_log_cpu_s"]            # start-up, shut-down, client, scheduler
    fixed2 = two["wall_s"] - n * two["per_log_cpu_s"] / 2
    ideal = one["wall_s"] / (n * one["per_log_cpu_s"] / 2 + fixed2)
    per_log = max(one["per_log_cpu_s"], two["per_log_cpu_s"])   # the slower, all-cores-busy figure
    daily = cluster_size(per_log, 1000, sr["records_per_s"])
    dense = cluster_size(per_log, 1000 * 180, sr["records_per_s"])
    lines += ["",
              f"{sc['logs']} logs; load average {res['load_avg_start'][0]:.2f} at the start, "
              f"{res['load_avg_end'][0]:.2f} at the end (the benchmark's own load); {res['cpu_count']} cores. "
              f"The client writes {sr['records_per_s']:,.0f} results/s into the store "
              f"({sr['records']:,} results, one transaction each).",
              "",
              f"Where the {two['logs_per_s_wall'] / base:.2f}× (not 2×) goes: the wall time not spent "
              f"diagnosing (wall − logs × worker time per log / workers) is {fixed1:.1f} s with 1 worker and "
              f"{fixed2:.1f} s with 2 (cluster start-up and shut-down, task transfer, the client's store "
              f"writes), and the worker time per log grows from {one['per_log_cpu_s']:.3f} s to "
              f"{two['per_log_cpu_s']:.3f} s (+{100 * (two['per_log_cpu_s'] / one['per_log_cpu_s'] - 1):.0f} %) "
              f"when both cores compute (shared caches and memory bandwidth; the client, scheduler and nanny "
              f"processes run on the same two cores). With the 1-worker time per log, 2 workers would reach "
              f"{ideal:.2f}×: the per-log slowdown costs most of the gap, per-task overhead and serialization "
              f"(within those {fixed2:.1f} s, about {1000 * fixed2 / n:.0f} ms per log at most) little.",
              "",
              f"**Cluster size for 1,000 robots' daily logs in one hour (paper estimate).** Per log "
              f"{per_log:.2f} s of worker time (the 2-worker figure, all cores busy). One 20 s log per robot "
              f"and day: 1,000 logs = {daily['worker_s']:,.0f} worker-seconds = {daily['workers']:.2f} of one "
              f"worker process's hour, so **{daily['workers_rounded_up']} worker process (one core)** does it, "
              f"and the store needs {daily['store_s']:.2f} s of the hour. One hour of logging per robot and day, "
              f"cut into 20 s logs (180,000 logs): {dense['worker_s']:,.0f} worker-seconds = "
              f"**{dense['workers_rounded_up']} worker processes** (e.g. {-(-dense['workers_rounded_up'] // 16)} "
              f"machines of 16 cores), and the single SQLite writer needs {dense['store_s']:.0f} s of the hour, "
              f"so it is not the limit yet."]
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, default=50)
    ap.add_argument("--days", type=int, default=30)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--scaling-logs", type=int, default=120)
    ap.add_argument("--skip-acceptance", action="store_true")
    ap.add_argument("--skip-scaling", action="store_true")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--keep", default=None, help="keep the work folder here")
    ap.add_argument("--json", default=None)
    ap.add_argument("--markdown", default=None, metavar="JSON",
                    help="print the README scaling table from a --json result of an earlier run and exit")
    a = ap.parse_args(argv)
    _quiet_single_thread_env()
    if a.markdown:
        text = markdown(json.loads(Path(a.markdown).read_text()))
        print(text, end="")
        return text
    work = Path(a.keep) if a.keep else Path(tempfile.mkdtemp(prefix="bench_fleet_"))
    work.mkdir(parents=True, exist_ok=True)
    out = {"cpu_count": os.cpu_count(), "load_avg_start": os.getloadavg()}
    try:
        if not a.skip_acceptance:
            out["acceptance"] = acc = acceptance(work, a.robots, a.days, a.workers, a.seed)
            ch = acc["check"]
            print(f"acceptance: {acc['logs']} logs ({a.robots} robots x {a.days} days) synthesized in "
                  f"{acc['synth_s']:.0f} s, diagnosed in {acc['diagnose']['wall_s']:.0f} s "
                  f"({acc['diagnose']['ok']} ok, {acc['diagnose']['failed']} failed); planted changes found "
                  f"{ch['found']}/{ch['planted']}; warnings {ch['warnings']}; warnings on healthy robots "
                  f"{ch['healthy_robot_warnings']}/{ch['healthy_robots']}; other warnings "
                  f"{ch['extra_warnings_on_planted_robots']}; rerun skipped {acc['rerun_skipped']}")
        if not a.skip_scaling:
            out["scaling"] = sc = scaling(work, a.scaling_logs, a.seed)
            out["store"] = sr = store_rate(work)
            per_log = sc["local_1_workers"]["per_log_cpu_s"]
            need = 1000 * per_log / 3600.0
            out["paper_estimate"] = {
                "per_log_s_one_worker": per_log, "logs_per_hour_needed": 1000,
                "workers_for_1000_logs_per_hour": need, "store_records_per_s": sr["records_per_s"],
                "store_time_for_1000_logs_s": 1000 / sr["records_per_s"]}
            print(f"scaling ({sc['logs']} logs): 1 worker {sc['local_1_workers']['logs_per_s_wall']:.2f} logs/s, "
                  f"2 workers {sc['local_2_workers']['logs_per_s_wall']:.2f} logs/s "
                  f"(x{sc['speedup_2_vs_1_wall']:.2f}), separate scheduler + 2 workers "
                  f"{sc['separate_scheduler_2_workers']['logs_per_s_wall']:.2f} logs/s; store "
                  f"{sr['records_per_s']:.0f} results/s; 1,000 daily logs in one hour need "
                  f"{need:.2f} workers at {per_log:.2f} s per log")
        out["load_avg_end"] = os.getloadavg()
    finally:
        if not a.keep:
            shutil.rmtree(work, ignore_errors=True)
    if a.json:
        from drake_est.jsonutil import dump_json
        dump_json(out, a.json)
    return out


if __name__ == "__main__":
    main()
