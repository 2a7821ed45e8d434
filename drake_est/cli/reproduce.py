"""``drake-est reproduce NAME``: rerun a thesis experiment, write PNGs and a JSON of numbers."""
from __future__ import annotations

import inspect
from pathlib import Path

from drake_est.errors import DrakeEstError
from drake_est.jsonutil import dump_json


def register(sub):
    p = sub.add_parser("reproduce", help="reproduce a thesis figure/table (writes PNGs + JSON)")
    p.add_argument("name", nargs="?", help="experiment name; omit to list them")
    p.add_argument("--out", default=None, help="output folder (default: ./reproduce-NAME)")
    p.add_argument("--quick", action="store_true", help="smaller sizes for a fast look (numbers differ from the thesis setting)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--data", default=None, help="folder with the real data sets (real-* experiments; default ../shared/data)")
    p.add_argument("--workers", type=int, default=None,
                   help="parallel worker processes for experiments that run many seeds (default: their own, "
                        "at most the local cores)")
    p.set_defaults(func=run)


def run(args) -> int:
    from drake_est.reproduce import experiments

    exps = experiments()
    if not args.name:
        print("Available experiments:")
        for name in sorted(exps):
            doc = (exps[name].__doc__ or "").strip().split("\n\n")[0]   # first paragraph, not its first line
            print(f"  {name:22s} {' '.join(doc.split())}")
        print("Run one with: drake-est reproduce NAME [--quick] [--out DIR]")
        return 0
    if args.name not in exps:
        raise DrakeEstError(f"unknown experiment '{args.name}'; choose one of: {', '.join(sorted(exps))}")
    from drake_est.cli._common import check_number

    check_number("--seed", args.seed, 0, 2**32 - 1, integer=True)
    params = inspect.signature(exps[args.name]).parameters
    if args.data is not None:
        if "data_dir" not in params:
            raise DrakeEstError(f"--data is only used by the real-data experiments; '{args.name}' does not read it")
        if not Path(args.data).exists():
            raise DrakeEstError(f"--data folder {args.data} not found")
        if not Path(args.data).is_dir():
            raise DrakeEstError(f"--data {args.data} is not a folder")
    par = None
    if args.workers is not None:
        check_number("--workers", args.workers, 1, 1024, integer=True)
        par = next((k for k in ("workers", "jobs") if k in params), None)
        if par is None:
            raise DrakeEstError(f"--workers is only used by experiments that run seeds in parallel; "
                                f"'{args.name}' runs in one process")
    out = Path(args.out or f"reproduce-{args.name}")
    if out.exists() and not out.is_dir():
        raise DrakeEstError(f"--out {out} exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    kwargs = dict(out_dir=out, quick=args.quick, seed=args.seed)
    if args.data is not None:
        kwargs["data_dir"] = args.data
    if par is not None:
        kwargs[par] = args.workers
    result = exps[args.name](**kwargs)
    path = out / f"{args.name}.json"
    if isinstance(result, dict):
        result = {**result, "run": {"quick": bool(args.quick), "seed": args.seed}}
    if isinstance(result, dict):   # undefined numbers (e.g. a median over no successes): null, listed
        from drake_est.jsonutil import nonfinite_to_null

        result, undefined = nonfinite_to_null(result)
        if undefined:
            result["undefined_numbers"] = undefined
    dump_json(result, path)
    if isinstance(result, dict):
        lines = _scalar_lines(result)
        if lines:
            print(f"{args.name}: key numbers (all of them in {path.name})")
            for line in lines[:25]:
                print(f"  {line}")
            if len(lines) > 25:
                print(f"  ... {len(lines) - 25} more in {path.name}")
    print(f"wrote {path} and figures in {out}/" + (" (--quick: smaller sizes, numbers differ from the full run)"
                                                    if args.quick else ""))
    return 0



def _scalar_lines(d, prefix="", depth=0) -> list:
    """'a.b = 1.23' lines for the numbers and short strings of a nested result dict (not lists/arrays)."""
    import numpy as np

    out = []
    for k, v in d.items():
        if k == "run":
            continue
        key = f"{prefix}{k}"
        if isinstance(v, dict) and depth < 2:
            out += _scalar_lines(v, key + ".", depth + 1)
        elif isinstance(v, (bool, np.bool_)):
            out.append(f"{key} = {bool(v)}")
        elif isinstance(v, (int, float, np.integer, np.floating)):
            out.append(f"{key} = {float(v):.4g}")
        elif isinstance(v, str) and len(v) < 60:
            out.append(f"{key} = {v}")
    return out
