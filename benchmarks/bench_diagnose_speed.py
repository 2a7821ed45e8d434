"""Time to diagnose 45,000-sample logs (issue #16 acceptance: one log < 10 s, ten logs < 60 s on 2 cores).

Times exactly ``diagnose(log, robot=..., simulate=False)`` (preparation, search, unexplained verdict; no
forward simulation, no report writing) on logs generated before the clock starts:

* ``generic``: ten 450 s, 100 Hz generic-axis logs of :mod:`drake_est.diagnose.testbench` (seeds 0-9,
  cycling through ripple, Stribeck, time-periodic disturbance, energy drift and none);
* ``irb140``: one 450 s, 100 Hz joint-1 IRB 140 log of :mod:`drake_est.synth` with a motor ripple;
* ``loop`` (``--loop N``, default 10): N 450 s, 100 Hz closed-loop logs of :mod:`drake_est.diagnose.testbench_loop`
  (seeds 0..N-1, cycling through five pairs of effects: these need several rounds, the set-aside check and
  the inertia backfit, the slowest diagnoses of the benchmark families).

Each log is diagnosed twice, on one thread and on ``--threads N`` (default: :func:`~drake_est.diagnose.parallel.
default_threads`, 2 on a 2-core machine; the candidates of a round at once, :mod:`drake_est.diagnose.parallel`), and
the two reports must be identical (report.json without its timing).  Wall time and process CPU time
(``time.process_time``) are both written: one thread's CPU time is the cost, and on a machine shared with other jobs
the meaningful number; the threaded run's wall time is the time to a report on N cores (the issue's "one log on 2
cores").  BLAS runs single-threaded inside ``diagnose``.

``--workers N`` also times each set of logs diagnosed by N worker processes at once (the issue's "ten logs on
2 cores"): the workers are started and have imported drake_est before the clock starts, the logs are sent to
them pickled, and their findings must equal the one-by-one run's.

Usage: python benchmarks/bench_diagnose_speed.py [--n 10] [--loop 10] [--workers 2] [--json OUT.json]
       python benchmarks/bench_diagnose_speed.py --markdown benchmarks/results/diagnose_speed.json  (README table)
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

EFFECTS = ("motor_position_ripple", "stribeck", "time_periodic_disturbance", "energy_dependent_friction", None)
N_SAMPLES = 45000
LOOP_EFFECTS = (("position_dependent_friction", "time_periodic_disturbance"), ("asymmetric_coulomb", "stribeck"),
                ("position_dependent_load", "stribeck"), ("abrupt_change", "motor_position_ripple"),
                ("motor_position_ripple", "stribeck"))


def loop_log(seed: int):
    """The closed-loop log of the benchmark with this seed: 45,000 samples at 100 Hz, the pair of effects
    ``LOOP_EFFECTS[seed % 5]`` at full size. Returns (effects, log)."""
    from drake_est.diagnose.testbench_loop import generate
    effs = LOOP_EFFECTS[seed % len(LOOP_EFFECTS)]
    lg, _ = generate({e: 1.0 for e in effs}, seed=seed, duration=N_SAMPLES / 100.0, sample_rate=100.0)
    return effs, lg


def readme_table(out, source="diagnose_speed.json") -> list:
    """The README table lines for a result of :func:`main` (tests/test_diagnose_speed_readme.py checks them)."""
    return [f"| logs (`{source}`, load average {out['load_average_1min']:.1f} on {out['cpu_count']} cores) | wall | CPU "
            "| slowest log, CPU | goal (issue 16) |",
            "|---|---|---|---|---|",
            f"| {out['n_generic_logs']} generic-axis testbench logs, 45,000 samples each | "
            f"{out['generic_total_wall_s']:.1f} s | {out['generic_total_cpu_s']:.1f} s | {out['generic_max_cpu_s']:.1f} s | "
            "10 logs < 60 s, one < 10 s |",
            f"| one IRB 140 synth log, 45,000 samples | {out['irb140_wall_s']:.1f} s | {out['irb140_cpu_s']:.1f} s | "
            "| < 10 s |"] + ([
            f"| {out['n_loop_logs']} closed-loop logs (two effects each), 45,000 samples each | "
            f"{out['loop_total_wall_s']:.1f} s | {out['loop_total_cpu_s']:.1f} s | {out['loop_max_cpu_s']:.1f} s | "
            "10 logs < 60 s, one < 10 s |"] if out.get("n_loop_logs") else []) + [
            f"| the same {n} {what} logs one by one, each on {out['threads']} threads (the same reports) | "
            f"{out[f'{key}_total_wall_threads_s']:.1f} s | | {out[f'{key}_max_wall_threads_s']:.1f} s wall | "
            "one < 10 s |"
            for n, what, key in ((out.get("n_generic_logs"), "generic-axis", "generic"),
                                 (out.get("n_loop_logs"), "closed-loop", "loop"))
            if out.get("threads", 1) > 1 and n and out.get(f"{key}_total_wall_threads_s") is not None] + [
            f"| the same {n} {what} logs, {out['pool_workers']} worker processes at once | {out[key]:.1f} s | | | "
            "10 logs < 60 s |"
            for n, what, key in ((out.get("n_generic_logs"), "generic-axis", "generic_pool_wall_s"),
                                 (out.get("n_loop_logs"), "closed-loop", "loop_pool_wall_s"))
            if out.get("pool_workers") and n and out.get(key) is not None]


def cpu_model() -> str:
    """The processor's model name (/proc/cpuinfo on Linux, else :func:`platform.processor`): the same code takes
    1.5-3x longer on some 2-core machines than on others, so each kept JSON says which one it ran on."""
    import platform
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def _diagnose_one(item):
    """(name, findings) of one log diagnosed in a worker process (one thread: the workers take a core each)."""
    from drake_est.diagnose import diagnose
    name, lg, robot = item
    return name, diagnose(lg, robot=robot, seed=0, simulate=False, threads=1).effects


def _report_text(rep) -> str:
    """report.json of a diagnosis without its timing, as text (the one-thread and threaded runs must agree)."""
    import json
    d = rep.to_dict()
    d.pop("timing_s", None)
    return json.dumps(d, sort_keys=True, default=str)


def _warm(_):
    import drake_est.diagnose  # noqa: F401  (the import is what is warmed)
    return os.getpid()


def pool_wall_s(items, workers: int, expected: dict) -> float:
    """Wall time [s] of diagnosing ``items`` ((name, log, robot) each) with ``workers`` processes at once, the
    pool started and warmed before the clock; every log's findings must equal ``expected[name]``."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor
    with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn")) as ex:
        list(ex.map(_warm, range(workers)))
        w0 = time.perf_counter()
        got = dict(ex.map(_diagnose_one, items))
        wall = time.perf_counter() - w0
    bad = sorted(k for k in expected if got.get(k) != expected[k])
    if bad:
        raise SystemExit(f"worker findings differ from the one-by-one run for: {', '.join(bad)}")
    return wall


def main(argv=None):
    import sys
    if argv is None:
        argv = sys.argv[1:]
    if len(argv) == 2 and argv[0] == "--markdown":
        import json
        out = json.load(open(argv[1]))
        print("\n".join(readme_table(out, os.path.basename(argv[1]))))
        return out
    from drake_est.data import Log
    from drake_est.diagnose import diagnose
    from drake_est.diagnose.testbench import generate
    from drake_est.jsonutil import dump_json
    from drake_est.synth import synthesize

    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=10)
    ap.add_argument("--loop", type=int, default=10, help="closed-loop logs (0: none)")
    ap.add_argument("--json", default=None)
    ap.add_argument("--workers", type=int, default=0,
                    help="also time each set with this many worker processes at once (0: not)")
    ap.add_argument("--threads", type=int, default=None,
                    help="threads of the second run of each log (default: the diagnosis' default; 1: no second run)")
    args = ap.parse_args(argv)
    from drake_est.diagnose.parallel import check_threads, default_threads
    threads = default_threads() if args.threads is None else check_threads(args.threads, "--threads")
    logs = []
    for s in range(args.n):
        eff = EFFECTS[s % len(EFFECTS)]
        lg, _ = generate({eff: 1.0} if eff else {}, seed=s, duration=N_SAMPLES / 100.0, sample_rate=100.0)
        logs.append((f"testbench {eff or 'none'} seed {s}", lg, "generic"))
    lg, _ = synthesize("motor_position_ripple", seed=45, duration=451.0, sample_rate=100.0)
    irb = Log(t=lg.t[:N_SAMPLES], q=lg.q[:N_SAMPLES], tau=lg.tau[:N_SAMPLES], joints=lg.joints)
    loop = []
    for s in range(args.loop):
        effs, lg = loop_log(s)
        loop.append((f"loop {'+'.join(effs)} seed {s}", lg, "generic"))
    rows = []
    for name, lg, robot in logs + [("synth irb140 ripple", irb, "irb140")] + loop:
        w0, c0 = time.perf_counter(), time.process_time()
        rep = diagnose(lg, robot=robot, seed=0, simulate=False, threads=1)
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        row = {"log": name, "samples": int(lg.n_samples), "robot": robot, "wall_s": wall, "cpu_s": cpu,
               "findings": rep.effects}
        if threads > 1:
            w0, c0 = time.perf_counter(), time.process_time()
            rep_t = diagnose(lg, robot=robot, seed=0, simulate=False, threads=threads)
            row["wall_threads_s"], row["cpu_threads_s"] = time.perf_counter() - w0, time.process_time() - c0
            if _report_text(rep_t) != _report_text(rep):
                raise SystemExit(f"{name}: the report on {threads} threads differs from the one-thread report")
        rows.append(row)
        print(f"{name:45s} {lg.n_samples} samples: wall {wall:5.1f} s, CPU {cpu:5.1f} s"
              + (f"; on {threads} threads wall {row['wall_threads_s']:5.1f} s, CPU {row['cpu_threads_s']:5.1f} s "
                 "(same report)" if threads > 1 else "") + f"  {rep.effects}", flush=True)
    gen = [r for r in rows if r["robot"] == "generic" and r["log"].startswith("testbench")]
    lp = [r for r in rows if r["log"].startswith("loop")]
    out = {"rows": rows, "n_generic_logs": len(gen),
           "generic_total_wall_s": float(sum(r["wall_s"] for r in gen)),
           "generic_total_cpu_s": float(sum(r["cpu_s"] for r in gen)),
           "generic_max_cpu_s": float(max(r["cpu_s"] for r in gen)),
           "irb140_cpu_s": rows[len(gen)]["cpu_s"], "irb140_wall_s": rows[len(gen)]["wall_s"],
           "n_loop_logs": len(lp),
           "loop_total_wall_s": float(sum(r["wall_s"] for r in lp)), "loop_total_cpu_s": float(sum(r["cpu_s"] for r in lp)),
           "loop_max_cpu_s": float(max((r["cpu_s"] for r in lp), default=0.0)),
           "load_average_1min": os.getloadavg()[0], "cpu_count": os.cpu_count(), "cpu_model": cpu_model(),
           "threads": threads}
    if threads > 1:
        # the second run of each log, on `threads` threads: the same reports (checked above), the time to them
        for key, sel in (("generic", gen), ("loop", lp)):
            out[f"{key}_total_wall_threads_s"] = float(sum(r["wall_threads_s"] for r in sel))
            out[f"{key}_max_wall_threads_s"] = float(max((r["wall_threads_s"] for r in sel), default=0.0))
        out["irb140_wall_threads_s"] = rows[len(gen)]["wall_threads_s"]
        out["reports_identical_across_threads"] = True
    if args.workers > 0:
        found = {r["log"]: r["findings"] for r in rows}
        out["pool_workers"] = args.workers
        out["generic_pool_wall_s"] = pool_wall_s(logs, args.workers, {n: found[n] for n, _, _ in logs})
        out["loop_pool_wall_s"] = (pool_wall_s(loop, args.workers, {n: found[n] for n, _, _ in loop})
                                   if loop else None)
        print(f"with {args.workers} worker processes: {len(logs)} generic logs {out['generic_pool_wall_s']:.1f} s wall"
              + (f", {len(loop)} closed-loop logs {out['loop_pool_wall_s']:.1f} s wall" if loop else ""))
    print(f"{len(gen)} generic logs of {N_SAMPLES} samples: total wall {out['generic_total_wall_s']:.1f} s, "
          f"CPU {out['generic_total_cpu_s']:.1f} s (slowest {out['generic_max_cpu_s']:.1f} s CPU); "
          f"IRB 140 log: wall {out['irb140_wall_s']:.1f} s, CPU {out['irb140_cpu_s']:.1f} s; "
          f"load average {out['load_average_1min']:.1f} on {out['cpu_count']} cores ({out['cpu_model']})")
    if lp:
        print(f"{len(lp)} closed-loop logs of {N_SAMPLES} samples: total wall {out['loop_total_wall_s']:.1f} s, "
              f"CPU {out['loop_total_cpu_s']:.1f} s (slowest {out['loop_max_cpu_s']:.1f} s CPU)")
    if threads > 1:
        print(f"on {threads} threads (the same reports): generic logs {out['generic_total_wall_threads_s']:.1f} s "
              f"wall (slowest {out['generic_max_wall_threads_s']:.1f} s), IRB 140 {out['irb140_wall_threads_s']:.1f} s"
              + (f", closed-loop logs {out['loop_total_wall_threads_s']:.1f} s (slowest "
                 f"{out['loop_max_wall_threads_s']:.1f} s); one thread against {threads}, slowest closed-loop log: "
                 f"{out['loop_max_cpu_s'] / max(out['loop_max_wall_threads_s'], 1e-9):.2f}x" if lp else ""))
    if args.json:
        dump_json(out, args.json)
    return out


if __name__ == "__main__":
    main()
