"""A law in time that is the only finding of its joint, held against a free function of the state (a lead for a
round after the fifty-first: core.time_law_explained_by_state checks a law in time only beside a law of the state).

For the kept closed-loop rows whose final model is one law in time (an abrupt change or an energy drift, named or
first in an ambiguity) while the final residual holds structure in the state (an ``unexplained`` entry in position,
velocity or acceleration), the diagnosis is run again and, where the final model is still one law in time, the law
is held against a free function of the state (core._state_explains on the nominal model): ``explained`` when given
the function the law does not predict the held-out residual and the function alone predicts it at least as well as
the law alone.  Printed and written per log: the truth, the final model, the ``unexplained`` variables and, when
tested, the law's held-out RMSE reduction given the function, alone, and the function's alone.

    python benchmarks/probe_sole_time_law_state.py --json benchmarks/results/diagnose_sole_time_law_state_probe.json
    python benchmarks/probe_sole_time_law_state.py --k 13761 8484
"""
import argparse
import json
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_diagnose_testbench as b  # noqa: E402

TIME_LAWS = ("abrupt_change", "energy_dependent_friction")
STATE = {"position", "velocity", "acceleration"}


def selected() -> list:
    """The kept loop specs this probe reads (module docstring)."""
    out = []
    for (fam, _, k), (_, r) in b.kept_rows_naming("any").items():
        parts = re.findall(r"ambiguous\([^)]*\)|[a-z_]+", r["got"])
        if fam != "loop" or len(parts) != 1:
            continue
        first = parts[0][10:-1].split("|")[0] if parts[0].startswith("ambiguous(") else parts[0]
        if first in TIME_LAWS and set(r.get("unexplained") or []) & STATE:
            out.append(k)
    return sorted(out)


def probe(k: int, truth: str = "") -> dict:
    from drake_est.diagnose import core
    from drake_est.diagnose.core import Model, run_diagnosis
    spec = b.loop_cases(k + 1)[k]
    log, _ = b.loop_log(spec)
    d = run_diagnosis(log, robot="generic")
    m = d.final_model
    names = [e.effect for e in m.exts]
    out = {"k": k, "truth": truth, "final": names, "unexpl": sorted({u["variable"] for u in d.unexplained})}
    if len(m.exts) == 1 and names[0] in TIME_LAWS:
        e = m.exts[0]
        got = core._state_explains(d.prep, Model(d.prep, []), e.joint, e.cols[e.joint], core.ALPHA, core.MIN_GAIN)
        out["explained"] = got is not None
        if got is not None:
            _, t, own, state = got
            out.update(given=t["rmse_reduction"], own=own, state=state)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--k", type=int, nargs="*", help="loop specs (default: the kept rows of the module docstring)")
    ap.add_argument("--json", help="write the rows here")
    a = ap.parse_args(argv)
    kept = b.kept_rows_naming("any")
    ks = a.k if a.k else selected()
    rows = []
    for k in ks:
        r = probe(k, kept.get(("loop", "generic", k), (None, {"truth": ""}))[1]["truth"])
        print(json.dumps(r), flush=True)
        rows.append(r)
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"command": "python benchmarks/probe_sole_time_law_state.py" + (" --k " + " ".join(map(str, ks))
                                                                                     if a.k else ""),
                       "logs": len(rows), "explained": [r["k"] for r in rows if r.get("explained")], "rows": rows},
                      f, indent=0)


if __name__ == "__main__":
    main()
