"""The sixty-sixth round's probe outside its rerun: would the likelihood-ratio bound of core.gain_within_rounding set
aside a finding of a kept quantized-torque log that does not name Stribeck?

Draws a random sample (seed 5) of 400 of the kept closed-loop logs with a quantized torque and a finding, diagnoses each
with the code of the checkout, and records every call of core.rounding_loglik_gains: per finding its held-out
log-likelihood gain at the common noise level (``gain_max``, what the forty-fifth round's check reads), at each model's
training level (``gain_own``), at each model's held-out-favoured level (``gain_hopt``, a bounded search over sigma in
[1e-4, 10] N m), the training gain and its column count.  ``--summary`` reads such files and prints how many calls the
bound would decide otherwise and the smallest ``gain_hopt`` / bound.  Run with 53f118e's code (the round's base) for
``benchmarks/results/diagnose_rounding_lr_round66_sample.json`` (two processes, about 12 minutes on 2 cores).

    python benchmarks/probe_rounding_lr_sample.py --sample > ks.txt
    python benchmarks/probe_rounding_lr_sample.py OUT.jsonl $(cat ks.txt)
    python benchmarks/probe_rounding_lr_sample.py --summary benchmarks/results/diagnose_rounding_lr_round66_sample.json
"""
import json
import os
import random
import sys

import numpy as np
import scipy.optimize

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))


def sample_keys(n=400, seed=5):
    from bench_diagnose_testbench import kept_jsons
    ks = set()
    for f in kept_jsons():
        for r in json.load(open(f))["rows"]:
            if r.get("family") == "loop" and r.get("noise") == "quantized" and r["got"] not in ("none", "unexplained"):
                ks.add(r["k"])
    ks = sorted(ks)
    random.seed(seed)
    return len(ks), sorted(random.sample(ks, n))


def run(out_path, ks):
    import drake_est.diagnose.core as core
    import drake_est.diagnose.quantization as qz
    from bench_diagnose_testbench import loop_cases, loop_log
    from drake_est.diagnose import diagnose
    ll, fit = qz.interval_loglik, qz.interval_fit
    lls, fits, rec = [], [], []

    def spy_ll(X, coef, sigma, lo, hi):
        lls.append((X, coef, lo, hi))
        return ll(X, coef, sigma, lo, hi)

    def spy_fit(X, lo, hi, **kw):
        r = fit(X, lo, hi, **kw)
        fits.append((X, lo, hi, r))
        return r

    def best(X, c, lo, hi):
        r = scipy.optimize.minimize_scalar(lambda s: -np.sum(ll(X, c, np.exp(s), lo, hi)),
                                           bounds=(np.log(1e-4), np.log(10.0)), method="bounded")
        return float(-r.fun)

    gains = core.rounding_loglik_gains

    def spy(prep, model):
        for e, info in gains(prep, model):
            (X1, c1, lo, hi), (X0, c0, _, _) = lls[-2], lls[-1]
            (X0t, lot, hit, (_, s0)), (X1t, _, _, (_, s1)) = fits[-2], fits[-1]
            rec.append({"effect": e.effect, "joint": e.joint, "k_params": int(X1.shape[1] - X0.shape[1]),
                        "gain_max": info["heldout_loglik_gain"],
                        "gain_own": float(np.sum(ll(X1, c1, s1, lo, hi) - ll(X0, c0, s0, lo, hi))),
                        "gain_hopt": best(X1, c1, lo, hi) - best(X0, c0, lo, hi),
                        "train_gain": float(np.sum(ll(X1t, c1, s1, lot, hit)) - np.sum(ll(X0t, c0, s0, lot, hit))),
                        "n_val": int(X1.shape[0]), "step": info["adc_step"], "s0": s0, "s1": s1,
                        "model": [x.effect for x in model.exts]})
            yield e, info

    qz.interval_loglik, qz.interval_fit, core.rounding_loglik_gains = spy_ll, spy_fit, spy
    specs = loop_cases(max(ks) + 1)
    with open(out_path, "a") as out:
        for k in ks:
            log, truth = loop_log(specs[k])
            rec.clear()
            d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
            out.write(json.dumps({"k": k, "truth": truth["effects"], "not_visible": list(truth.get("not_visible", {})),
                                  "found": [(f["effect"], f["status"]) for f in d["findings"]],
                                  "set_aside": [x.get("effect") for x in d.get("set_aside") or []],
                                  "rec": list(rec)}) + "\n")
            out.flush()


def read(paths):
    logs = []
    for p in paths:
        if p.endswith(".json"):
            logs += json.load(open(p))["logs"]
        else:
            logs += [json.loads(line) for line in open(p)]
    return logs


def summary(logs, alpha=1e-4):
    """{logs, calls, decided_otherwise: [...], smallest: [(ratio, k, effect, planted, gain_hopt, columns)...]}: the
    records against core.rounding_lr_bound at ``alpha`` (the diagnosis' ALPHA)."""
    from drake_est.diagnose.core import rounding_lr_bound

    bound = lambda k: rounding_lr_bound(k, alpha)  # noqa: E731
    other, ratios, calls = [], [], 0
    for L in logs:
        for r in L["rec"]:
            calls += 1
            old = r["gain_max"] >= 1.0
            new = old and r["gain_hopt"] >= bound(r["k_params"])
            if old:
                ratios.append((r["gain_hopt"] / bound(r["k_params"]), L["k"], r["effect"], r["effect"] in L["truth"],
                               r["gain_hopt"], r["k_params"]))
            if old != new:
                other.append((L["k"], r["effect"], r["gain_max"], r["gain_hopt"], r["k_params"]))
    return {"logs": len(logs), "calls": calls, "decided_otherwise": other, "smallest": sorted(ratios)[:5]}


if __name__ == "__main__":
    if sys.argv[1:2] == ["--sample"]:
        n, ks = sample_keys()
        print(" ".join(map(str, ks)))
        print(f"# {len(ks)} of {n} kept quantized loop logs with a finding", file=sys.stderr)
    elif sys.argv[1:2] == ["--summary"]:
        s = summary(read(sys.argv[2:]))
        print(f"{s['logs']} logs, {s['calls']} calls of the rounding check; the bound decides "
              f"{len(s['decided_otherwise'])} otherwise: {s['decided_otherwise']}")
        for ratio, k, eff, planted, g, c in s["smallest"]:
            print(f"  profiled gain {g:.1f} nats = {ratio:.2f} x bound: spec {k}, {eff} ({c} columns)"
                  + (", planted" if planted else ""))
    else:
        run(sys.argv[1], [int(x) for x in sys.argv[2:]])
