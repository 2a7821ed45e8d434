"""What the seventieth round's pair rescue (``core.PAIR_RESCUE``) costs: the CPU time of the speed benchmark's ten
closed-loop logs (``bench_diagnose_speed.loop_log``, 45,000 samples at 100 Hz, two effects each) diagnosed with the rule
off and on, alternating log by log in one run on one thread, and whether the findings are the same.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_pair_rescue_cost.py --json benchmarks/results/diagnose_pair_rescue_cost.json
"""
import argparse
import json
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_diagnose_speed as S  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--loop", type=int, default=10, help="closed-loop logs (seeds 0..N-1)")
    ap.add_argument("--json", default=None, help="write the figures here")
    a = ap.parse_args(argv)
    if a.loop < 1:
        raise SystemExit("--loop: expected at least 1 log")
    from drake_est.diagnose import core, diagnose
    was = core.PAIR_RESCUE
    cpu = {"off": [], "on": []}
    findings = {"off": [], "on": []}
    try:
        for seed in range(a.loop):
            _, lg = S.loop_log(seed)
            for key, on in (("off", False), ("on", True)):
                core.PAIR_RESCUE = on
                t0 = time.process_time()
                d = diagnose(lg, robot="generic", seed=0, simulate=False, threads=1).to_dict()
                cpu[key].append(time.process_time() - t0)
                findings[key].append([f["effect"] for f in d["findings"]])
            print(f"log {seed}: {cpu['off'][-1]:.1f} s off, {cpu['on'][-1]:.1f} s on, {findings['on'][-1]}", flush=True)
    finally:
        core.PAIR_RESCUE = was
    out = {"logs": a.loop, "cpu_s_off": sum(cpu["off"]), "cpu_s_on": sum(cpu["on"]),
           "ratio_on_to_off": sum(cpu["on"]) / sum(cpu["off"]), "slowest_cpu_s_off": max(cpu["off"]),
           "slowest_cpu_s_on": max(cpu["on"]), "same_findings": findings["off"] == findings["on"],
           "processor": S.cpu_model(), "per_log_cpu_s": cpu}
    print(f"total CPU {out['cpu_s_off']:.1f} s off, {out['cpu_s_on']:.1f} s on (ratio {out['ratio_on_to_off']:.3f}); "
          f"same findings: {out['same_findings']}")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1)


if __name__ == "__main__":
    main()
