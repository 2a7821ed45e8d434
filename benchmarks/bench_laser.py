"""Benchmark: laser-scanner calibration (thesis Sec. 13.2) vs a generic scipy nonlinear least squares.

100 realizations, 10 poses on each of 3 planes, 64 points per scan, noise 0.5 mm, initial error
U(+-200 mm) and U(+-30 deg) roll/pitch/yaw, 30 iterations.  Prints success rates, errors and times.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_laser.py [--n 100] [--seed 0]

``--cells N``: automatic plane assignment in N random robot cells (3-6 planes, up to two within 15 deg
of parallel to another plane at offsets >= 50 mm apart, each pose sees one finite plane patch, 8 poses
per plane, 32 rays, 0.5 mm noise), start 100 mm / 20 deg off the truth.  Each cell is solved with the
true labels and without; the automatic answer counts as right when within 1 mm / 0.2 deg of the truth,
as refused when it raises IdentifiabilityError, and as silently wrong otherwise.  Prints the counts
(and writes them as JSON with ``--json``).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_laser.py --cells 100 --json laser_cells.json
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
    ap.add_argument("--cells", type=int, default=0, help="run the automatic-assignment benchmark on N cells")
    ap.add_argument("--json", default=None, help="write the --cells counts to this JSON file")
    ap.add_argument("--first", type=int, default=0, help="--cells: first cell index (to split a run over processes)")
    a = ap.parse_args(argv)
    if a.cells:
        return cells(a.cells, a.seed, a.json, a.first)
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


def make_cell(seed):
    """One random cell: planes, scans, and an initial guess 100 mm / 20 deg off (both exactly)."""
    import numpy as np

    from drake_est.calibration import make_pose, random_laser_problem
    from drake_est.calibration.simulate import cell_planes
    from drake_est.calibration.so3 import exp_so3

    rng = np.random.default_rng(seed)
    K = int(rng.integers(3, 7))
    n_par = min(int(rng.integers(0, 3)), K - 3)
    planes = cell_planes(rng, K, n_par, max_angle_deg=15.0, min_offset=0.05)
    pr = random_laser_problem(rng, planes=planes, n_rays=32, tilt_deg=45, occlusion=False, poses_per_plane=8)
    u = rng.standard_normal(3)
    v = rng.standard_normal(3)
    T0 = make_pose(pr.T_true[:3, :3] @ exp_so3(np.radians(20.0) * u / np.linalg.norm(u)),
                   pr.T_true[:3, 3] + 0.1 * v / np.linalg.norm(v))
    return pr, T0, K, n_par


def cells(n, seed=0, json_path=None, first=0):
    import time

    import numpy as np

    from drake_est.calibration import calibrate_laser, transform_error
    from drake_est.errors import DrakeEstError, IdentifiabilityError
    from drake_est.jsonutil import dump_json

    def ok(T, T_true):
        et, er = transform_error(T, T_true)
        return et < 1e-3 and np.degrees(er) < 0.2

    c = {"cells": n, "first_cell": first, "labelled_right": 0, "auto_right": 0, "auto_refused": 0, "auto_silently_wrong": 0,
         "auto_right_where_labelled_right": 0, "auto_refused_where_labelled_right": 0, "auto_wrong_where_labelled_right": 0,
         "cells_with_near_parallel_planes": 0, "auto_right_with_near_parallel_planes": 0}
    t_auto = 0.0
    for i in range(first, first + n):
        pr, T0, K, n_par = make_cell(seed * 100003 + i)
        c["cells_with_near_parallel_planes"] += n_par > 0
        try:
            lab_ok = ok(calibrate_laser(pr.poses, pr.points, pr.pose_index, labels=pr.labels, T0=T0).T, pr.T_true)
        except DrakeEstError:
            lab_ok = False
        t = time.perf_counter()
        try:
            auto = calibrate_laser(pr.poses, pr.points, pr.pose_index, labels=None, T0=T0)
            state = "right" if ok(auto.T, pr.T_true) else "wrong"
        except IdentifiabilityError as e:
            state, msg = "refused", str(e)
        t_auto += time.perf_counter() - t
        c["labelled_right"] += lab_ok
        c["auto_right"] += state == "right"
        c["auto_refused"] += state == "refused"
        c["auto_silently_wrong"] += state == "wrong"
        c["auto_right_where_labelled_right"] += lab_ok and state == "right"
        c["auto_refused_where_labelled_right"] += lab_ok and state == "refused"
        c["auto_wrong_where_labelled_right"] += lab_ok and state == "wrong"
        c["auto_right_with_near_parallel_planes"] += n_par > 0 and state == "right"
        print(f"cell {i:3d}: {K} planes, {n_par} near-parallel, labelled {'right' if lab_ok else 'WRONG'}, "
              f"automatic {state}" + (f" ({msg[:90]})" if state == "refused" else ""), flush=True)
    c["seconds_per_automatic_cell"] = t_auto / max(n, 1)
    for k, v in c.items():
        print(f"{k:40s} {v}")
    if json_path:
        dump_json(c, json_path)
    return c


if __name__ == "__main__":
    main(sys.argv[1:])
