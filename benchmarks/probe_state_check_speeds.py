"""The ninety-first round's probe: the checks of a law in time against a free function of its joint's state leave out
the held-out rows faster than 1.5 times the joint's fastest training row.

``core.time_law_explained_by_state`` and ``core.sole_time_law_explained_by_state`` set a law in time (an abrupt change,
an energy drift) aside when a free function of the joint's state explains it one way (``core._state_explains_one_way``).
The function's speed curve holds its last value beyond the training speeds, so a few held-out samples of a faster move
can decide the comparison (fresh loop spec 33429: an asymmetric level beside Stribeck named an abrupt change alone).
The rule (``core.STATE_CHECK_WITHIN_TRAINING_SPEEDS``; rule file:
``benchmarks/results/diagnose_state_check_speeds_round91_rule.txt``) leaves those rows out of the two checks.

It can only change a log whose diagnosis held a law in time at a final check, on a joint with such held-out rows: the
kept row names a law in time in ``got`` or ``set_aside`` (``--keys candidates``; every open-loop testbench row, whose
rows do not store the set-aside list).  ``--screen OUT.json [--lane I/N] [--family=F]`` generates and prepares those
logs (no diagnosis) and lists the ones with such rows; ``--keys screened SCREEN.json ...`` prints them for the probe.

    python benchmarks/probe_state_check_speeds.py --keys candidates [--family=testbench] > kc.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_state_check_speeds.py --screen S0.json --lane 0/2 $(cat kc.txt)
    python benchmarks/probe_state_check_speeds.py --keys screened S0.json S1.json > ks.txt
    OPENBLAS_NUM_THREADS=1 python benchmarks/probe_state_check_speeds.py OUT.json $(cat ks.txt)
    python benchmarks/probe_state_check_speeds.py --against-off-rows A.json B.json     # the docs' table
"""
from __future__ import annotations

import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_diagnose_testbench as B  # noqa: E402
from drake_est.diagnose import core as _core  # noqa: E402
from probe_held_back_rival import against_off, against_off_cli, against_off_row  # noqa: E402,F401
from probe_position_friction_halves import row_class  # noqa: E402,F401
from probe_runner import keys_args, kept_keys, kept_rows, probe_main, run_rule_probe  # noqa: E402

RULE = "STATE_CHECK_WITHIN_TRAINING_SPEEDS"
FUNC = "_state_explains_one_way"
TIME_LAWS = ("abrupt_change", "energy_dependent_friction")
#: what the screen lists
FAST = "held-out rows faster than 1.5 times the fastest training row"


def candidate(r: dict, family: str = "loop") -> bool:
    """Whether a kept row can be changed by the rule: it names a law in time in ``got`` or among the findings set
    aside; every open-loop testbench row (those do not store the set-aside list)."""
    if family == "testbench":
        return True
    names = [r.get("got", "")] + list(r.get("set_aside") or [])
    return any(t in x for x in names for t in TIME_LAWS)


def candidate_keys(family: str = "loop", results_dir=None) -> list:
    """The spec numbers of ``family``'s kept rows that are :func:`candidate`, sorted."""
    return kept_keys(family, lambda r: candidate(r, family), results_dir)


def prepared_log(family: str, spec: dict):
    """The log of ``spec`` (of ``family``) as prepared for its kept row (no diagnosis; the closed-loop log generated
    without its visibility check, which changes nothing in the log), or ``{"refused": message}`` when preparation
    refuses it.  The screens' common part (those of the ninety-first, ninety-third, ninety-sixth, ninety-eighth and
    ninety-ninth rounds)."""
    from drake_est.diagnose.nominal import prepare
    from drake_est.errors import DataError
    log = B.loop_log(spec, check_visible=False)[0] if family == "loop" else B.family_log(family, spec)[0]
    try:
        return prepare(log, robot="generic")
    except DataError as e:
        return {"refused": str(e)}


def per_joint_of_prepared(family: str, spec: dict, per_joint) -> dict:
    """{joint: ``per_joint(jd)``} over the joints of :func:`prepared_log` of ``spec`` (of ``family``), joints where it
    returns None left out; ``{"refused": message}`` when preparation refuses the log."""
    prep = prepared_log(family, spec)
    if isinstance(prep, dict):
        return prep
    out = {}
    for j, jd in prep.joints.items():
        got = per_joint(jd)
        if got is not None:
            out[str(j)] = got
    return out


def fast_held_out_rows(family: str, spec: dict) -> dict:
    """{joint: held-out rows faster than 1.5 times its fastest training row} of the log of ``spec`` (of ``family``)
    (:func:`per_joint_of_prepared`); joints without such rows left out."""
    from drake_est.diagnose.nominal import faster_than_training
    return per_joint_of_prepared(family, spec,
                                 lambda jd: int(faster_than_training(jd.v[jd.rows], jd.train).sum()) or None)


def screen(out_path: str, keys, family: str = "loop", lane: str = "0/1", measure=None, what: str = FAST,
           desc: str = "prepare (fast held-out rows)", extra: dict | None = None) -> dict:
    """``measure(family, spec)`` (:func:`fast_held_out_rows` unless given; a dict, empty when the log has nothing to
    list, ``{"refused": message}`` when preparation refuses it) of the logs ``keys`` in lane ``I/N`` (every N-th from
    I), written to ``out_path`` every 50 logs and at the end: ``{"family", "lane", "logs", "keys_screened",
    "touched": [[k, {joint: ...}]], "refused": [[k, message]]}``; ``what``: what a listed log has, for the summary
    line; ``extra``: more keys for the JSON, e.g. a threshold the screen ran with.  Also the ninety-third round's
    screen (``probe_load_untested_direction.py``)."""
    measure = fast_held_out_rows if measure is None else measure
    from drake_est.progress import progress
    i, n = B._lane(lane)
    kept_rows(family, keys)     # exits when a key has no kept row
    mine = list(keys)[i::n]
    specs = (B.loop_cases if family == "loop" else B.cases)(max(mine) + 1) if mine else []
    res = {"family": family, "lane": f"{i}/{n}", **(extra or {}), "logs": 0, "keys_screened": [], "touched": [],
           "refused": []}
    for m, k in enumerate(progress(mine, desc=desc)):
        got = measure(family, specs[k])
        res["logs"] += 1
        res["keys_screened"].append(k)
        if "refused" in got:
            res["refused"].append([k, got["refused"]])
        elif got:
            res["touched"].append([k, got])
        if m % 50 == 49:
            B._write_json(res, out_path)
    B._write_json(res, out_path)
    print(f"{res['logs']} logs prepared (lane {res['lane']}); {len(res['touched'])} with {what}; "
          f"{len(res['refused'])} refused")
    return res


def screened_keys(paths, family: str = "loop") -> list:
    """The spec numbers that the screens ``paths`` list with fast held-out rows, sorted; exits when a screen is of
    another family."""
    out = set()
    for p in paths:
        d = json.load(open(p))
        if d.get("family") != family:
            raise SystemExit(f"{p}: a screen of family {d.get('family')!r}, not {family!r}")
        out |= {int(k) for k, _ in d["touched"]}
    return sorted(out)


def keys_cli(argv, candidate_keys=candidate_keys, name: str = "candidates") -> None:
    """``--keys candidates [--family=F]``: the kept rows the rule can change (``candidate_keys(family)``,
    :func:`candidate_keys` unless given; the ninety-third and ninety-eighth rounds' probes pass their own, the latter
    under the ``name`` touchable); ``--keys screened S.json ... [--family=F]``: those the screens list."""
    family, rest = keys_args(argv)
    if rest == [name]:
        keys = candidate_keys(family)
    elif rest and rest[0] == "screened" and len(rest) > 1:
        keys = screened_keys(rest[1:], family)
    else:
        raise SystemExit(f"--keys: expected '{name}' or 'screened SCREEN.json ...'")
    print(" ".join(str(k) for k in keys))


def screen_cli(argv, **kw) -> bool:
    """``--screen OUT.json [--lane I/N] [--family=F] K ...``: run :func:`screen` (``kw``: its ``measure``, ``what`` and
    ``desc``); False when ``argv`` is not one."""
    if not argv or argv[0] != "--screen":
        return False
    family, lane, rest = "loop", "0/1", []
    for a in argv[1:]:
        if a.startswith("--family="):
            family = a.split("=", 1)[1]
        elif a.startswith("--lane="):
            lane = a.split("=", 1)[1]
        else:
            rest.append(a)
    if len(rest) < 2:
        raise SystemExit("--screen: expected OUT.json and spec numbers")
    try:
        keys = [int(x) for x in rest[1:]]
    except ValueError as e:
        raise SystemExit(f"--screen: expected spec numbers after OUT.json: {e}")
    screen(rest[0], keys, family, lane, **kw)
    return True


def _record(got, a, kw):
    """The record of one check where the rule left rows out and changed its outcome (None otherwise): the outcome
    with the rule on (``got``) against the same call with it off."""
    prep, m0, j, C, alpha, min_gain = a[:6]
    if not _core.STATE_CHECK_WITHIN_TRAINING_SPEEDS:
        return None
    _, n_far = _core.state_check_rows(prep, j)
    if not n_far:
        return None
    _core.STATE_CHECK_WITHIN_TRAINING_SPEEDS = False
    try:
        off = _ORIGINAL(prep, m0, j, C, alpha, min_gain)
    finally:
        _core.STATE_CHECK_WITHIN_TRAINING_SPEEDS = True
    if (got is None) == (off is None):
        return None
    laws = [e.effect for e in m0.exts if not e.shared and e.joint == j]
    return {"joint": int(j), "held_out_rows_left_out": n_far, "explained_by_state_on": got is not None,
            "explained_by_state_off": off is not None, "other_findings_of_joint": laws}


def run(out_path: str, keys, family: str = "loop") -> dict:
    """Diagnose the kept logs ``keys`` of ``family`` with the rule on; where it changed a check's outcome, store the
    rows and the rows of the same logs with the rule off."""
    return run_rule_probe(out_path, keys, family, rule=RULE, func=FUNC, record=_record, hits_key="checks",
                          row_class=row_class, compare_off=True)


# the unwrapped check (run_rule_probe wraps core._state_explains_one_way while it runs)
_ORIGINAL = _core._state_explains_one_way


def screen_probe_main(argv, doc: str, keys_cli, run, **screen_kw) -> None:
    """A screening probe's command line: ``--screen ...`` (:func:`screen_cli`, ``screen_kw``: its ``measure``, ``what``
    and ``desc``), ``--against-off-rows ...`` (``probe_held_back_rival.against_off_cli``), else
    ``probe_runner.probe_main`` with ``keys_cli`` and ``run`` (the probes of the ninety-first, ninety-third,
    ninety-sixth, ninety-eighth and ninety-ninth rounds)."""
    if not screen_cli(argv, **screen_kw) and not against_off_cli(argv):
        probe_main(argv, doc, keys_cli, run)


def main(argv=None):
    screen_probe_main(list(sys.argv[1:] if argv is None else argv), __doc__, keys_cli, run)


if __name__ == "__main__":
    main()
