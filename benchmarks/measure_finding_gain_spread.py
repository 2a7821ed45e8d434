"""Where each finding of a closed-loop spec's final model takes its held-out gain: a measurement, not a rule.

For each single-joint finding of the final model (the diagnosis as it stands), the model without it is fitted and the
per-sample held-out gains ``g = e_without^2 - e_with^2`` of its joint are read: the share of their sum held by the
largest 5 % of the samples (above 1: the other 95 % are predicted worse), the excess-kurtosis test of the final
held-out residual, and the paired test over the held-out blocks on the squared and on the absolute errors -- the
quantities of the forty-first round's check of a sole finding (``core.sole_finding_gain_in_few_samples``).

Fresh spec 46439 (backlash at 1000 Hz, reported as a position friction) against planted position frictions of the
same blocks:

    OPENBLAS_NUM_THREADS=1 python benchmarks/measure_finding_gain_spread.py 46439 46005 46203 46247
"""
from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np
import scipy.stats

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_diagnose_testbench as B  # noqa: E402
from drake_est.diagnose import core, diagnose  # noqa: E402
from drake_est.diagnose import competition as comp  # noqa: E402


def gain_spread(k: int, top: float = core.FEW_SAMPLES_SHARE) -> list:
    """One dict per single-joint finding of closed-loop spec ``k``'s final model."""
    log, truth = B.loop_log(k)
    res = diagnose(log, robot="generic").result
    prep, model, fit, sigma = res.prep, res.final_model, res.final_fit, res.sigma
    out = []
    for e in model.exts:
        if e.shared:
            continue
        j = e.joint
        jd = prep.joints[j]
        f0 = core.Model(prep, [x for x in model.exts if x is not e]).fit(sigma)
        eb, ea = (jd.y - fit.pred[j])[jd.val], (jd.y - f0.pred[j])[jd.val]
        g = ea ** 2 - eb ** 2
        n_top = max(1, int(np.ceil(top * g.size)))
        sq = comp.paired_block_test(prep, f0, fit, [j])
        ab = comp.paired_block_test(prep, f0, fit, [j], loss="absolute")
        out.append({
            "k": k, "truth": "+".join(truth.get("planted", [])) or "none", "effect": e.effect, "joint": int(j),
            "heldout_samples": int(g.size),
            "heldout_rmse_reduction": float(1 - np.sqrt(np.mean(eb ** 2) / np.mean(ea ** 2))),
            "share_of_gain_in_largest": float(np.sort(g)[::-1][:n_top].sum() / g.sum()) if g.sum() > 0 else None,
            "largest_fraction": top,
            "kurtosis_p": float(scipy.stats.kurtosistest(eb, alternative="greater").pvalue),
            "paired_p_squared": float(sq["p_value"]), "paired_p_absolute": float(ab["p_value"]),
            "blocks_better_absolute": f"{ab['groups_better']} / {ab['groups']}"})
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("specs", nargs="+", type=int, help="closed-loop spec numbers")
    args = ap.parse_args(argv)
    for k in args.specs:
        for row in gain_spread(k):
            print(json.dumps(row))
    return 0


if __name__ == "__main__":
    sys.exit(main())
