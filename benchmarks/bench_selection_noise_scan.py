"""Which kept benchmark logs would a different velocity-noise estimate in the data selection (9.9) touch?

:func:`drake_est.diagnose.nominal.select_rows` bounds the selected speeds from below by ``max(5 % of the top speed,
10 x velocity noise)``, the noise being the robust spread of v's first differences.  At a low sample rate a smooth
motion's own change between samples dominates that spread and the bound rises to about half the top speed.  This
script computes, for every kept row of ``bench_diagnose_testbench.py`` (``kept_rows_naming("any")``), the selection
with the first-difference estimate (the library's) and with ``--alternative``:

* ``second-differences``: MAD of v's second differences / sqrt(6);
* ``second-differences-one-speed``: the same, and a sample is also left out where its speed changes by more than half
  of itself within one sample period (``|a| dt > 0.5 |v|``).

It writes the logs whose selected rows change (``--only`` file lines ``FAMILY K`` for
``bench_diagnose_testbench.py --rerun-kept any --only FILE``) and a JSON of counts per family and sample rate.  The
twenty-second round tried both alternatives this way (``results/diagnose_selection_velocity_noise_tried_round22.json``,
the patch ``results/diagnose_selection_velocity_noise_tried_round22.patch``); neither was kept.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_selection_noise_scan.py --lane 0/2 --json a.json --only-out a.txt
"""
from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

ALTERNATIVES = ("second-differences", "second-differences-one-speed")


def _mad(x) -> float:
    return 1.4826 * float(np.median(np.abs(x - np.median(x)))) if x.size else 0.0


def alternative_selection(v, a, t, alternative: str = "second-differences") -> np.ndarray:
    """The selected-rows mask of ``select_rows`` with the velocity noise of ``alternative`` (module docstring)."""
    from drake_est.diagnose.nominal import V_MIN_FRACTION
    if alternative not in ALTERNATIVES:
        raise SystemExit(f"--alternative must be one of {', '.join(ALTERNATIVES)}, got '{alternative}'")
    av, aa = np.abs(v), np.abs(a)
    vref = float(np.quantile(av, 0.95))
    v_min = max(V_MIN_FRACTION * vref, 10.0 * _mad(np.diff(v, 2)) / np.sqrt(6.0))
    moving = av > v_min
    a_max = max(3.0 * (float(np.median(aa[moving])) if moving.any() else 0.0), 1e-9)
    mask = moving & (aa <= a_max)
    if alternative == "second-differences-one-speed":
        dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
        mask &= aa * dt <= 0.5 * av
    return mask


def scan(alternative: str, lane: str = "0/1") -> list:
    """[{family, k, sample_rate, changed: [{joint, rows_library, rows_alternative}]}] over this lane's kept logs."""
    import bench_diagnose_testbench as B
    from drake_est.diagnose.nominal import select_rows, with_diagnosis_derivatives
    i, n = B._lane(lane)
    kept = B.kept_rows_naming("any")
    logs = sorted({(fam, k) for fam, _, k in kept})
    specs = B._specs_of(kept)
    out = []
    for fam, k in logs[i::n]:
        spec = specs[fam][k]
        log = with_diagnosis_derivatives(B.family_log(fam, spec)[0])
        changed = []
        for j in log.joints:
            c = log.col(j)
            v, a = log.dq[:, c], log.ddq[:, c]
            m0 = select_rows(v, a, log.t)[0]
            m1 = alternative_selection(v, a, log.t, alternative)
            if (m0 != m1).any():
                changed.append({"joint": int(j), "rows_library": int(m0.sum()), "rows_alternative": int(m1.sum())})
        out.append({"family": fam, "k": int(k), "sample_rate": spec.get("sample_rate"), "changed": changed})
    return out


def counts(rows) -> dict:
    """{"FAMILY RATE Hz": [logs whose selection changes, logs]}."""
    out = {}
    for r in rows:
        key = f"{r['family']} {r['sample_rate']:g} Hz"
        c = out.setdefault(key, [0, 0])
        c[0] += bool(r["changed"])
        c[1] += 1
    return dict(sorted(out.items()))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--alternative", default="second-differences", choices=ALTERNATIVES)
    ap.add_argument("--lane", default="0/1", help="i/n: every n-th kept log from the i-th")
    ap.add_argument("--json", help="write the rows and counts here")
    ap.add_argument("--only-out", help="write the changed logs as an --only file for --rerun-kept")
    a = ap.parse_args(argv)
    rows = scan(a.alternative, a.lane)
    c = counts(rows)
    for key, (ch, tot) in c.items():
        print(f"{key:>20}: {ch:5d} of {tot:5d} logs change their selection")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"alternative": a.alternative, "lane": a.lane, "counts": c, "rows": rows}, f, indent=1)
    if a.only_out:
        with open(a.only_out, "w") as f:
            f.writelines(f"{r['family']} {r['k']}\n" for r in rows if r["changed"])


if __name__ == "__main__":
    main()
