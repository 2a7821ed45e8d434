"""``DiagnosisResult.structure_readings``: what every test of the "unexplained" verdict read on the final residual,
reported or not (``benchmarks/bench_unexplained_shares.py`` measures the tests' null tails from it)."""
from __future__ import annotations

from drake_est.diagnose import diagnose
from drake_est.diagnose.unexplained import MIN_SHARE

from conftest import bench_module


def _loop_rep(k):
    log, truth = bench_module("bench_diagnose_testbench").loop_log(k)
    return diagnose(log, robot="generic", seed=0, simulate=False), truth


def test_the_readings_give_back_the_reported_entries():
    """Loop spec 4463 (backlash, 100 Hz) ends as "none": no test passes both its p-value and its share, although the
    time shift reads p = 4e-48 on 2.7 % of the residual (below MIN_SHARE); with a 1 % share for that test alone the
    readings give it as an entry (what the twentieth round tried and did not keep)."""
    rep, truth = _loop_rep(4463)
    assert truth["effects"] == ["backlash"]
    shares = bench_module("bench_unexplained_shares")
    row = {"readings": rep.result.structure_readings}
    reported = {(u["joint"], u["variable"]) for u in rep.result.unexplained if u["variable"] != "velocity_reversals"}
    assert shares.entries(row) == reported == set()
    shift = next(r for r in rep.result.structure_readings if r["variable"] == "time_shift_torque_vs_position")
    assert shift["p_value"] < 1e-20 and 0.01 < shift["share"] < MIN_SHARE and not shift["adc_guarded"]
    assert shares.entries(row, {"time_shift_torque_vs_position": 0.01}) == {(1, "time_shift_torque_vs_position")}
    names = {r["variable"] for r in rep.result.structure_readings}
    assert {"position", "velocity", "time_correlation", "snap_excluded_samples"} <= names


def test_the_readings_of_a_reported_structure():
    """Loop spec 371 (backlash under point-to-point moves, 50 Hz): its reported time shift is among the readings with
    the same p-value and share."""
    rep, _ = _loop_rep(371)
    shares = bench_module("bench_unexplained_shares")
    row = {"readings": rep.result.structure_readings}
    reported = {(u["joint"], u["variable"]) for u in rep.result.unexplained if u["variable"] != "velocity_reversals"}
    assert (1, "time_shift_torque_vs_position") in reported
    assert shares.entries(row) == reported
    u = next(u for u in rep.result.unexplained if u["variable"] == "time_shift_torque_vs_position")
    r = next(r for r in rep.result.structure_readings if r["variable"] == "time_shift_torque_vs_position")
    assert (r["p_value"], r["share"]) == (u["p_value"], u["share_of_residual_variance"])


def test_the_docs_table_of_the_readings_is_the_kept_json():
    """The twentieth round's table of what each test read on specs 3500-4499 is printed from its kept JSON."""
    import json
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    shares = bench_module("bench_unexplained_shares")
    d = json.loads((root / "benchmarks/results/unexplained_shares_loop3500.json").read_text())
    text = (root / "docs/readme/diagnose_testbench.md").read_text()
    for line in shares.table_lines(d):
        assert line in text, line
    # the numbers the text quotes: the time-shift test's null tail, and the snap test's
    tails = d["null_tails"]
    assert tails["time_shift_torque_vs_position"]["null_max_share"] < 0.0035
    assert tails["time_shift_torque_vs_position"]["significant"]["null"] == 7 and d["kinds"]["null"] == 135
    assert 0.09 < tails["snap_excluded_samples"]["null_max_share"] < 0.095
