"""Issue 16 on the independent generator (drake_est.diagnose.testbench): out-of-vocabulary effects end as
"unexplained" (with where the structure lies), null logs end with nothing, and the evidence tests that keep
wrong names out (time-periodic present at every speed, constant-amplitude ripple, energy LPV form)."""
from __future__ import annotations

import numpy as np
import pytest

from drake_est.diagnose import diagnose
from conftest import bench_module
from drake_est.diagnose.testbench import generate

#: closed-loop blocks whose rows the eleventh round (the snap test) changed: their tenth-round JSONs are kept as
#: *_round10.json


def _d(effects, **kw):
    log, truth = generate(effects, **kw)
    return diagnose(log, robot="generic", simulate=False).to_dict(), truth


def test_testbench_positions_not_ahead_of_torque():
    """q is the trapezoidal integral of the velocity: no built-in delay between torque and position (a
    cumulative sum put q half a sample ahead, which the time-shift test saw on every null log as a delay of
    h/2); the time-shift test finds (almost) nothing on a nearly noise-free null log."""
    from drake_est.diagnose.core import run_diagnosis
    from drake_est.diagnose.unexplained import _time_shift
    log, _ = generate({}, seed=2, duration=60, sample_rate=50, noise_std=1e-4)
    res = run_diagnosis(log, robot="generic")
    p, share, shift = _time_shift(res.prep, res.final_fit, 1)[:3]
    assert share < 0.05          # with q = cumsum(v) h it was about 0.45
    log, _ = generate({"delay": 1.0}, seed=2, duration=60, sample_rate=50, noise_std=1e-4)
    res = run_diagnosis(log, robot="generic")
    p, share, shift = _time_shift(res.prep, res.final_fit, 1)[:3]
    assert share > 0.3 and p < 1e-6


def test_delay_is_unexplained_with_its_shift():
    d, truth = _d({"delay": 1.0}, seed=11, duration=120, sample_rate=100)
    assert d["findings"] == []
    shift = [u for u in d["unexplained"] if u["variable"] == "time_shift_torque_vs_position"]
    assert shift, d["unexplained"]
    assert shift[0]["share_of_residual_variance"] > 0.08
    # the delay itself: the torque missing at each velocity reversal is 2 kc d (the time-shift test now leaves
    # the reversals out, and its best shift is a weak estimate on the smooth stretches)
    rev = [u for u in d["unexplained"] if u["variable"] == "velocity_reversals"]
    assert rev and rev[0]["where"].startswith("torque missing"), d["unexplained"]
    assert rev[0]["coulomb_step_equivalent_s"] == pytest.approx(truth["delay"]["seconds"], abs=0.011)


def test_backlash_is_unexplained_not_named():
    d, _ = _d({"backlash": 1.0}, seed=19, duration=120, sample_rate=50, noise="student_t")
    assert d["findings"] == []
    assert d["unexplained"], "backlash left no structure"


@pytest.mark.parametrize("noise", ["gaussian", "student_t", "quantized"])
def test_null_logs_end_empty(noise):
    d, _ = _d({}, seed=5, duration=90, sample_rate=50, noise=noise, noise_std=0.05)
    assert d["findings"] == [] and d["unexplained"] == [], (d["findings"], d["unexplained"])


def test_null_log_at_10hz_no_left_out_sample_tests():
    """At 10 Hz the derivative window (7 samples, 0.7 s) smooths the accelerations away: the jerk and
    time-shift tests do not run and the null log stays clean."""
    d, _ = _d({}, seed=1059, duration=300, sample_rate=10, noise="quantized", noise_std=0.0803)
    assert d["unexplained"] == []


def test_present_at_all_speeds():
    from drake_est.diagnose.detectors import present_at_all_speeds
    rng = np.random.default_rng(0)
    n = 4000
    v = np.repeat([0.1, 0.3, 0.6, 1.2], n // 4) * rng.choice([-1, 1], n)
    t = np.arange(n) * 0.01
    C = np.column_stack([np.cos(2 * np.pi * 3 * t), np.sin(2 * np.pi * 3 * t)])
    e = 0.05 * rng.standard_normal(n)
    assert present_at_all_speeds(C, v, e + 0.1 * C[:, 0])              # everywhere: a disturbance
    only_fast = np.abs(v) > 1.0
    assert not present_at_all_speeds(C, v, e + 0.3 * C[:, 0] * only_fast)   # one speed bin only
    assert present_at_all_speeds(C, np.full(n, 0.5), e + 0.3 * C[:, 0] * only_fast)  # one speed: untestable


def test_constant_amplitude_ripple_named_not_position_load():
    """Ripple + Stribeck on a quantized torque: the ripple (constant amplitude) was fitted with 8 amplitude
    functions per component and lost to a 64-kernel position load (a wrong name)."""
    d, _ = _d({"motor_position_ripple": 1.0, "stribeck": 1.0, "_vs": 0.1}, seed=1092, duration=120,
              sample_rate=50, noise="quantized", noise_std=0.0248)
    names = {f["effect"] for f in d["findings"]}
    assert "position_dependent_load" not in names
    assert "motor_position_ripple" in names


@pytest.mark.slow
def test_energy_drift_not_named_abrupt_change():
    """The planted warm-up lowers Coulomb and viscous friction; the LPV energy term (9.29) takes both."""
    d, _ = _d({"energy_dependent_friction": 1.0}, seed=1007, duration=600, sample_rate=50, noise="student_t",
              noise_std=0.039)
    names = [f["effect"] for f in d["findings"]]
    assert names[0] == "energy_dependent_friction"
    assert "abrupt_change" not in names and "time_periodic_disturbance" not in names
    assert "gain_k_e_viscous" in d["findings"][0]["parameters"]


def test_change_point_after_energy_must_beat_a_smooth_drift():
    """After the energy drift is in the model its misfit is smooth in time; a step that only corrects it
    (here kc 2.20 -> 2.19 at t = 421 s) is not an abrupt change."""
    d, _ = _d({"energy_dependent_friction": 1.0}, seed=1028, duration=600, sample_rate=10, noise="student_t",
              noise_std=0.0412)
    names = [f["effect"] for f in d["findings"]]
    assert names == ["energy_dependent_friction"], names


def test_abrupt_change_with_position_friction_still_named():
    d, _ = _d({"position_dependent_friction": 1.0, "abrupt_change": 1.0}, seed=1052, duration=120,
              sample_rate=50, noise="gaussian", noise_std=0.05)
    names = {f["effect"] for f in d["findings"]}
    assert names == {"position_dependent_friction", "abrupt_change"}, names


def test_readme_testbench_counts_are_the_measured_ones():
    """The README's per-family table (testbench, loop, synth/generic, synth/irb140, all) holds the counts that
    the benchmark's summarize() gives for the kept JSON (readme_table renders the lines)."""
    import json
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    mod = bench_module("bench_diagnose_testbench")
    s = mod.summarize(json.loads((root / "benchmarks" / "results" / "diagnose_testbench.json").read_text())["rows"])
    readme = (root / "docs" / "readme" / "diagnose_testbench.md").read_text()
    for line in mod.readme_table(s):
        assert line in readme, line
    fams = {r.get("family", "testbench") for r in s["rows"]}
    assert sum(f["logs"] for f in s["per_family"].values()) == s["logs"]
    # the history table: the first round's testbench-only run and this JSON's testbench family
    r1 = mod.summarize(json.loads((root / "benchmarks" / "results" / "diagnose_testbench_round1.json").read_text())["rows"])
    assert (f"| final code of the first round, after item 6 (`diagnose_testbench_round1.json`) | {r1['correct']} | "
            f"{r1['wrong_names']} | {r1['missed']} | {r1['oov_unexplained_right']} / {r1['oov_logs']} | "
            f"{r1['null_logs_clean']} / {r1['null_logs']} |") in readme
    # the second round's JSON: its testbench row and its loop family, quoted by the third round's section
    r2 = mod.summarize(json.loads((root / "benchmarks" / "results" / "diagnose_testbench_round2.json").read_text())["rows"])
    t2, l2 = r2["per_family"]["testbench"], r2["per_family"]["loop"]
    assert (f"(testbench family of `diagnose_testbench_round2.json`) | {t2['correct']} | {t2['wrong_names']} | "
            f"{t2['missed']} | {t2['oov_unexplained_right']} / {t2['oov_logs']} | "
            f"{t2['null_logs_clean']} / {t2['null_logs']} |") in readme
    assert (f"{l2['correct']} / {l2['logs']} correct, {l2['wrong_names']} wrong names, {l2['missed']} missed"
            in " ".join(readme.split()))
    # the ambiguity table of the open-loop and closed-loop families, fourth round's JSON and this one
    for f in ("diagnose_testbench_round4.json", "diagnose_testbench_round5.json", "diagnose_testbench_round6.json",
              "diagnose_testbench_round7.json", "diagnose_testbench_round8.json", "diagnose_testbench_round9_first.json",
              "diagnose_testbench_round11.json", "diagnose_testbench_round12.json", "diagnose_testbench_round13.json",
              "diagnose_testbench_round14.json", "diagnose_testbench.json"):
        h = mod.summarize(json.loads((root / "benchmarks" / "results" / f).read_text())["rows"])
        for fam in ("testbench", "loop"):
            assert mod.ambiguity_line(f"{fam} family of `{f}`", h["per_family"][fam]) in readme, (f, fam)
    # the sixth to eighth rounds' tables of the "unexplained" verdict: every family / block, the fifth to eighth
    # rounds' JSONs (the fresh blocks from 700 on: the runs each was given)
    # (the closed-loop blocks' rows: test_every_closed_loop_block_row_in_the_docs_is_its_json)
    for r in ("_round5", "_round6", "_round7", "_round8", "_round9_first", "_round11", "_round12", "_round13", "_round14", ""):
        f = f"diagnose_testbench{r}.json"
        h = mod.summarize(json.loads((root / "benchmarks" / "results" / f).read_text())["rows"])
        for fam in ("testbench", "loop", "synth/generic", "synth/irb140"):
            line = mod.unexplained_line(f"{fam} family of `{f}`", h["per_family"][fam])
            assert line in readme, line
    # the third to seventh rounds' JSONs: their testbench rows
    for f in ("diagnose_testbench_round3.json", "diagnose_testbench_round4.json", "diagnose_testbench_round5.json",
              "diagnose_testbench_round6.json", "diagnose_testbench_round7.json", "diagnose_testbench_round8.json",
              "diagnose_testbench_round9_first.json", "diagnose_testbench_round11.json",
              "diagnose_testbench_round12.json", "diagnose_testbench_round13.json",
              "diagnose_testbench_round14.json"):
        r3 = mod.summarize(json.loads((root / "benchmarks" / "results" / f).read_text())["rows"])
        t3 = r3["per_family"]["testbench"]
        assert (f"(testbench family of `{f}`) | {t3['correct']} | {t3['wrong_names']} | "
                f"{t3['missed']} | {t3['oov_unexplained_right']} / {t3['oov_logs']} | "
                f"{t3['null_logs_clean']} / {t3['null_logs']} |") in readme
    if "testbench" in fams:
        t = s["per_family"]["testbench"]
        assert (f"(testbench family of `diagnose_testbench.json`) | **{t['correct']}** | **{t['wrong_names']}** | "
                f"{t['missed']} | **{t['oov_unexplained_right']} / {t['oov_logs']}** | "
                f"**{t['null_logs_clean']} / {t['null_logs']}** |") in readme


def test_every_closed_loop_block_row_in_the_docs_is_its_json():
    """Every table row of docs/readme/diagnose_testbench.md that names a closed-loop block JSON
    (``diagnose_testbench_loop_heldout*.json``: a run row, a row of the "unexplained" table or of the ambiguity
    table) holds the counts that summarize() gives for that JSON, and every such JSON kept in benchmarks/results
    has a run row, a row in the "unexplained" table and one in the ambiguity table or is named in a run row only
    (the older rounds)."""
    import json
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    mod = bench_module("bench_diagnose_testbench")
    readme = (root / "docs" / "readme" / "diagnose_testbench.md").read_text()
    cache = {}

    def summary(f):
        if f not in cache:
            cache[f] = mod.summarize(json.loads((root / "benchmarks" / "results" / f).read_text())["rows"])
        return cache[f]

    pat = re.compile(r"`(diagnose_testbench_loop_heldout\d*(?:_[a-z0-9_]+)?\.json)`")
    run_rows = set()
    n_rows = 0
    for line in (x.strip() for x in readme.splitlines()):
        if not line.startswith("| "):
            continue
        m = pat.search(line)
        if m is None:
            continue
        f = m.group(1)
        h = summary(f)
        n_rows += 1
        m_run = re.match(r"^\| (.+) \(`" + re.escape(f) + r"`\) \| ", line)
        if m_run:
            label = m_run.group(1)
            assert line == (f"| {label} (`{f}`) | {h['logs']} | {h['correct']} | {h['wrong_names']} | {h['missed']} | "
                            f"{h['oov_unexplained_right']} / {h['oov_logs']} | {h['null_logs_clean']} / "
                            f"{h['null_logs']} |"), line
            run_rows.add(f)
        else:
            assert line in (mod.unexplained_line(f"`{f}`", h), mod.ambiguity_line(f"`{f}`", h)), line
        m_rows = {r["k"] for r in h["rows"]}
        lo = re.search(r"heldout(\d+)", f)
        lo = int(lo.group(1)) if lo else 100
        assert m_rows <= set(range(lo, lo + 100)), f
    kept = sorted(p.name for p in (root / "benchmarks" / "results").glob("diagnose_testbench_loop_heldout*.json"))
    assert n_rows > len(kept)
    assert set(kept) <= run_rows, sorted(set(kept) - run_rows)
    # the ambiguity table holds every block JSON, the "unexplained" table every one from the fifth round on
    amb = {f for f in kept if mod.ambiguity_line(f"`{f}`", summary(f)) in readme}
    assert amb == set(kept), sorted(set(kept) - amb)
    early = re.compile(r"_round[234]\.json$|_round5_first\.json$")
    une = {f for f in kept if mod.unexplained_line(f"`{f}`", summary(f)) in readme}
    assert {f for f in kept if not early.search(f)} <= une, sorted({f for f in kept if not early.search(f)} - une)


def test_summarize_counts_per_family():
    """Rows of several families: the per-family counts add up to the overall ones, synth splits by robot, and a
    not-visible effect is shown in the truth label."""
    mod = bench_module("bench_diagnose_testbench")
    base = {"wrong": [], "missed": [], "oov_unexplained": True, "correct": True, "seconds": 1.0}
    rows = [dict(base, k=0, truth="none", got="none"),
            dict(base, k=0, family="loop", truth="stribeck", got="abrupt_change", wrong=["abrupt_change"],
                 missed=["stribeck"], correct=False),
            dict(base, k=0, family="synth", robot="generic", truth="none", got="none"),
            dict(base, k=0, family="synth", robot="irb140", truth="none", got="unexplained")]
    s = mod.summarize(rows)
    assert list(s["per_family"]) == ["testbench", "loop", "synth/generic", "synth/irb140"]
    assert s["correct"] == 3 and s["wrong_names"] == 1 and s["null_logs_clean"] == 2 and s["null_logs"] == 3
    assert s["per_family"]["loop"]["wrong_name_cases"][0]["truth"] == "stribeck"
    assert sum(f["correct"] for f in s["per_family"].values()) == s["correct"]
    assert mod._label({"stribeck": 1, "_vs": 0.1}, {"stribeck": "tiny"}) == "none (not visible: stribeck)"
    table = mod.readme_table(s)
    assert table[-1].startswith("| all | 4 | 3 | 1 | 1 |")


def test_untestable_effects_reads_the_reports_entries():
    """untestable_effects: the vocabulary effects whose next_experiment entry says "untestable", nothing from
    entries about ambiguities, one speed level or the residual tests."""
    mod = bench_module("bench_diagnose_testbench")
    d = {"next_experiment": [
        {"reason": "stribeck with vs below 0.0123 per s untestable: the slowest selected speed is 0.0246 per s"},
        {"reason": "asymmetric_coulomb untestable: joint 1 holds 3 of its 400 selected training samples"},
        {"reason": "ambiguous between stribeck and abrupt_change"},
        {"reason": "one speed only: position-periodic and time-periodic cannot be told apart"},
        {"reason": "structure outside the vocabulary (a delay ...) is only partly testable at 10 Hz"}]}
    assert mod.untestable_effects(d) == ["asymmetric_coulomb", "stribeck"]
    assert mod.untestable_effects({"next_experiment": []}) == []


def test_row_of_a_missed_stribeck_law_at_10hz_records_it_untestable():
    """Closed-loop spec 26730, Stribeck at 10 Hz (a multisine: the selection's speed bound is half the top speed):
    missed, and its row records that the report declares Stribeck untestable (and names the experiment)."""
    mod = bench_module("bench_diagnose_testbench")
    rows = []
    mod._run_family("loop", [mod.loop_cases(26731)[26730]], rows, 26730)
    assert rows[0]["truth"] == "stribeck" and rows[0]["missed"] == ["stribeck"] and not rows[0]["wrong"]
    assert rows[0]["untestable"] == ["stribeck"]


def test_rerun_kept_selects_rows_and_lists_what_differs(tmp_path):
    """--rerun-kept: kept_jsons skips earlier rounds' copies, kept_rows_naming selects the rows whose truth or
    finding names the effect, and row_differences lists a changed outcome (unexplained compared as a set), not an
    unchanged row nor a row that was not kept."""
    import json

    mod = bench_module("bench_diagnose_testbench")
    base = {"family": "loop", "robot": "generic", "sample_rate": 100.0, "wrong": [], "missed": [],
            "oov_unexplained": True, "correct": True, "unexplained": ["time", "jerk_excluded_samples"]}
    rows = [dict(base, k=3, truth="time_periodic_disturbance", got="time_periodic_disturbance"),
            dict(base, k=4, truth="stribeck", got="ambiguous(time_periodic_disturbance|motor_position_ripple)"),
            dict(base, k=5, truth="stribeck", got="stribeck"),
            dict(base, k=6, truth="stribeck", got="stribeck", set_aside=["time_periodic_disturbance"])]
    (tmp_path / "diagnose_testbench_loop_heldout9.json").write_text(json.dumps({"rows": rows}))
    (tmp_path / "diagnose_testbench_loop_heldout9_round15.json").write_text(json.dumps({"rows": rows}))
    assert [f.name for f in mod.kept_jsons(tmp_path)] == ["diagnose_testbench_loop_heldout9.json"]
    kept = mod.kept_rows_naming("time_periodic_disturbance", tmp_path)
    # a row that names the effect only among its set-aside findings is selected too
    assert sorted(kept) == [("loop", "generic", 3), ("loop", "generic", 4), ("loop", "generic", 6)]
    assert len(mod.kept_rows_naming("any", tmp_path)) == 4
    assert mod.kept_rows_naming("any", tmp_path, sample_rate=10.0) == {}
    again = [dict(rows[0], unexplained=["jerk_excluded_samples", "time"]),
             dict(rows[1], got="stribeck", correct=True, unexplained=["time"]),
             dict(base, k=7, truth="none", got="stribeck", correct=False)]
    diffs = mod.row_differences(kept, again)
    assert diffs == [{"json": "diagnose_testbench_loop_heldout9.json", "family": "loop", "robot": "generic", "k": 4,
                      "got": ["ambiguous(time_periodic_disturbance|motor_position_ripple)", "stribeck"],
                      "unexplained": [["jerk_excluded_samples", "time"], ["time"]]}]
    # two lanes' JSONs merged with --from-json: one summary of the same shape, lanes named, differences kept
    lanes = []
    for i, (rr, dd) in enumerate([(again[:1], []), (again[1:2], diffs)]):
        f = tmp_path / f"lane{i}.json"
        f.write_text(json.dumps(mod._rerun_summary("time_periodic_disturbance", None, f"{i}/2", rr, [], dd)))
        lanes.append(str(f))
    merged = mod.main(["--from-json", ",".join(lanes), "--json", str(tmp_path / "merged.json")])
    assert merged["logs"] == 2 and merged["lane"] == "0/2+1/2" and merged["differences"] == diffs
    assert json.loads((tmp_path / "merged.json").read_text())["differences"] == diffs


def test_sixteenth_round_rerun_numbers_are_its_json():
    """The docs' count of kept rows diagnosed again by --rerun-kept and of those that differ come from its JSON, and
    every differing spec is named there."""
    import json
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    doc = " ".join((root / "docs" / "readme" / "diagnose_testbench.md").read_text().split())
    d = json.loads((root / "benchmarks" / "results" / "diagnose_rerun_kept_time_periodic_round16.json").read_text())
    assert d["logs"] == len(d["rows"]) and d["effect"] == "time_periodic_disturbance"
    assert f"**{d['logs']} kept rows, {len(d['differences'])} differing**" in doc
    for x in d["differences"]:
        assert f"spec {x['k']}" in doc and f"`{x['json']}`" in doc
    # the 10 Hz rows: the differences are labels and entries, none in what is correct, wrong or missed
    d = json.loads((root / "benchmarks" / "results" / "diagnose_rerun_kept_10hz_round16.json").read_text())
    assert d["logs"] == len(d["rows"]) and d["sample_rate"] == 10.0
    assert {r["sample_rate"] for r in d["rows"]} == {10.0}
    assert f"**{d['logs']} kept rows, {len(d['differences'])} differing**, none in what is correct" in doc
    for x in d["differences"]:
        assert not set(x) & {"correct", "wrong", "missed", "oov_unexplained"}, x
        assert str(x["k"]) in doc


def test_lowrate_unexplained_table_is_the_measured_one():
    """The docs' table of the "unexplained" verdict by sample rate holds the rows that
    benchmarks/bench_unexplained_lowrate.py --markdown prints for the kept JSONs."""
    import json
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    mod = bench_module("bench_unexplained_lowrate")
    doc = (root / "docs" / "readme" / "diagnose_testbench.md").read_text()
    lines = []
    for f in ("unexplained_lowrate_10hz.json", "unexplained_lowrate_50_250hz.json"):
        lines += mod.markdown_rows(json.loads((root / "benchmarks" / "results" / f).read_text()))
    assert len(lines) == 3
    for line in lines:
        assert line in doc, line


def test_the_roadmaps_wrong_names_are_those_of_the_kept_jsons():
    """The roadmap's "no wrong name on ... the closed-loop generator's specs 0-N except spec ..." is read off the kept
    benchmark JSONs (every row of every kept run, each with the latest code that ran it)."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    mod = bench_module("bench_diagnose_testbench")
    kept = mod.kept_rows_naming("any")
    wrong = sorted((fam, k) for (fam, _, k), (_, r) in kept.items() if r.get("wrong"))
    last = max(k for fam, _, k in kept if fam == "loop")
    text = " ".join((root / "docs" / "readme" / "_roadmap.md").read_text().split())
    m = re.search(r"closed-loop generator's specs 0-(\d+)(?: except spec(?:s)? ([\d, and]+?))? \(", text)
    assert m, "the roadmap's wrong-name sentence moved"
    assert int(m.group(1)) == last
    assert [("loop", int(x)) for x in re.findall(r"\d+", m.group(2) or "")] == [w for w in wrong if w[0] == "loop"]
    assert not [w for w in wrong if w[0] != "loop"]    # "no wrong name on the open-loop testbench ... synth"


def test_eighteenth_round_numbers_are_its_jsons():
    """The eighteenth round's counts: the kept logs the one-level rule touches (found by preparing every kept log),
    the rerun of those, and the rerun of the rule tried without the one-level condition."""
    import json
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    res = root / "benchmarks" / "results"
    doc = " ".join((root / "docs" / "readme" / "diagnose_testbench.md").read_text().split())
    t = json.loads((res / "diagnose_kept_beyond_training_speeds_round18.json").read_text())
    assert t["count"] == "beyond_training_speeds" and not t["refused"]
    assert f"of the {t['logs']:,} kept rows, **{len(t['touched'])} logs**" in doc
    d = json.loads((res / "diagnose_rerun_kept_one_level_round18.json").read_text())
    assert sorted((f, k) for f, k, _ in t["touched"]) == sorted((r["family"], r["k"]) for r in d["rows"])
    assert f"**{d['logs']} kept rows, {len(d['differences'])} differing**" in doc
    diff = {x["k"]: x for x in d["differences"]}
    assert diff[2122]["wrong"] == [["position_dependent_load"], []]
    assert diff[981]["correct"] == [True, False]
    a = json.loads((res / "diagnose_rerun_kept_10hz_beyond_training_any_spread_round18.json").read_text())
    assert f"**{a['logs']} kept rows, {len(a['differences'])} differing**" in doc
    assert {x["k"]: x for x in a["differences"]}[195]["wrong"] == [[], ["position_dependent_load"]]
    # the second change: the rerun of the kept rows naming an asymmetric level, and the seventeenth round's code on
    # the differing ones (the rows that code gives the same here are this CPU's)
    r = json.loads((res / "diagnose_rerun_kept_asymmetric_round18.json").read_text())
    assert f"**{r['logs']} kept rows, {len(r['differences'])} differing**" in doc
    old = {x["k"]: x for x in json.loads(
        (res / "diagnose_rerun_kept_asymmetric_differing_seventeenth_code_round18.json").read_text())["rows"]}
    new = {x["k"]: x for x in r["rows"]}
    fields = ("got", "correct", "wrong", "missed", "oov_unexplained", "unexplained")
    cpu = sorted(k for k in old if all(old[k].get(f) == new[k].get(f) for f in fields))
    assert cpu == [1749, 2057, 2697, 2805, 3091, 3137, 3201]
    assert "The other seven (" + ", ".join(map(str, cpu)) + ") are this CPU's" in doc
    assert sorted({x["k"] for x in r["differences"]} - set(cpu)) == [1661, 2079, 3840]
    # every kept row of specs 0-3899: none names a cause that was not planted
    kept = bench_module("bench_diagnose_testbench").kept_rows_naming("any")
    k3899 = [row for (fam, _, k), (_, row) in kept.items() if fam != "loop" or k < 3900]
    # ... (from the thirty-seventh round's rerun to the fifty-fourth, 2406, whose kept row had gone stale, was one;
    # 1627, stale too, was mended in the thirty-ninth round)
    assert f"of the {len(k3899):,} kept rows of specs 0-3899" in doc
    assert sorted(x["k"] for x in k3899 if x.get("wrong")) == [] and "fifty-fourth one did: 2406" in doc


def test_the_results_row_is_read_off_the_kept_jsons():
    """The README's "Results at a glance" row of this benchmark is results_row() of the kept JSONs (not typed), and
    the roadmap's "specs 0-N" is the same N."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    row = bench_module("bench_diagnose_testbench").results_row()
    assert row in (root / "docs" / "readme" / "_results.md").read_text().splitlines()
    n = re.search(r"closed-loop axis, specs 0-(\d+)", row).group(1)
    assert f"generator's specs 0-{n} " in " ".join((root / "docs" / "readme" / "_roadmap.md").read_text().split())
