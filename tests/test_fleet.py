"""Fleet pieces without a Dask cluster: change detection, store, discovery, per-log task, CLI errors."""
from __future__ import annotations

import json
import os
import sqlite3
import stat
import subprocess
import sys

import numpy as np
import pytest

from drake_est.errors import DataError
from drake_est.fleet import FleetStore, check_against_truth, detect_change, diagnose_entry, discover, synth_fleet
from drake_est.fleet.mc import child_seed, mc_map
from drake_est.fleet.run import DEFAULT_SETTINGS, parse_time
from drake_est.fleet.synth_fleet import plan_fleet
from drake_est.fleet.trends import detect_appearance, robust_sigma, trend_filter


# ----------------------------------------------------------------------------- change detection
@pytest.mark.parametrize("seed", range(5))
def test_wear_onset_dated_within_two_days(seed):
    rng = np.random.default_rng(seed)
    t = np.arange(30.0)
    d0 = int(rng.integers(6, 22))
    y = 4.0 + 0.02 * rng.standard_normal(30)
    y[d0:] *= 1.0 + 0.04 * (t[d0:] - d0)
    ch = detect_change(t, y, min_rel=0.15)
    assert ch is not None and ch.kind == "trend"
    assert abs(ch.index - d0) <= 2
    assert ch.after_end > 1.3 * ch.before


@pytest.mark.parametrize("seed", range(5))
def test_step_found_and_stationary_series_quiet(seed):
    rng = np.random.default_rng(100 + seed)
    t = np.arange(30.0)
    y = 3.0 + 0.05 * rng.standard_normal(30)
    assert detect_change(t, y, min_rel=0.15) is None
    y2 = y.copy()
    y2[17:] += 1.5
    ch = detect_change(t, y2, min_rel=0.15)
    assert ch is not None and ch.kind == "step" and ch.index == 17


def test_small_relative_change_is_not_a_warning():
    rng = np.random.default_rng(1)
    y = 4.0 + 0.005 * rng.standard_normal(30)
    y[15:] += 0.2                      # 5 %: significant but below the 15 % relevance rule
    assert detect_change(np.arange(30.0), y, min_rel=0.15) is None


def test_appearance_needs_persistence():
    t = np.arange(30.0)
    y = np.zeros(30)
    y[12] = 1.0                        # one odd finding
    assert detect_appearance(t, y) is None
    y = np.zeros(30)
    y[12:] = np.linspace(0.5, 1.5, 18)
    ch = detect_appearance(t, y)
    assert ch is not None and ch.index == 12 and ch.after_end > 2.5 * ch.after_start
    y[20] = 0.0                        # one missed log after the onset does not hide it
    assert detect_appearance(t, y).index == 12


def test_trend_filter_and_sigma():
    rng = np.random.default_rng(2)
    t = np.arange(40.0)
    y = 0.1 * t + 0.3 * rng.standard_normal(40)
    assert abs(robust_sigma(y) - 0.3) < 0.12
    tr = trend_filter(t, y)
    assert np.sqrt(np.mean((tr - 0.1 * t) ** 2)) < 0.15


# ----------------------------------------------------------------------------- store
def _result(k=0, status="ok"):
    return {"entry": {"robot_id": "robot_001", "time": f"2026-05-{k + 1:02d}", "path": "x.npz", "robot_model": "generic",
                      "joints": "1"},
            "file_sha256": f"sha{k}", "settings_hash": "h", "settings": {"seed": 0}, "software_version": "0",
            "status": status, "error": None if status == "ok" else "bad log",
            "findings": [{"effect": "motor_position_ripple", "joint": 1, "heldout_gain": 2.0, "p_value": 1e-6,
                          "parameters": {"rms_amplitude": 0.5}, "evidence": {"F": 3.0}}],
            "parameters": [{"joint": 1, "name": "coulomb_nm", "value": 4.0}]}


def test_store_records_each_result_once(tmp_path):
    with FleetStore(tmp_path / "s.db") as st:
        assert st.record(_result(0))
        assert not st.record(_result(0))          # same log, same settings: ignored
        assert st.record(_result(1, "failed"))
        assert st.counts() == {"logs": 2, "ok": 1, "failed": 1, "findings": 2, "robots": 1}
        assert st.done_keys("h") == {("robot_001", "2026-05-01", "sha0"), ("robot_001", "2026-05-02", "sha1")}
    con = sqlite3.connect(tmp_path / "s.db")      # any SQLite client reads the schema
    assert con.execute("SELECT COUNT(*) FROM parameters WHERE name='coulomb_nm'").fetchone()[0] == 2
    assert con.execute("SELECT value FROM meta WHERE key='schema_version'").fetchone()[0] == "1"
    con.close()


def test_store_refuses_read_only_and_foreign_files(tmp_path):
    p = tmp_path / "s.db"
    FleetStore(p).close()
    os.chmod(p, stat.S_IRUSR | stat.S_IRGRP)
    try:
        with pytest.raises(DataError, match="read-only"):
            FleetStore(p)
        with FleetStore(p, write=False) as st:    # reading still works
            assert st.counts()["logs"] == 0
    finally:
        os.chmod(p, stat.S_IRUSR | stat.S_IWUSR)
    bad = tmp_path / "bad.db"
    bad.write_text("not sqlite at all " * 100)
    with pytest.raises(DataError, match="not a drake_est fleet store"):
        FleetStore(bad)
    with pytest.raises(DataError, match="does not exist"):
        FleetStore(tmp_path / "none.db", write=False)


# ----------------------------------------------------------------------------- discovery and per-log task
@pytest.fixture(scope="module")
def small_fleet(tmp_path_factory):
    out = tmp_path_factory.mktemp("fleet") / "fleet"
    s = synth_fleet(out, robots=3, days=8, seed=3, n_irb140=0, duration=10.0, show_progress=False)
    return out, s


def test_synth_fleet_layout_and_truth_apart(small_fleet):
    out, s = small_fleet
    truth = json.loads(open(s["truth"]).read())
    assert not str(s["truth"]).startswith(str(out) + os.sep)     # the truth is not inside the fleet folder
    assert s["logs"] == 24 and len(discover(out)) == 24 and len(discover(out / "manifest.csv")) == 24
    assert {c["cause"] for c in truth["changes"]} == {"coulomb_wear", "motor_position_ripple"}
    assert len(truth["corrupt"]) >= 2


def test_diagnose_entry_ok_corrupt_and_unknown_model(small_fleet):
    out, s = small_fleet
    truth = json.loads(open(s["truth"]).read())
    entries = {(e["robot_id"], e["time"]): e for e in discover(out)}
    bad = truth["corrupt"][0]
    e_bad = entries[(bad["robot"], f"2026-05-{bad['day'] + 1:02d}")]
    r = diagnose_entry(e_bad, DEFAULT_SETTINGS)
    assert r["status"] == "failed" and "\n" not in r["error"] and r["error"]
    good = next(e for k, e in entries.items() if (k[0], int(k[1][-2:]) - 1) not in
                {(c["robot"], c["day"]) for c in truth["corrupt"]})
    r = diagnose_entry(good, DEFAULT_SETTINGS)
    assert r["status"] == "ok", r.get("error")
    names = {(p["joint"], p["name"]) for p in r["parameters"]}
    assert {(1, "coulomb_nm"), (2, "viscous_nms"), (1, "ripple_amplitude_nm")} <= names
    r = diagnose_entry(dict(good, robot_model="kuka_kr16"), DEFAULT_SETTINGS)
    assert r["status"] == "failed" and "unknown robot model 'kuka_kr16'" in r["error"]
    r = diagnose_entry(dict(good, time="yesterday"), DEFAULT_SETTINGS)
    assert r["status"] == "failed" and "not an ISO date" in r["error"]


def test_manifest_errors(tmp_path):
    m = tmp_path / "m.csv"
    m.write_text("robot,path\nr1,a.npz\n")
    with pytest.raises(DataError, match="missing column"):
        discover(m)
    with pytest.raises(DataError, match="does not exist"):
        discover(tmp_path / "nothing")
    (tmp_path / "empty.csv").write_text("")
    with pytest.raises(DataError, match="is empty"):
        discover(tmp_path / "empty.csv")
    assert parse_time("2026-05-12T08-30-00") == "2026-05-12T08:30:00"


def test_plan_smallest_fleet():
    """3 robots (two generic, one IRB 140): every planted change and corrupt log has a robot."""
    truth = plan_fleet(3, 8, seed=0)
    assert len(truth["changes"]) == 3 and len(truth["corrupt"]) == 2
    assert all(truth["robots"][c["robot"]]["model"] == "generic" for c in truth["corrupt"])


def test_plan_checks_sizes():
    with pytest.raises(DataError, match="--robots"):
        plan_fleet(2, 30)
    with pytest.raises(DataError, match="--days"):
        plan_fleet(10, 5)


def test_truth_check_counts_false_alarms():
    truth = {"robots": {"r1": {}, "r2": {}}, "changes": [{"robot": "r1", "joint": 1, "cause": "coulomb_wear",
                                                           "date": "2026-05-10"}]}
    w = [{"rank": 1, "robot_id": "r1", "joint": 1, "cause": "coulomb_wear", "date": "2026-05-12", "text": "a"},
         {"rank": 2, "robot_id": "r2", "joint": 2, "cause": "coulomb_wear", "date": "2026-05-03", "text": "b"}]
    chk = check_against_truth({"warnings": w}, truth)
    assert chk["found"] == 1 and chk["healthy_robot_warnings"] == 1
    w[0]["date"] = "2026-05-13"                   # 3 days off: not a match
    assert check_against_truth({"warnings": w}, truth)["found"] == 0


# ----------------------------------------------------------------------------- Monte-Carlo (in process)
def _trial(params, seed):
    rng = np.random.default_rng(seed)
    return float(params["mu"] + rng.standard_normal())


def test_mc_map_inline_seeds_depend_on_position_only():
    ps = [{"mu": k} for k in range(6)]
    a = mc_map(_trial, ps, seed=4, workers=0)
    b = mc_map(_trial, ps, seed=4, workers=0)
    assert a == b and len(set(a)) == 6
    assert mc_map(_trial, ps, seed=5, workers=0) != a
    assert child_seed(4, 2) == child_seed(4, 2) != child_seed(4, 3)
    with pytest.raises(DataError):
        mc_map(_trial, ps, workers=-1)


# ----------------------------------------------------------------------------- CLI
def _cli(*args):
    return subprocess.run([sys.executable, "-m", "drake_est", *args], capture_output=True, text=True, timeout=120)


def test_cli_errors_are_one_line(tmp_path):
    p = _cli("fleet", "report", "--store", str(tmp_path / "none.db"), "--out", str(tmp_path / "r"))
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1 and "does not exist" in p.stderr
    ro = tmp_path / "ro.db"
    FleetStore(ro).close()
    os.chmod(ro, stat.S_IRUSR)
    (tmp_path / "f" / "robot_001").mkdir(parents=True)
    (tmp_path / "f" / "robot_001" / "2026-05-01.csv").write_text("t,q1,tau1\n")
    before = (ro.read_bytes(), ro.stat().st_mtime_ns, sorted(os.listdir(tmp_path)))
    p = _cli("fleet", "diagnose", str(tmp_path / "f"), "--store", str(ro))
    assert p.returncode == 2 and "read-only" in p.stderr and "Traceback" not in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1 and p.stdout == ""
    # nothing written: same bytes, same mtime, no journal/WAL side files, no run recorded
    assert (ro.read_bytes(), ro.stat().st_mtime_ns, sorted(os.listdir(tmp_path))) == before
    with FleetStore(ro, write=False) as st:
        assert st.query("SELECT COUNT(*) FROM runs")[0][0] == 0 and st.counts()["logs"] == 0
    p = _cli("synth-fleet", "--robots", "2", "--days", "10", "--out", str(tmp_path / "sf"))
    assert p.returncode == 2 and "--robots" in p.stderr


# ----------------------------------------------------------------------------- README numbers
def test_readme_scaling_text_is_generated_from_the_measured_json():
    """docs/readme/fleet.md holds exactly what `bench_fleet.py --markdown` makes of the measured JSON."""
    from pathlib import Path

    from conftest import bench_module
    root = Path(__file__).resolve().parents[1]
    bench = bench_module("bench_fleet")
    res = json.loads((root / "benchmarks" / "results" / "fleet_scaling.json").read_text())
    doc = (root / "docs" / "readme" / "fleet.md").read_text()
    b, e = "<!-- generated by bench_fleet.py --markdown: begin -->\n", "<!-- generated by bench_fleet.py --markdown: end -->"
    assert doc[doc.index(b) + len(b):doc.index(e)] == bench.markdown(res)
    est = bench.cluster_size(0.6, 1000, 2000.0)
    assert est["workers_rounded_up"] == 1 and abs(est["store_s"] - 0.5) < 1e-12
    assert bench.cluster_size(0.6, 180000, 2000.0)["workers_rounded_up"] == 30


def test_readme_acceptance_row_holds_the_measured_json():
    """The acceptance row of docs/readme/fleet.md that names benchmarks/results/fleet_acceptance.json holds its
    numbers (logs, synthesis and diagnosis time, ok/failed, rate, planted changes found, healthy-robot warnings)."""
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    acc = json.loads((root / "benchmarks" / "results" / "fleet_acceptance.json").read_text())["acceptance"]
    doc = (root / "docs" / "readme" / "fleet.md").read_text()
    row = next(ln for ln in doc.splitlines() if "`benchmarks/results/fleet_acceptance.json`" in ln and ln.startswith("|"))
    d, ch = acc["diagnose"], acc["check"]
    assert f"| {acc['logs']:,} in {acc['synth_s']:.0f} s |" in row
    assert (f"| {d['ok']:,} ok + {d['failed']} failed (corrupt) in {d['wall_s']:.0f} s = "
            f"{d['logs'] / d['wall_s']:.2f} logs/s |") in row
    assert f"**{ch['found']}/{ch['planted']}**" in row and f"| **{ch['healthy_robot_warnings']}** (" in row
    assert f"({ch['extra_warnings_on_planted_robots']} other warnings)" in row
    assert (f"all {acc['rerun_skipped']:,} skipped" in row) == (acc["rerun_skipped"] == acc["logs"])


def test_readme_store_schema_matches_the_store(tmp_path):
    """Every table and column of the store is in the README's schema table, which lists no other table."""
    import re
    from pathlib import Path
    doc = (Path(__file__).resolve().parents[1] / "docs" / "readme" / "fleet.md").read_text()
    FleetStore(tmp_path / "s.db").close()
    con = sqlite3.connect(tmp_path / "s.db")
    try:
        tables = [r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type='table'")]
        cols = {t: [r[1] for r in con.execute(f"PRAGMA table_info({t})")] for t in tables}
    finally:
        con.close()
    rows = {m.group(1): m.group(2) for m in re.finditer(r"^\| `(\w+)` \| [^|]+ \| (.+) \|$", doc, re.M)}
    assert set(rows) == set(tables)
    for t, cs in cols.items():
        named = [c for c in re.findall(r"`(\w+)`", rows[t]) if c in cs]
        assert set(named) == set(cs), (t, set(cs) - set(named))
