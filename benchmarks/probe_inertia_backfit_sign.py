"""The seventy-fifth round's probe: the inertia backfit does not move a positive J to J <= 0.

``core.backfit_inertia`` re-estimates a generic axis' inertia beside the findings.  The rule
(``core.inertia_move_through_zero``, switched on by ``core.INERTIA_BACKFIT_KEEPS_SIGN``; rule:
``benchmarks/results/diagnose_inertia_backfit_sign_round75_rule.txt``) withholds a correction that would leave a
positive J at J <= 0 (loop spec 21549: J 0.787 -> -19.3, the generator's 0.919).  The rule can only change a log
whose backfit, without it, moves J from above 0 to 0 or below; kept rows since the thirty-sixth round record the
move (``inertia_backfit``: [J from prepare, J after]), so the selection is those rows (``--keys touchable``).

    python benchmarks/probe_inertia_backfit_sign.py --keys touchable > kt.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_inertia_backfit_sign.py OUT.json $(cat kt.txt)
    python benchmarks/probe_inertia_backfit_sign.py --against-off A.json B.json
    python benchmarks/probe_inertia_backfit_sign.py --against-off-rows A.json B.json     # the docs' table

``--against-off``: the rows where the rule fired, judged against their rule-off rows
(``probe_held_back_rival.against_off``).

Kept rows from before the thirty-sixth round do not record the backfit's move.  ``--screen OUT.json K...`` runs, with
the rule off, only as far as the inertia backfit of each log (the first searches, no checks of the final model) and
writes {k: [J, J after the backfit] or null}; the keys whose move crosses zero are then probed as above:

    python benchmarks/probe_inertia_backfit_sign.py --keys unrecorded > ku.txt    # loop rows without the record
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_inertia_backfit_sign.py --screen S.json $(cat ku.txt)
    python benchmarks/probe_inertia_backfit_sign.py --crossed S.json              # the keys to probe
"""
from __future__ import annotations

import functools
import os
import sys
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import probe_position_laws_speed_curve as speed_curve  # noqa: E402
# against_off, against_off_row and the header: this probe's judging and docs table (its tests read them here)
from probe_held_back_rival import (AGAINST_OFF_HEADER, against_off, against_off_cli,  # noqa: E402,F401
                                   against_off_row)
from probe_pair_rescue import row_class  # noqa: E402
from probe_runner import probe_main, run_rule_probe  # noqa: E402


def crosses_zero(moves) -> bool:
    """Whether {joint: [J, J after the backfit]} (a row's ``inertia_backfit``, a screen's entry) holds a move from
    J > 0 to J <= 0."""
    return any(J > 0 and J_new <= 0 for J, J_new in (moves or {}).values())


def moved_through_zero(row) -> bool:
    """Whether the kept row records an inertia backfit move from J > 0 to J <= 0 on some joint."""
    return crosses_zero(row.get("inertia_backfit"))


touchable_keys = functools.partial(speed_curve.touchable_keys, touchable=moved_through_zero)
keys_cli = functools.partial(speed_curve.keys_cli, touchable=moved_through_zero)


def unrecorded_keys(family: str = "loop") -> list:
    """The keys of ``family``'s kept rows that hold no ``inertia_backfit`` record and come from a block JSON first
    committed before the rows recorded it (5e2e280, the thirty-sixth round): their backfit's move is unknown."""
    import subprocess
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    git = functools.partial(subprocess.run, capture_output=True, text=True, cwd=root, check=True, shell=True)
    before = set(git("git rev-list 5e2e280").stdout.split())
    added, cur = {}, None
    for line in git("git log --diff-filter=A --format=@%H --name-only -- benchmarks/results").stdout.splitlines():
        if line.startswith("@"):
            cur = line[1:]
        elif line.strip():
            added[os.path.basename(line.strip())] = cur
    return sorted(k for (f, _, k), (src, r) in speed_curve.B.kept_rows_naming("any").items()
                  if f == family and "inertia_backfit" not in r and added.get(os.path.basename(src)) in before)


class _Screened(Exception):
    """Raised once a screened log's backfit has run (or the search went past it without one)."""


def screen(out_path: str, keys, family: str = "loop") -> dict:
    """{k: [J, J after the backfit] or None (the backfit did not move J, or did not run)} of the kept logs ``keys``,
    each diagnosed with the rule off only as far as the inertia backfit; written to ``out_path`` every 50 logs."""
    import json
    from drake_est.diagnose import core, diagnose
    from drake_est.errors import DataError
    make = speed_curve.B.loop_cases if family == "loop" else speed_curve.B.cases
    was_on, bi, fa, tla = (core.INERTIA_BACKFIT_KEEPS_SIGN, core.backfit_inertia, core.finding_to_set_aside,
                           core.time_law_alternative)
    got = {}

    def backfit(prep, model, fit):
        moved = bi(prep, model, fit)
        got.update({int(j): [float(a), float(b)] for j, (a, b) in moved.items()})
        raise _Screened

    def stop(*a, **kw):
        raise _Screened

    res = {"family": family, "screened": {}, "refused": []}
    core.INERTIA_BACKFIT_KEEPS_SIGN = False
    core.backfit_inertia, core.finding_to_set_aside, core.time_law_alternative = backfit, stop, stop
    try:
        for m, k in enumerate(keys):
            log, _ = speed_curve.B.family_log(family, make(k + 1)[k])
            got.clear()
            try:
                diagnose(log, robot="generic", seed=0, simulate=False)
            except _Screened:
                pass
            except DataError as e:
                res["refused"].append({"k": k, "reason": str(e)})
            res["screened"][str(k)] = {str(j): v for j, v in got.items()} or None
            if m % 50 == 49:
                Path(out_path).write_text(json.dumps(res))
                print(f"screened {m + 1} / {len(keys)}", flush=True)
    finally:
        core.INERTIA_BACKFIT_KEEPS_SIGN = was_on
        core.backfit_inertia, core.finding_to_set_aside, core.time_law_alternative = bi, fa, tla
    Path(out_path).write_text(json.dumps(res))
    return res


def crossed(paths) -> list:
    """The screened keys whose backfit moved J from above 0 to 0 or below on some joint."""
    import json
    return sorted({int(k) for p in paths for k, moves in json.loads(Path(p).read_text())["screened"].items()
                   if crosses_zero(moves)})


def _withheld(got, a, kw):
    """The record of one firing: the move withheld (None: the rule did not apply)."""
    if got is None:
        return None
    return {"J": float(a[0]), "J_moved": float(got["J_moved"]), "standard_error": float(got["standard_error"])}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it fired, store the rows and the rows of
    the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule="INERTIA_BACKFIT_KEEPS_SIGN", func="inertia_move_through_zero",
                          record=_withheld, hits_key="withheld", row_class=row_class, compare_off=True)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:2] == ["--keys", "unrecorded"]:
        print(" ".join(map(str, unrecorded_keys())))
    elif argv[:1] == ["--screen"]:
        if len(argv) < 3:
            raise SystemExit("--screen OUT.json K...: give the output file and the spec numbers")
        res = screen(argv[1], [int(x) for x in argv[2:]])
        print(f"screened {len(res['screened'])}, refused {len(res['refused'])}, crossing zero: {crossed([argv[1]])}")
    elif argv[:1] == ["--crossed"]:
        print(" ".join(map(str, crossed(argv[1:]))))
    elif not against_off_cli(argv):
        probe_main(argv, __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
