"""Benchmark: laser-scanner calibration (thesis Sec. 13.2) vs a generic scipy nonlinear least squares.

100 realizations, 10 poses on each of 3 planes, 64 points per scan, noise 0.5 mm, initial error
U(+-200 mm) and U(+-30 deg) roll/pitch/yaw, 30 iterations.  Prints success rates, errors and times.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_laser.py [--n 100] [--seed 0]
"""
import argparse
import json
import os
import sys

os.environ.setdefault("DRAKE_EST_NO_PROGRESS", "1")


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=None, help="folder for figures/JSON (default: a temporary folder)")
    a = ap.parse_args(argv)
    import tempfile

    from drake_est.reproduce.calibration import laser_calibration

    out = a.out or tempfile.mkdtemp(prefix="bench_laser_")
    r = laser_calibration(out, n_real=a.n, seed=a.seed)
    print(f"{'method':22s} {'success':>8s} {'med trans mm':>13s} {'max trans mm':>13s} {'med rot deg':>12s} "
          f"{'max rot deg':>12s} {'s/realization':>14s}")
    for k, v in r["methods"].items():
        print(f"{k:22s} {v['success_rate']:8.2f} {v['median_translation_mm']:13.4f} {v['max_translation_mm']:13.4f} "
              f"{v['median_rotation_deg']:12.4f} {v['max_rotation_deg']:12.4f} "
              f"{v['seconds_total'] / r['n_realizations']:14.4f}")
    print("success:", r["success_definition"])
    print("iterations to success:", json.dumps(r["iterations_to_success"]))
    return r


if __name__ == "__main__":
    main(sys.argv[1:])
