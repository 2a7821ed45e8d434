"""Sweep: every bad-input case of docs/readme/hardening.md plus damaged numeric options of each command,
each run as a fresh `drake-est` process; counts tracebacks, hangs, multi-line errors, exit 0 on garbage
and NaN/Infinity in written files (issue 19's acceptance measure; target: all zero).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/sweep_bad_inputs.py [--timeout 120] [--json out.json]
"""
import argparse
import json
import os
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
        cases += [(f"synth --duration {bad}", ["synth", "--out", str(tmp / "s.csv"), "--duration", bad]),
                  (f"synth --rate {bad}", ["synth", "--out", str(tmp / "s.csv"), "--rate", bad]),
                  (f"synth --noise {bad}", ["synth", "--out", str(tmp / "s.csv"), "--noise", bad, "--duration", bad]),
                  (f"spectrum --gear-ratio {bad}", ["spectrum", log, "--signal", "tau1", "--position", "q1",
                                                   "--gear-ratio", bad] + out),
                  (f"spectrum --f-max {bad}", ["spectrum", log, "--signal", "tau1", "--position", "q1",
                                              "--f-max", bad] + out),
                  (f"fit-friction --holdout {bad}", ["fit-friction", log, "--holdout", bad] + out),
                  (f"fit-friction --v-min {bad}", ["fit-friction", log, "--v-min", bad, "--holdout", bad] + out),
                  (f"calibrate ft --mass {bad}", ["calibrate", "ft", ft, "--method", "cayley", "--mass", bad] + out),
                  (f"calibrate laser --length-scale {bad}", ["calibrate", "laser", laser, "--length-scale", bad] + out),
                  (f"calibrate laser --assign-threshold {bad}", ["calibrate", "laser", laser, "--assign-threshold",
                                                                bad] + out)]
    cases += [("synth --seed -1", ["synth", "--out", str(tmp / "s.csv"), "--seed", "-1"]),
              ("calibrate laser --T0 nan", ["calibrate", "laser", laser, "--T0", "nan 0 0 0 0 0"] + out),
              ("calibrate laser --iters 0", ["calibrate", "laser", laser, "--iters", "0"] + out)]
    del np
    return cases


def run(argv, timeout):
    exe = str(ROOT / ".venv" / "bin" / "drake-est")
    try:
        p = subprocess.run([exe] + argv, capture_output=True, text=True, timeout=timeout,
                           env={**os.environ, "DRAKE_EST_NO_PROGRESS": "1"})
        return p.returncode, p.stderr
    except subprocess.TimeoutExpired:
        return None, ""


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
        for name, args, d in cases:
            rc, err = run(args, a.timeout)
            counts["runs"] += 1
            lines = err.strip().splitlines()
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
