"""Where a later finding's held-out gain lies: in a few large errors, or across the absolute errors (the probe that
led to the thirty-seventh round, core.gain_in_few_samples).

For closed-loop benchmark specs, the diagnosis is run and, for every finding of the final model accepted after
another one on its joint, the model without it is fitted; printed per finding: the held-out RMSE reduction, the
reductions of a Huber loss (threshold 1.345 robust standard deviations of the errors without it) and of the mean
absolute error, the share of the squared-error gain held by the 5 largest per-sample gains, and the one-sided
paired Wilcoxon p over the held-out groups of the absolute errors and of the Huber loss.  Run with the code before
the round (a0b840e), a finding the round sets aside is still in the final model.

    python benchmarks/probe_gain_in_few_samples.py --k 11752 9353 --json out.json
    python benchmarks/probe_gain_in_few_samples.py --random 40 --json out.json   # kept loop rows, 10-50 Hz,
                                                                                # Student-t, two findings, correct
"""
import argparse
import json
import os
import random
import sys

import numpy as np
import scipy.stats

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_diagnose_testbench as b  # noqa: E402


def huber(e, c):
    a = np.abs(e)
    return np.where(a <= c, 0.5 * e ** 2, c * (a - 0.5 * c))


def _wilcoxon_greater(d) -> float:
    return float(scipy.stats.wilcoxon(d, alternative="greater").pvalue) if d.size >= 3 and np.any(d) else 1.0


def probe(k: int) -> dict:
    from drake_est.diagnose import competition as comp
    from drake_est.diagnose.core import Model, run_diagnosis
    from drake_est.diagnose.nominal import block_index
    spec = b.loop_cases(k + 1)[k]
    log, _ = b.loop_log(spec)
    d = run_diagnosis(log, robot="generic")
    out, seen = [], set()
    for st in d.steps:
        e = st.ext
        js = {int(j) for j in e.cols}
        later = bool(js & seen)
        seen |= js
        if not later or e.shared or not any(x is e for x in d.final_model.exts):
            continue
        j = e.joint
        jd = d.prep.joints[j]
        f0 = Model(d.prep, [x for x in d.final_model.exts if x is not e]).fit(d.sigma)
        ea = (jd.y - f0.pred[j])[jd.val]
        eb = (jd.y - d.final_fit.pred[j])[jd.val]
        c = 1.345 * 1.4826 * float(np.median(np.abs(ea - np.median(ea))))
        g = ea ** 2 - eb ** 2
        blk = block_index(jd.t, jd.rows)[jd.val]
        ub, inv = np.unique(blk, return_inverse=True)
        grp = (inv * min(comp.PAIRED_GROUPS, ub.size)) // ub.size
        out.append({
            "effect": e.effect, "joint": j, "planted": e.effect in spec["effects"], "heldout_samples": int(g.size),
            "rmse_reduction": float(1 - np.sqrt(np.mean(eb ** 2) / np.mean(ea ** 2))),
            "huber_reduction": float(1 - huber(eb, c).sum() / huber(ea, c).sum()),
            "mae_reduction": float(1 - np.mean(np.abs(eb)) / np.mean(np.abs(ea))),
            "top5_share": float(np.sort(g)[::-1][:5].sum() / g.sum()) if g.sum() > 0 else None,
            "paired_p_absolute": _wilcoxon_greater(np.bincount(grp, weights=np.abs(ea) - np.abs(eb))),
            "paired_p_huber": _wilcoxon_greater(np.bincount(grp, weights=huber(ea, c) - huber(eb, c)))})
    return {"k": k, "noise": spec["noise"], "sample_rate": spec["sample_rate"],
            "truth": [x for x in spec["effects"] if not x.startswith("_")], "later": out}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--k", type=int, nargs="*", default=[])
    ap.add_argument("--random", type=int, default=0, help="this many kept loop rows at 10-50 Hz with Student-t "
                                                          "noise, two or more findings, correct (seeded)")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    ks = list(a.k)
    if a.random:
        pool = sorted(k for (f, _, k), (_, r) in b.kept_rows_naming("any").items()
                      if f == "loop" and r["noise"] == "student_t" and r["sample_rate"] <= 50 and "+" in r["got"]
                      and r["correct"])
        ks += sorted(random.Random(1).sample(pool, a.random))
    rows = []
    for k in ks:
        r = probe(k)
        rows.append(r)
        for x in r["later"]:
            print(f"{k:6d} {r['sample_rate']:6.0f} Hz {x['effect']:28s} planted={x['planted']!s:5s} "
                  f"RMSE {100 * x['rmse_reduction']:5.1f} %  MAE {100 * x['mae_reduction']:5.1f} %  "
                  f"top-5 share {x['top5_share'] if x['top5_share'] is None else round(x['top5_share'], 2)}  "
                  f"paired p (absolute) {x['paired_p_absolute']:.2g}", flush=True)
    if a.json:
        from drake_est.jsonutil import dump_json
        dump_json({"what": "later findings' held-out gains (benchmarks/probe_gain_in_few_samples.py), run with the "
                           "code before the thirty-seventh round (a0b840e)", "rows": rows}, a.json)


if __name__ == "__main__":
    main()
