"""Sweep: every bad-input case of docs/readme/hardening.md plus damaged numeric options of each command,
each run as a fresh `drake-est` process; counts tracebacks, hangs, multi-line errors, exit 0 on garbage
and NaN/Infinity in written files (issue 19's acceptance measure; target: all zero).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/sweep_bad_inputs.py [--timeout 120] [--json out.json]
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))


def option_cases(tmp):
    """(name, argv) with damaged numeric options; inputs otherwise valid."""
    import numpy as np

    from test_hardening import _csv, _ft_npz, _laser_npz, _log_cols

    log = str(_csv(tmp / "ok.csv", _log_cols()))
    ft = str(_ft_npz(tmp))
    laser = str(_laser_npz(tmp))
    out = ["--out", str(tmp / "out")]
    cases = []
    for bad in ("nan", "inf", "-inf", "-1", "0", "1e300"):
        nz = bad if bad != "0" else "-0.001"      # noise 0 and v-min 0 are valid settings
        cases += [(f"synth --duration {bad}", ["synth", "--out", str(tmp / "s.csv"), "--duration", bad]),
                  (f"synth --rate {bad}", ["synth", "--out", str(tmp / "s.csv"), "--rate", bad]),
                  (f"synth --noise {nz}", ["synth", "--out", str(tmp / "s.csv"), "--noise", nz]),
                  (f"spectrum --gear-ratio {bad}", ["spectrum", log, "--signal", "tau1", "--position", "q1",
                                                   "--gear-ratio", bad] + out),
                  (f"spectrum --f-max {bad}", ["spectrum", log, "--signal", "tau1", "--position", "q1",
                                              "--f-max", bad] + out),
                  (f"fit-friction --holdout {bad}", ["fit-friction", log, "--holdout", bad] + out),
                  (f"fit-friction --v-min {nz}", ["fit-friction", log, "--v-min", nz] + out),
                  (f"calibrate ft --mass {bad}", ["calibrate", "ft", ft, "--method", "cayley", "--mass", bad] + out),
                  (f"calibrate laser --length-scale {bad}", ["calibrate", "laser", laser, "--length-scale", bad] + out),
                  (f"calibrate laser --assign-threshold {bad}", ["calibrate", "laser", laser, "--assign-threshold",
                                                                bad] + out)]
    cases += [("synth --seed -1", ["synth", "--out", str(tmp / "s.csv"), "--seed", "-1"]),
              ("calibrate laser --T0 nan", ["calibrate", "laser", laser, "--T0", "nan 0 0 0 0 0"] + out),
              ("calibrate laser --iters 0", ["calibrate", "laser", laser, "--iters", "0"] + out)]
    del np
    return cases


def new_command_cases(tmp, timeout):
    """(name, argv) for the commands of this round: track, fleet diagnose/report, synth-fleet, reproduce,
    diagnose with several logs; damaged numeric options, missing files, corrupt inputs."""
    import numpy as np

    from test_hardening import _csv, _log_cols

    ok = str(_csv(tmp / "ok.csv", _log_cols()))
    c = _log_cols()
    two = str(_csv(tmp / "two.csv", {"t": c["t"], "q2": c["q1"], "tau2": c["tau1"]}))
    deg = str(_csv(tmp / "deg.csv", {**c, "q1": np.degrees(c["q1"]) * 4}))
    garbage = tmp / "garbage.csv"
    garbage.write_bytes(bytes(range(256)) * 8)
    seam_nan = tmp / "seam_nan.csv"
    seam_nan.write_text("x,y,z\n0,0,0\nnan,0.1,0\n0.2,0.2,0\n0.3,0.3,0\n")
    seam_two = tmp / "seam_two.csv"
    seam_two.write_text("x,y,z\n0,0,0\n0.1,0,0\n")
    # a tiny fleet (one robot, two days) and its store, written by the commands themselves
    fleet = tmp / "fleet"
    (fleet / "robot_a").mkdir(parents=True)
    for day in ("2026-05-01", "2026-05-02"):
        _csv(fleet / "robot_a" / f"{day}.csv", _log_cols())
    store = tmp / "fleet.sqlite"
    run(["fleet", "diagnose", str(fleet), "--store", str(store), "--workers", "1"], timeout)
    empty = tmp / "empty_dir"
    empty.mkdir()
    man_bad = tmp / "manifest_bad.csv"
    man_bad.write_text("robot,when\nx,y\n")
    truth_bad = tmp / "truth_bad.json"
    truth_bad.write_text("{not json")
    out = ["--out", str(tmp / "out")]
    track = ["track", "--seam", "xy", "--out", str(tmp / "track")]
    sf = ["synth-fleet", "--out", str(tmp / "sf"), "--robots", "3", "--days", "8", "--duration", "5"]
    fd = ["fleet", "diagnose", str(fleet), "--store", str(tmp / "s2.sqlite"), "--workers", "1"]
    cases = [
        ("track --seam bogus", ["track", "--seam", "bogus", "--out", str(tmp / "track")]),
        ("track --seam missing.csv", ["track", "--seam", str(tmp / "missing.csv"), "--out", str(tmp / "track")]),
        ("track --seam garbage.csv", ["track", "--seam", str(garbage), "--out", str(tmp / "track")]),
        ("track --seam with NaN", ["track", "--seam", str(seam_nan), "--out", str(tmp / "track")]),
        ("track --seam of 2 points", ["track", "--seam", str(seam_two), "--out", str(tmp / "track")]),
        ("track --seed -1", track + ["--seed", "-1"]),
        ("track --out /dev/null", ["track", "--seam", "xy", "--out", "/dev/null"]),
        ("track --particles 1000000000", track + ["--particles", "1000000000"]),
    ]
    for bad in ("0", "1", "-5"):
        cases.append((f"track --particles {bad}", track + ["--particles", bad]))
    for bad in ("nan", "inf", "-inf", "-1", "0", "1e300"):
        cases.append((f"track --speed {bad}", track + ["--speed", bad]))
        cases.append((f"track --realtime-rate {bad}", track + ["--realtime-rate", bad]))
        cases.append((f"synth-fleet --duration {bad}", sf[:-1] + [bad]))
    cases.append(("track --realtime-rate 1e-300", track + ["--realtime-rate", "1e-300"]))
    for bad in ("0", "-1", "2", "100000000"):
        cases.append((f"synth-fleet --robots {bad}", sf + ["--robots", bad]))
    for bad in ("0", "-1", "7", "100000000"):
        cases.append((f"synth-fleet --days {bad}", sf + ["--days", bad]))
    for bad in ("-1", "100"):
        cases.append((f"synth-fleet --irb140 {bad}", sf + ["--irb140", bad]))
    cases += [
        ("synth-fleet --seed -1", sf + ["--seed", "-1"]),
        ("synth-fleet --out /dev/null", ["synth-fleet", "--out", "/dev/null", "--robots", "3", "--days", "8"]),
        ("fleet diagnose missing source", ["fleet", "diagnose", str(tmp / "nope"), "--store", str(tmp / "s3.sqlite")]),
        ("fleet diagnose empty folder", ["fleet", "diagnose", str(empty), "--store", str(tmp / "s3.sqlite")]),
        ("fleet diagnose manifest without columns", ["fleet", "diagnose", str(man_bad), "--store",
                                                     str(tmp / "s3.sqlite")]),
        ("fleet diagnose garbage manifest", ["fleet", "diagnose", str(garbage), "--store", str(tmp / "s3.sqlite")]),
        ("fleet diagnose --workers 0", fd + ["--workers", "0"]),
        ("fleet diagnose --workers -1", fd + ["--workers", "-1"]),
        ("fleet diagnose --limit -1", fd + ["--limit", "-1"]),
        ("fleet diagnose --seed -1", fd + ["--seed", "-1"]),
        ("fleet diagnose --store in a file", ["fleet", "diagnose", str(fleet), "--store", "/dev/null/x.sqlite"]),
        ("fleet diagnose --store is a folder", ["fleet", "diagnose", str(fleet), "--store", str(empty)]),
        ("fleet diagnose --store garbage", ["fleet", "diagnose", str(fleet), "--store", str(garbage)]),
        ("fleet diagnose --scheduler bogus", fd + ["--scheduler", "bogus-address"]),
        ("fleet diagnose --scheduler refused", fd + ["--scheduler", "tcp://127.0.0.1:9"]),
        ("fleet report missing store", ["fleet", "report", "--store", str(tmp / "nope.sqlite")] + out),
        ("fleet report garbage store", ["fleet", "report", "--store", str(garbage)] + out),
        ("fleet report --out /dev/null", ["fleet", "report", "--store", str(store), "--out", "/dev/null"]),
        ("fleet report --truth missing", ["fleet", "report", "--store", str(store), "--truth",
                                          str(tmp / "nope.json")] + out),
        ("fleet report --truth garbage", ["fleet", "report", "--store", str(store), "--truth", str(truth_bad)] + out),
        ("reproduce bogus", ["reproduce", "bogus"] + out),
        ("reproduce mbrl-cartpole --seed -1", ["reproduce", "mbrl-cartpole", "--quick", "--seed", "-1"] + out),
        ("reproduce mbrl-cartpole --out /dev/null", ["reproduce", "mbrl-cartpole", "--quick", "--out", "/dev/null"]),
        ("reproduce mbrl-cartpole --data missing", ["reproduce", "mbrl-cartpole", "--quick", "--data",
                                                    str(tmp / "nope")] + out),
        ("diagnose two logs, one missing", ["diagnose", ok, str(tmp / "missing.csv")] + out),
        ("diagnose two logs, one garbage", ["diagnose", ok, str(garbage)] + out),
        ("diagnose two logs, other joints", ["diagnose", ok, two] + out),
        ("diagnose the same log twice", ["diagnose", ok, ok] + out),
        ("diagnose two logs, one in degrees (irb140)", ["diagnose", ok, deg, "--robot", "irb140"] + out),
    ]
    return cases


def run(argv, timeout):
    """Run ``drake-est ARGV`` in its own process group; on timeout the whole group (Dask workers too) is
    killed and (None, "") returned."""
    import signal

    exe = str(ROOT / ".venv" / "bin" / "drake-est")
    p = subprocess.Popen([exe] + argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         env={**os.environ, "DRAKE_EST_NO_PROGRESS": "1"}, start_new_session=True)
    try:
        _, err = p.communicate(timeout=timeout)
        return p.returncode, err
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        p.communicate()
        return None, ""


WARNING = re.compile(r"^(drake-est [\w-]+: warning: |WARNING:|\[\d{4}-\d\d-\d\d .*\] \[\w+\] \[warning\])")


def nonfinite_files(folder: Path):
    bad = []
    for f in folder.rglob("*.json"):
        txt = f.read_text(errors="replace")
        if "NaN" in txt or "Infinity" in txt:
            bad.append(str(f))
    return bad


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--timeout", type=float, default=120.0)
    ap.add_argument("--json", default=None)
    ap.add_argument("--only", default=None, help="run only the cases whose name contains this text")
    ap.add_argument("--skip-new", action="store_true", help="leave out this round's commands (track, fleet, ...)")
    ap.add_argument("--new-only", action="store_true", help="only this round's commands")
    a = ap.parse_args(argv)
    from test_hardening import _build, _table

    counts = {"runs": 0, "one_line_exit_2": 0, "tracebacks": 0, "hangs": 0, "multi_line_errors": 0,
              "exit_0_on_garbage": 0, "other_exit_codes": 0, "files_with_nan_or_infinity": 0}
    failures = []
    with tempfile.TemporaryDirectory() as td:
        td = Path(td)
        cases = []
        for case, _frag in _table():
            d = td / case
            d.mkdir()
            built = _build(case, d)
            if not callable(built):      # API rows are covered by tests/test_hardening.py
                cases.append((case, built, d))
        od = td / "options"
        od.mkdir()
        cases += [(n, v, od) for n, v in option_cases(od)]
        nd = td / "new_commands"
        nd.mkdir()
        if not a.skip_new:
            new = new_command_cases(nd, a.timeout)
            new_command_cases.names = [n for n, _ in new]
            cases += [(n, v, nd) for n, v in new]
        if a.new_only:
            cases = cases[-len(new_command_cases.names):]
        if a.only:
            cases = [c for c in cases if a.only in c[0]]
        for name, args, d in cases:
            rc, err = run(args, a.timeout)
            counts["runs"] += 1
            lines = [ln for ln in err.strip().splitlines() if not WARNING.match(ln)]
            if rc is None:
                counts["hangs"] += 1
                failures.append((name, "hang"))
            elif "Traceback" in err:
                counts["tracebacks"] += 1
                failures.append((name, lines[-1] if lines else "traceback"))
            elif rc == 0:
                counts["exit_0_on_garbage"] += 1
                failures.append((name, "exit 0"))
            elif rc == 2 and len(lines) == 1:
                counts["one_line_exit_2"] += 1
            elif rc == 2:
                counts["multi_line_errors"] += 1
                failures.append((name, " | ".join(lines[-2:])))
            else:
                counts["other_exit_codes"] += 1
                failures.append((name, f"exit {rc}"))
            print(f"{name:45s} rc={rc} {lines[-1][:100] if lines else ''}", flush=True)
        counts["files_with_nan_or_infinity"] = len(nonfinite_files(td))
    for k, v in counts.items():
        print(f"{k:30s} {v}")
    for n, why in failures:
        print(f"FAIL {n}: {why}")
    if a.json:
        Path(a.json).write_text(json.dumps({"counts": counts, "failures": failures}, indent=2))
    return counts


if __name__ == "__main__":
    main(sys.argv[1:])
