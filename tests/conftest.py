import os

# small per-step linear algebra is faster single-threaded on shared 2-core machines (shared/drake_notes.md)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("DRAKE_EST_NO_PROGRESS", "1")

import matplotlib  # noqa: E402

matplotlib.use("Agg")

from pathlib import Path  # noqa: E402

import pytest  # noqa: E402

# ------------------------------------------------------------------ optional extras and real data
# Locally, a test whose optional extra (nbclient, nbformat, ...) or real data set (../shared/data) is missing
# is skipped with the reason; under CI=true it FAILS instead, so nothing vanishes silently from a CI run.
CI = os.environ.get("CI", "").strip().lower() in ("1", "true", "yes")


def unavailable(reason: str):
    """Skip (locally) or fail (CI=true) the running test because ``reason``."""
    if CI:
        pytest.fail(f"{reason} -- CI=true: missing test extras or data fail the run", pytrace=False)
    pytest.skip(reason)


def _require_module(name: str):
    try:
        return __import__(name)
    except ImportError:
        unavailable(f"test extra {name!r} is not installed (pip install -e .[test])")


def _data_path(rel: str) -> Path:
    from drake_est.datasets.paths import default_data_dir
    return default_data_dir() / rel


@pytest.fixture
def require_module():
    """``require_module("nbformat")`` -> the module; skipped locally / failed under CI=true when absent."""
    return _require_module


def bench_module(name: str):
    """A fresh module object of ``benchmarks/NAME.py`` (the benchmark scripts are not a package)."""
    import importlib.util

    path = Path(__file__).resolve().parents[1] / "benchmarks" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def closed_loop_case(k: int, reference_ulps: int = 0):
    """(benchmark module, spec, log, truth) of the closed-loop benchmark's spec ``k``; ``reference_ulps``: its position
    reference moved by that many ulps (another CPU's last digits; 0: as generated, and left to the last-digits
    plugin)."""
    mod = bench_module("bench_diagnose_testbench")
    spec = mod.loop_cases(k + 1)[k]
    kw = {"reference_ulps": reference_ulps} if reference_ulps else {}
    return (mod, spec) + tuple(mod.loop_log(spec, **kw))


def closed_loop_case_where(k: int, premise, ulps=(0, 1, 2, 3, 5)):
    """(benchmark module, spec, log, truth, report) of the closed-loop spec ``k`` at the first of ``ulps`` (last digits
    of its position reference, :func:`closed_loop_case`) whose report (``diagnose(..., simulate=False).to_dict()`` with
    the switches as they stand) satisfies ``premise``; None when none does.  For a test whose premise, a state of the
    search a rule acts on, the CPU's last digits decide."""
    from drake_est.diagnose import diagnose
    for u in ulps:
        mod, spec, log, truth = closed_loop_case(k, reference_ulps=u)
        d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
        if premise(d):
            return mod, spec, log, truth, d
    return None


def closed_loop_off_and_on(k: int, switch: str, while_on=None, held=()):
    """(benchmark module, spec, truth, rule-off report, rule-on report, what ``while_on`` returned) of the closed-loop
    spec ``k`` diagnosed (``diagnose(..., simulate=False).to_dict()``) with ``core.<switch>`` False, then True;
    ``while_on(mp)`` (None: nothing) runs with the MonkeyPatch before the rule-on diagnosis, e.g. to wrap the function
    where the rule acts; ``held``: other switches of ``core`` held False in both diagnoses (a later round's rule that
    would act on the log too).  Everything patched is restored afterwards.  For a module-scoped design-log fixture."""
    import pytest
    from drake_est.diagnose import core, diagnose
    mod, spec, log, truth = closed_loop_case(k)
    mp = pytest.MonkeyPatch()
    try:
        for h in held:
            mp.setattr(core, h, False)
        mp.setattr(core, switch, False)
        off = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
        mp.setattr(core, switch, True)
        extra = while_on(mp) if while_on is not None else None
        on = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    finally:
        mp.undo()
    return mod, spec, truth, off, on, extra


def recording(name: str, record):
    """A ``while_on`` for :func:`closed_loop_off_and_on`: wraps ``core.<name>`` so that each call's
    ``record(result, args, kwargs)`` (an iterable: what to keep of that call) is appended to the list it returns."""
    def while_on(mp):
        from drake_est.diagnose import core
        seen = []
        original = getattr(core, name)

        def counted(*a, **kw):
            got = original(*a, **kw)
            seen.extend(record(got, a, kw))
            return got
        mp.setattr(core, name, counted)
        return seen
    return while_on


def load_set_aside_as_not_significant(d) -> bool:
    """Whether a report set joint 1's position load aside because a fresh re-detection of it was not significant given
    the other findings (what the seventy-third and seventy-fourth rounds' checks are about)."""
    return any(s["effect"] == "position_dependent_load" and s["joint"] == 1
               and s.get("reason", "").startswith("not significant given the other findings") for s in d["set_aside"])


def refolded_rows(pattern: str, rows: str = "rows") -> frozenset:
    """The keys whose rows a rule probe's JSONs ``benchmarks/results/PATTERN`` folded: its ``rows`` (the rule-on rows;
    ``rows_off``: the rule-off rows) that differ from the rows kept before it (each rule-on row's ``kept_row``,
    :func:`bench_diagnose_testbench.row_differences`)."""
    import json
    bench = bench_module("bench_diagnose_testbench")
    out = set()
    for f in sorted((Path(__file__).resolve().parents[1] / "benchmarks" / "results").glob(pattern)):
        d = json.loads(f.read_text())
        before = {r["k"]: (r["kept_json"], r["kept_row"]) for r in d["rows"]}
        for r in d[rows]:
            kept = {(r["family"], r["robot"], r["k"]): before[r["k"]]}
            if bench.row_differences(kept, [{a: b for a, b in r.items() if a not in ("kept_json", "kept_row")}]):
                out.add(r["k"])
    return frozenset(out)


#: the kept rows the ninety-sixth round folded (its rule-on rows that differ from the rows kept before it, lanes a-h
#: of ``benchmarks/results/diagnose_beyond_training_positions_round96_lane_*.json``) and those it folded back when its
#: switch went off (its rule-off rows that differ from the rows kept before them, every lane): earlier rounds' lanes
#: and screens were run on the rows as they were, and leave these out where they compare with today's kept rows
REFOLDED_ROUND_96 = (refolded_rows("diagnose_beyond_training_positions_round96_lane_[a-h].json")
                     | refolded_rows("diagnose_beyond_training_positions_round96_lane_*.json", "rows_off"))
#: the keys whose kept rows the ninety-eighth round folded (its rule-on rows that differ from the rows kept before
#: them): earlier rounds' screens were run on the rows as they were (17828 then named a law in time)
REFOLDED_ROUND_98 = refolded_rows("diagnose_speed_curve_adc_guarded_round98_lane_*.json")
#: the keys whose kept rows the hundredth round folded: 41128 (mended) and 16004 (the same names; no position friction
#: set aside, a shorter `unexplained` verdict), which earlier rounds' lanes and screens saw as they were.  Its lanes
#: were run again after the fold (the split costs' SVD basis), so their rule-on rows are the kept rows: the folded keys
#: are those whose rule-off rows differ from them
REFOLDED_ROUND_100 = refolded_rows("diagnose_change_refined_before_position_law_round100_lane_*.json", "rows_off")
#: the keys whose kept rows the hundred-and-first round folded (its rule-on rows that differ from the rows kept before
#: them): 36374 (mended), which earlier rounds' lanes and screens saw as it was
REFOLDED_ROUND_101 = refolded_rows("diagnose_rescue_filter_slope_round101_lane_*.json")
#: the keys whose kept rows the hundred-and-second round folded (its rule-on rows that differ from the rows kept before
#: them): 41591 (mended), which earlier rounds' lanes and screens saw as it was
REFOLDED_ROUND_102 = refolded_rows("diagnose_time_law_beside_stribeck_filter_slope_round102_lane_*.json")
#: the keys whose kept rows the hundred-and-third round folded (its rule-on rows that differ from the rows kept before
#: them): 41808 (mended: its abrupt change now ambiguous with stribeck too), which earlier rounds' lanes and screens
#: saw as it was
REFOLDED_ROUND_103 = refolded_rows("diagnose_time_law_beside_untestable_stribeck_round103_lane_*.json")
#: the keys whose kept rows the hundred-and-fourth round folded: 42666 (its energy drift set aside, the wrong name now a
#: miss of Stribeck), which earlier rounds' lanes and screens saw as it was
REFOLDED_ROUND_104 = refolded_rows("diagnose_time_law_rival_named_round104_lane_*.json")
#: the keys whose kept rows the hundred-and-fifth round folded: 43172 (mended: its abrupt change now ambiguous with
#: stribeck too), which earlier rounds' lanes and screens saw as it was
REFOLDED_ROUND_105 = refolded_rows("diagnose_time_law_beside_stribeck_both_ways_round105_lane_*.json")
#: the keys whose kept rows the hundred-and-sixth round folded: 44020 (mended: no finding, `unexplained`), 21591 (its
#: missed position friction now named) and 18768 (the same finding, fewer entries set aside and `unexplained`), which
#: earlier rounds' lanes and screens saw as they were
REFOLDED_ROUND_106 = refolded_rows("diagnose_motion_line_linear_response_round106_lane_*.json")
#: the keys whose kept rows the hundred-and-eighth round folded: 45767 (mended: its abrupt change set aside, the drift
#: alone), which earlier rounds' lanes and screens saw as it was
REFOLDED_ROUND_108 = refolded_rows("diagnose_change_beside_drift_round108_lane_*.json")


def probe_results(pattern: str):
    """(the text of docs/readme/diagnose_testbench.md, [(path, JSON)] of the probe JSONs
    ``benchmarks/results/PATTERN`` in name order, and ``differences(d)``: a probe JSON's rows, their ``kept_json`` and
    ``kept_row`` left out, against the kept rows (``bench_diagnose_testbench.row_differences``; [] when every row is
    its log's kept row)).  Each JSON must say how far it got: ``examined`` equals its ``keys_examined``."""
    import json
    root = Path(__file__).resolve().parents[1]
    bench = bench_module("bench_diagnose_testbench")
    doc = (root / "docs" / "readme" / "diagnose_testbench.md").read_text()
    out = [(f, json.loads(f.read_text())) for f in sorted((root / "benchmarks" / "results").glob(pattern))]
    for f, d in out:
        assert d["examined"] == len(d["keys_examined"]), f.name
    kept = bench.kept_rows_naming("any")

    def differences(d) -> list:
        return bench.row_differences(kept, [{k: v for k, v in r.items() if k not in ("kept_json", "kept_row")}
                                            for r in d["rows"]])
    return doc, out, differences


def probe_lanes(probe, pattern: str, lanes: str = "abc"):
    """(doc, files, examined, summary) of a rule probe's JSONs ``benchmarks/results/PATTERN`` (:func:`probe_results`),
    ``probe`` its module (``against_off``, ``against_off_row``): asserts their lanes are ``lanes`` in order (a string of
    one-letter lanes or a list of names, "z" before "za") and that
    the docs' table holds each JSON's row as --against-off-rows prints it; ``examined``: the keys examined per family,
    ``summary``: ``probe.against_off`` over them all."""
    doc, files, _ = probe_results(pattern)
    assert [f.name.rsplit("_lane_", 1)[-1][:-len(".json")] for f, _ in files] == list(lanes)
    examined = {"loop": set(), "testbench": set()}
    for f, d in files:
        assert probe.against_off_row(f.name, probe.against_off([str(f)])) in doc, f.name
        examined[d["family"]] |= set(d["keys_examined"])
    return doc, files, examined, probe.against_off([str(f) for f, _ in files])


def assert_rule_mended_only(pattern: str, files, s, k) -> None:
    """A kept rule's probe (``files`` and summary ``s`` of :func:`probe_lanes` over ``benchmarks/results/PATTERN``):
    it fired in the design log ``k`` only (or in the logs of the list ``k``, in the lanes' order), each of which lost
    its wrong name; no row gained one, lost ``unexplained``, gained a finding on a null log or stopped naming a planted
    effect outright; the missed effects did not rise; and every rule-on row is its log's kept row (``k``'s folded, or
    a fresh block's row run with the rule on)."""
    keys = list(k) if isinstance(k, (list, tuple)) else [k]
    assert [t["k"] for _, d in files for t in d["touched"]] == keys
    assert s["wrong_gained"] == s["null_findings_gained"] == s["oov_unexplained_lost"] == s["outright_lost"] == []
    assert s["wrong_lost"] == sorted(keys) and s["missed_on"] <= s["missed_off"]
    _, _, differences = probe_results(pattern)
    for f, d in files:
        assert differences(d) == [], f.name


def assert_fresh_screens(blocks) -> None:
    """Screens of fresh blocks, in order: each ``(screen JSON, size, first spec)`` of ``blocks`` lists ``size`` keys,
    none below ``first spec`` and every one above each key of the screen before it (the blocks do not overlap)."""
    prev = None
    for screen, size, first in blocks:
        keys = screen["keys_screened"]
        assert len(keys) == size, (first, len(keys))
        assert first <= min(keys), first
        if prev is not None:
            assert max(prev) < first, first
        prev = keys


def search_names(d) -> list:
    """The effects a diagnosis search ``d`` (:func:`drake_est.diagnose.core.run_diagnosis`) names: each step's effect,
    then the rivals of the steps reported ambiguous."""
    from drake_est.diagnose import competition as comp
    return [st.ext.effect for st in d.steps] + [x for st in d.steps if st.competition.get("ambiguous")
                                                for x in comp.ambiguous_rivals(st.competition)]


def nominal_candidates(effects: dict, seed: int):
    """(prep, sigma, {effect: candidate}) of an open-loop testbench log (120 s at 100 Hz, noise 0.05) of a generic
    axis: the first round's candidates against the nominal model, and the noise level the search starts from."""
    import numpy as np
    from drake_est.diagnose import core
    from drake_est.diagnose.nominal import prepare
    from drake_est.diagnose.testbench import generate
    log, _ = generate(effects, seed=seed, duration=120.0, sample_rate=100.0, noise_std=0.05)
    prep = prepare(log, robot="generic")
    model = core.Model(prep)
    fit = model.fit()
    sigma = {j: float(np.sqrt(fit.rss_val[j] / prep.joints[j].val.sum())) for j in prep.joints}
    cands = {e.effect: e for e in core._candidates(prep, model, fit, set())}
    return prep, sigma, cands


BROWSER_SHOT = Path(__file__).resolve().parents[2] / "shared" / "browser" / "shot"


def browser_shot():
    """The headless-Chromium renderer ``../shared/browser/shot`` (it needs node), or None when absent; under
    CI=true its absence fails the running test."""
    import shutil

    if BROWSER_SHOT.exists() and shutil.which("node"):
        return BROWSER_SHOT
    if CI:
        unavailable("headless browser ../shared/browser/shot not available")
    return None


@pytest.fixture
def require_browser():
    """The path of ``../shared/browser/shot``; skipped locally / failed under CI=true when absent."""
    shot = browser_shot()
    if shot is None:
        unavailable("headless browser ../shared/browser/shot not available")
    return shot


@pytest.fixture
def require_data():
    """``require_data("emps/DATA_EMPS.mat")`` -> the path under the data folder; skipped locally / failed
    under CI=true when absent."""
    def need(rel):
        p = _data_path(rel)
        if not p.exists():
            unavailable(f"real data {rel} not found under {p.parents[len(Path(rel).parts) - 1]} "
                        "(../shared/data or $DRAKE_EST_DATA)")
        return p
    return need


def pytest_configure(config):
    config.addinivalue_line("markers", "requires_data(*relpaths): real data files under ../shared/data the "
                                       "test needs (skip locally, fail under CI=true when absent)")


def pytest_runtest_setup(item):
    for mark in item.iter_markers("requires_data"):
        for rel in mark.args:
            if not _data_path(rel).exists():
                unavailable(f"real data {rel} not found (../shared/data or $DRAKE_EST_DATA)")
