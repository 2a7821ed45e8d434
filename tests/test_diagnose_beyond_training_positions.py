"""The ninety-sixth round: held-out rows beyond the training positions by more than one coarsest kernel width are not
used to judge a model (``nominal.BEYOND_TRAINING_POSITIONS_RULE``;
``benchmarks/results/diagnose_beyond_training_positions_round96_rule.txt``)."""
import numpy as np
import pytest

from drake_est.diagnose import nominal
from drake_est.diagnose.report import markdown


def test_only_held_out_rows_beyond_the_margin():
    """Training positions 0-7: the margin is 1; held-out rows below -1 or above 8 are flagged, training rows and
    held-out rows within the margin never; no training rows, nothing flagged."""
    q = np.array([0.0, 7.0, 3.0, -0.5, -1.5, 8.5, 7.9, 20.0, -3.0])
    train = np.array([True, True, True, False, False, False, False, True, False])
    train[7] = False        # 20.0 held out
    got = nominal.beyond_training_positions(q, train)
    assert got.tolist() == [False, False, False, False, True, True, False, True, True]
    assert nominal.beyond_training_positions(q, train, margin=0.0).tolist() == [
        False, False, False, True, True, True, True, True, True]
    assert not nominal.beyond_training_positions(q, np.zeros(q.size, bool)).any()
    assert nominal.BEYOND_POSITIONS_MARGIN == pytest.approx(1 / 7)


@pytest.fixture(scope="module")
def design_case():
    """Fresh spec 37492 (a load at 10 Hz with Student-t noise) prepared and diagnosed with the switch off and on:
    (module, spec, truth, {False: (prep, report), True: (prep, report)})."""
    from conftest import closed_loop_case
    from drake_est.diagnose import diagnose
    from drake_est.diagnose.nominal import prepare
    mod, spec, log, truth = closed_loop_case(37492)
    mp = pytest.MonkeyPatch()
    out = {}
    try:
        for on in (False, True):
            mp.setattr(nominal, "BEYOND_TRAINING_POSITIONS_RULE", on)
            rep = diagnose(log, robot="generic", seed=0, simulate=False)
            out[on] = (prepare(log, robot="generic"), rep)
    finally:
        mp.undo()
    return mod, spec, truth, out


def test_spec_37492_names_the_load(design_case):
    """Off: an abrupt change is named (a wrong name) and every held-out row is kept. On: the 9 held-out rows beyond
    the margin are dropped, counted in report.json and said in report.md, and the load is named, ambiguous with the
    change and the level."""
    mod, spec, truth, out = design_case
    assert truth["planted"] == ["position_dependent_load"]
    (p_off, r_off), (p_on, r_on) = out[False], out[True]
    assert mod.judge(spec, r_off.to_dict())["wrong"] == ["abrupt_change"]
    assert "beyond_training_positions" not in p_off.joints[1].counts
    assert p_on.joints[1].counts["beyond_training_positions"] == 9
    assert p_off.joints[1].val.sum() - p_on.joints[1].val.sum() == 9
    assert p_off.joints[1].train.sum() == p_on.joints[1].train.sum()
    d = r_on.to_dict()
    j = mod.judge(spec, d)
    assert j["wrong"] == [] and j["missed"] == [] and j["correct"]
    assert d["data"]["excluded"]["1"]["beyond_training_positions"] == 9
    assert "9 held-out samples beyond the training positions" in markdown(d)


@pytest.mark.parametrize("on", [False, True])
def test_spec_5586_gains_a_load_with_the_rule(on):
    """Why the switch is off: loop spec 5586 (an elastic gear at 1000 Hz with Student-t noise, out of the vocabulary)
    ends `unexplained` with the rule off; on, 24 held-out rows beyond the training positions are dropped, and a
    position load (not planted) is named, ambiguous with Stribeck."""
    from conftest import closed_loop_case
    from drake_est.diagnose import diagnose
    mod, spec, log, truth = closed_loop_case(5586)
    assert truth["planted"] == ["compliance"]
    mp = pytest.MonkeyPatch()
    try:
        mp.setattr(nominal, "BEYOND_TRAINING_POSITIONS_RULE", on)
        d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    finally:
        mp.undo()
    j = mod.judge(spec, d)
    assert d["data"]["excluded"]["1"].get("beyond_training_positions", 0) == (24 if on else 0)
    if on:
        assert j["wrong"] == ["position_dependent_load"] and not j["correct"]
    else:
        assert d["findings"] == [] and d["unexplained"] and j["correct"]


def test_switched_off_after_the_full_screen_and_its_table_is_its_jsons():
    """Kept on a sample, then switched off: the sample's screens ran on every 10th kept closed-loop row (screens 0 and
    1: the keys ``--keys every 10`` gives below 38000), every open-loop row (none listed) and the kept rows of the fresh
    blocks 37400-38399 (screens c-h); the lanes a-h diagnosed every log they listed and the design logs 21436 and 25506
    (f): no wrong name gained, 37492's lost.  The full screen (screens i and j) ran on every other kept closed-loop row
    and listed 708; lanes i and j diagnosed them all: 5586 gains a wrong name, so the switch is off and the kept rows
    are the rule-off rows."""
    import json
    from pathlib import Path
    from conftest import bench_module, probe_lanes, probe_results
    assert nominal.BEYOND_TRAINING_POSITIONS_RULE is False
    probe = bench_module("probe_beyond_training_positions")
    root = Path(__file__).resolve().parents[1] / "benchmarks" / "results"
    loop_screens = ["0", "1", *"cdefghijklmnopqrstuvwxyz", "za", "zb", "zc", "zd", "ze", "zf", "zg", "zh", "zi", "zj", "zk", "zl", "zm", "zn", "zo", "zp", "zq", "zr", "zs", "zt", "zu", "zv", "zw", "zx", "zy", "zz", "zza", "zzb", "zzc", "zzd", "zze", "zzf", "zzg", "zzh", "zzi", "zzj", "zzk", "zzl", "zzm", "zzn", "zzo", "zzp", "zzq", "zzr", "zzs", "zzt", "zzu", "zzv", "zzw", "zzx", "zzy", "zzz", "zzza", "zzzb", "zzzc", "zzzd", "zzze", "zzzf", "zzzg", "zzzh", "zzzi", "zzzj", "zzzk", "zzzl", "zzzm", "zzzn"]     # "z" before "za"
    screens = {x: json.loads((root / f"diagnose_beyond_training_positions_round96_screen_{x}.json").read_text())
               for x in ["testbench", *loop_screens]}
    sample = sorted(k for x in "01" for k in screens[x]["keys_screened"])
    # drawn when the kept rows ended at 37799 (blocks appended later do not move the earlier picks)
    assert sample == [k for k in probe.every_keys(10, "loop") if k < 37800] and len(sample) == 3775
    assert screens["testbench"]["keys_screened"] == probe.kept_keys("testbench", lambda r: True)
    assert screens["testbench"]["touched"] == []
    # one stale kept row that today's preparation refuses, with the rule on and off
    assert [k for s in screens.values() for k, _ in s["refused"]] == [17787]
    fresh = sorted(k for x in "cd" for k in screens[x]["keys_screened"])
    assert len(fresh) == 598 and min(fresh) == 37400 and max(fresh) < 38000
    # every kept closed-loop row is screened (the sample's picks at 37400 and above twice: screens c-h too)
    assert sorted({k for x in loop_screens for k in screens[x]["keys_screened"]}) == probe.kept_keys(
        "loop", lambda r: True)
    full = sorted(k for x in "ij" for k in screens[x]["keys_screened"])
    assert len(full) == 33609 and max(full) < 37400
    listed = probe.screened_keys([root / f"diagnose_beyond_training_positions_round96_screen_{x}.json" for x in "01"])
    listed_fresh = probe.screened_keys([root / f"diagnose_beyond_training_positions_round96_screen_{x}.json"
                                        for x in "cd"])
    listed_full = probe.screened_keys([root / f"diagnose_beyond_training_positions_round96_screen_{x}.json"
                                       for x in "ij"])
    assert len(listed) == 90 and len(listed_fresh) == 19 and 37492 in listed_fresh and len(listed_full) == 708
    doc, files, examined, s = probe_lanes(probe, "diagnose_beyond_training_positions_round96_lane_*.json",
                                          lanes=[*"abcdefghijklmnopqrstuvwxyz", "za", "zb", "zc", "zd", "ze", "zf", "zg", "zh", "zi", "zj", "zk", "zl", "zm", "zn", "zo", "zp", "zq", "zr", "zs", "zt", "zu", "zv", "zw", "zx", "zy"])
    keys = [d["keys_examined"] for _, d in files]
    assert sorted(keys[0] + keys[1]) == listed and keys[2] == [37492]
    assert sorted(keys[3] + keys[4]) == [k for k in listed_fresh if k != 37492] and keys[5] == [21436, 25506]
    assert keys[6] == probe.screened_keys([root / f"diagnose_beyond_training_positions_round96_screen_{x}.json"
                                           for x in "ef"]) == [38002, 38051, 38066, 38098, 38156, 38168, 38171]
    assert keys[7] == probe.screened_keys([root / f"diagnose_beyond_training_positions_round96_screen_{x}.json"
                                           for x in "gh"]) and len(keys[7]) == 8
    assert sorted(keys[8] + keys[9]) == listed_full
    # screens k, l and lane k: the fresh blocks 38400-38599, run with the switch off
    fresh4 = sorted(k for x in "kl" for k in screens[x]["keys_screened"])
    assert len(fresh4) == 200 and min(fresh4) == 38400 and max(fresh4) < 38600
    assert keys[10] == probe.screened_keys([root / f"diagnose_beyond_training_positions_round96_screen_{x}.json"
                                            for x in "kl"]) and len(keys[10]) == 7
    # screens m, n and lane l: the fresh blocks 38600-38799, run with the switch off
    fresh5 = sorted(k for x in "mn" for k in screens[x]["keys_screened"])
    assert len(fresh5) == 199 and min(fresh5) == 38600 and max(fresh5) < 38800
    assert keys[11] == probe.screened_keys([root / f"diagnose_beyond_training_positions_round96_screen_{x}.json"
                                            for x in "mn"]) == [38611, 38658, 38660, 38676]
    # screens o, p and lane m: the fresh blocks 38800-38999, run with the switch off
    fresh6 = sorted(k for x in "op" for k in screens[x]["keys_screened"])
    assert len(fresh6) == 200 and min(fresh6) == 38800 and max(fresh6) < 39000
    assert keys[12] == probe.screened_keys([root / f"diagnose_beyond_training_positions_round96_screen_{x}.json"
                                            for x in "op"]) == [38878]
    # screens q, r and lane n: the fresh blocks 39000-39199, run with the switch off
    fresh7 = sorted(k for x in "qr" for k in screens[x]["keys_screened"])
    assert len(fresh7) == 200 and min(fresh7) == 39000 and max(fresh7) < 39200
    assert keys[13] == probe.screened_keys([root / f"diagnose_beyond_training_positions_round96_screen_{x}.json"
                                            for x in "qr"]) == [39044, 39080, 39133, 39142, 39156]
    # screens of two lanes each and their lane, the fresh blocks 39200-47199, run with the switch off: (screens, first
    # spec, logs screened (39983, 40401 and 40580 refused by their blocks), listed); 40444 (a load beside Stribeck at
    # 1000 Hz, lane u) is correct with the rule on, `unexplained` with it off
    fresh_lanes = [("st", 39200, 200, [39286, 39310, 39372]),
                   ("uv", 39400, 200, [39479, 39482, 39502]),
                   ("wx", 39600, 200, [39600, 39622, 39679, 39680, 39774]),
                   ("yz", 39800, 199, [39863, 39925]),
                   (("za", "zb"), 40000, 200, [40013, 40057, 40084, 40097, 40122, 40133, 40178]),
                   (("zc", "zd"), 40200, 200, [40215, 40241, 40280, 40310, 40351, 40353]),
                   (("ze", "zf"), 40400, 198, [40406, 40411, 40444, 40494, 40526]),
                   (("zg", "zh"), 40600, 200, [40629, 40637, 40664, 40680, 40734, 40779]),
                   (("zi", "zj"), 40800, 200, [40802, 40816, 40834, 40980]),
                   (("zk", "zl"), 41000, 200, [41145, 41146, 41192]),
                   (("zm", "zn"), 41200, 200, [41233, 41234, 41263, 41296, 41340]),
                   (("zo", "zp"), 41400, 200, [41429, 41447, 41495, 41506]),
                   (("zq", "zr"), 41600, 200, [41660, 41769, 41775, 41781]),
                   (("zs", "zt"), 41800, 199, [41810, 41838, 41840, 41938]),     # 41886 refused by its block
                   (("zu", "zv"), 42000, 198, [42047, 42048, 42060]),     # 42051 and 42131 refused by their blocks
                   (("zw", "zx"), 42200, 200, [42210, 42231, 42347]),
                   (("zy", "zz"), 42400, 200, [42428, 42454, 42584]),
                   (("zza", "zzb"), 42600, 200, [42628, 42672, 42740, 42764, 42784]),
                   (("zzc", "zzd"), 42800, 200, [42883, 42905]),
                   (("zze", "zzf"), 43000, 400, [43008, 43053, 43095, 43124, 43132, 43177, 43213, 43308, 43387, 43397, 43398]),
                   (("zzg", "zzh"), 43400, 598, [43499, 43500, 43510, 43689, 43697, 43705, 43717, 43931, 43982, 43984]),
                   (("zzi", "zzj"), 44000, 200, [44069, 44154]),
                   (("zzk", "zzl"), 44200, 199, [44230, 44290, 44298, 44322, 44399]),
                   (("zzm", "zzn"), 44400, 199, [44400, 44404, 44417, 44449, 44462, 44466]),
                   (("zzo", "zzp"), 44600, 200, [44615, 44659, 44677, 44679, 44744]),
                   (("zzq", "zzr"), 44800, 200, [44832, 44859, 44908, 44944, 44954, 44966, 44981]),
                   (("zzs", "zzt"), 45000, 199, [45013, 45018, 45081, 45118, 45148, 45155]),
                   (("zzu", "zzv"), 45200, 199, [45210, 45243, 45252, 45382, 45386]),
                   (("zzw", "zzx"), 45400, 200, [45514]),
                   (("zzy", "zzz"), 45600, 200, [45675, 45678, 45715, 45717, 45748, 45760]),
                   (("zzza", "zzzb"), 45800, 200, [45847, 45918, 45947, 45991]),
                   (("zzzc", "zzzd"), 46000, 200, [46043, 46046, 46071, 46109, 46117, 46138, 46150, 46195]),
                   (("zzze", "zzzf"), 46200, 200, [46214]),
                   (("zzzg", "zzzh"), 46400, 200, [46432, 46434, 46446, 46458, 46461, 46465, 46470, 46570]),
                   (("zzzi", "zzzj"), 46600, 200, [46693, 46723, 46725, 46764, 46776]),
                   (("zzzk", "zzzl"), 46800, 200, [46828, 46884, 46900, 46924, 46958, 46966, 46984, 46996]),
                   (("zzzm", "zzzn"), 47000, 200, [47066, 47074, 47113, 47152, 47176])]
    for i, (pair, first, n, lane) in enumerate(fresh_lanes, start=14):
        fresh_i = sorted(k for x in pair for k in screens[x]["keys_screened"])
        span = 600 if n > 400 else 400 if n > 200 else 200     # a pair of screens covers 200 specs (400 from 43000, 600 from 43400)
        assert len(fresh_i) == n and min(fresh_i) == first and max(fresh_i) < first + span, pair
        assert keys[i] == probe.screened_keys([root / f"diagnose_beyond_training_positions_round96_screen_{x}.json"
                                               for x in pair]) == lane, pair
    assert s["fired"] == s["examined"] == 1031
    assert s["wrong_gained"] == [5586] and s["wrong_lost"] == [37492, 47176]     # 47176: lane zy
    assert s["null_findings_gained"] == s["oov_unexplained_lost"] == []
    _, _, differences = probe_results("diagnose_beyond_training_positions_round96_lane_*.json")
    for f, d in files:
        # the kept rows are the rule-off rows (folded back)
        assert differences({"rows": d["rows_off"]}) == [], f.name
    assert "The rule dropped rows in all 111 logs of lanes a-f" in " ".join(doc.split())
    assert "One row gains a wrong name: **5586**" in " ".join(doc.split())
