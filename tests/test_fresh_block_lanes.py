"""benchmarks/fresh_block_lanes.py: the kept rounds' lanes and screens a fresh closed-loop block needs."""
import json
from pathlib import Path

import pytest

from conftest import bench_module

RESULTS = Path(__file__).resolve().parents[1] / "benchmarks" / "results"


def test_letters_run_a_to_z_then_za():
    """The lanes' letters: a .. z, za .. zz, zza ..; words and digits (testbench, 0, 1) are not letters."""
    fb = bench_module("fresh_block_lanes")
    assert [fb.next_letter(x) for x in (None, "a", "m", "y", "z", "za", "zn", "zz", "zzg")] == \
        ["a", "b", "n", "z", "za", "zb", "zo", "zza", "zzh"]
    assert sorted(["zb", "z", "a", "zza", "y"], key=fb.letter_order) == ["a", "y", "z", "zb", "zza"]
    got = fb.letters("diagnose_beyond_training_positions_round96", "screen")
    assert "testbench" not in got and "0" not in got and got[:2] == ["c", "d"] and got.index("z") < got.index("za")


def test_bad_range_is_a_one_line_error(capsys):
    fb = bench_module("fresh_block_lanes")
    assert fb.main(["--start", "41400", "--end", "41400"]) == 2
    assert "--end (41400) must lie after --start (41400)" in capsys.readouterr().err
    # --end is one past the last spec: a range that does not end at a block's edge would leave specs out
    assert fb.main(["--start", "44800", "--end", "44999"]) == 2
    err = capsys.readouterr().err
    assert "must be multiples of 100" in err and "did you mean --end 45000?" in err and len(err.strip().splitlines()) == 1


def _keys(name, key):
    """The sorted ``key`` list (``keys_examined`` or ``keys_screened``) of ``benchmarks/results/<name>.json``."""
    return sorted(json.loads((RESULTS / f"{name}.json").read_text())[key])


def _assert_plan_is_what_they_saw(plan, lanes: dict, screens: dict):
    """Every round of ``lanes`` ({round: lane JSON}) plans the keys its lane examined (some), every round of
    ``screens`` ({round: [screen JSONs]}) the keys its screens screened."""
    for r, name in lanes.items():
        assert plan[r]["keys"] == _keys(name, "keys_examined") and plan[r]["keys"], r
    for r, names in screens.items():
        assert plan[r]["keys"] == sorted(k for n in names for k in _keys(n, "keys_screened")), r


@pytest.mark.long
def test_the_block_41200_41399_plan_is_what_its_lanes_and_screens_saw(tmp_path):
    """For the fresh blocks 41200-41399 (laned by hand before this script) every round's keys are the keys its lane or
    screens of that block examined; the hundred-and-first round's, whose lanes a and b took every touchable row, lie
    in them.  The letters named are those after the last JSON of each kind."""
    fb = bench_module("fresh_block_lanes")
    plan = {it["round"]: it for it in fb.block_plan(41200, 41400)}
    lanes = {100: "diagnose_change_refined_before_position_law_round100_lane_e",
             95: "diagnose_ripple_where_law_falls_round95_lane_n",
             89: "diagnose_position_friction_dissipation_round89_lane_zi",
             88: "diagnose_disturbance_stationary_round88_lane_zn",
             74: "diagnose_position_law_as_accepted_round74_lane_zzg"}
    screens = {99: ["diagnose_ripple_split_locked_round99_screen_g"],
               98: ["diagnose_speed_curve_adc_guarded_round98_screen_n"],
               96: ["diagnose_beyond_training_positions_round96_screen_zm",
                    "diagnose_beyond_training_positions_round96_screen_zn"],
               93: ["diagnose_load_untested_direction_round93_screen_y"],
               91: ["diagnose_state_check_speeds_round91_screen_ze"]}
    _assert_plan_is_what_they_saw(plan, lanes, screens)
    for r, names in screens.items():
        assert len(plan[r]["screens"]) == len(names) and plan[r]["lane_after_screens"]
    assert plan[92]["keys"] == plan[90]["keys"] == [] and plan[92]["lane"] is plan[90]["lane"] is None
    r101 = set(_keys("diagnose_rescue_filter_slope_round101_lane_a", "keys_examined")
               + _keys("diagnose_rescue_filter_slope_round101_lane_b", "keys_examined"))
    assert plan[101]["keys"] and set(plan[101]["keys"]) <= r101
    # the letters after the last JSON of each kind (later blocks were laned since, so the letters move on)
    rounds = {r.number: r for r in fb.ROUNDS}

    def after(n, kind, k=1):
        x = fb.letters(rounds[n].prefix, kind)[-1]
        for _ in range(k):
            x = fb.next_letter(x)
        return x
    for r in (102, 101, 100, 95, 89, 88, 74):
        assert plan[r]["lane"] == after(r, "lane"), r
    zq, zr = after(96, "screen"), after(96, "screen", 2)
    assert [x for x, _ in plan[96]["screens"]] == [zq, zr] and plan[96]["screens"][0][1] == "0/2"
    assert plan[91]["screens"][0][0] == plan[91]["lane"] == after(91, "screen")
    assert plan[97]["lane"] == after(97, "lane") and plan[97]["lane_of"] == 96
    first, second = fb.commands(list(plan.values()))
    assert any(f"round96_screen_{zq}.json --lane=0/2 41200 41201" in c for c in first)
    assert any(f"round97_lane_{after(97, 'lane')}.json $K" in c and f"round96_screen_{zq}.json" in c for c in second)


@pytest.mark.long
def test_the_block_41400_41599_plan_is_what_its_lanes_and_screens_saw():
    """The fresh blocks 41400-41599 were laned by this script (``--run``): every round's keys are the keys its lane or
    screens of that block examined.  The hundred-and-second round's lanes a and b took every touchable row (41591 in
    b), and round 90's lane q took 41591 after that round's fold gave it two findings set aside."""
    fb = bench_module("fresh_block_lanes")
    plan = {it["round"]: it for it in fb.block_plan(41400, 41600)}
    lanes = {101: "diagnose_rescue_filter_slope_round101_lane_d",
             100: "diagnose_change_refined_before_position_law_round100_lane_f",
             90: "diagnose_closed_rival_round90_lane_q",
             89: "diagnose_position_friction_dissipation_round89_lane_zj",
             88: "diagnose_disturbance_stationary_round88_lane_zo",
             74: "diagnose_position_law_as_accepted_round74_lane_zzh"}
    screens = {99: ["diagnose_ripple_split_locked_round99_screen_h"],
               98: ["diagnose_speed_curve_adc_guarded_round98_screen_o"],
               96: ["diagnose_beyond_training_positions_round96_screen_zo",
                    "diagnose_beyond_training_positions_round96_screen_zp"],
               93: ["diagnose_load_untested_direction_round93_screen_z"],
               91: ["diagnose_state_check_speeds_round91_screen_zf"]}
    _assert_plan_is_what_they_saw(plan, lanes, screens)
    assert plan[95]["keys"] == plan[92]["keys"] == []
    r102 = set(_keys("diagnose_time_law_beside_stribeck_filter_slope_round102_lane_a", "keys_examined")
               + _keys("diagnose_time_law_beside_stribeck_filter_slope_round102_lane_b", "keys_examined"))
    assert 41591 in plan[102]["keys"] and set(plan[102]["keys"]) <= r102
