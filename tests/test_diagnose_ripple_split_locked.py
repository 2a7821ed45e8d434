"""The ninety-ninth round: a named motor-position ripple is reported ambiguous with a disturbance periodic in time where
a sinusoid at the frequency locked to the held-out split explains most of its joint's nominal training residual
(core.split_locked_frequency_hz, core.split_locked_disturbance, core.mark_ripple_beside_split_locked_disturbance,
behind core.RIPPLE_BESIDE_SPLIT_LOCKED_DISTURBANCE)."""
from types import SimpleNamespace

import numpy as np
import pytest

from drake_est.diagnose import core, diagnose, nominal
from conftest import closed_loop_case


def _prep(duration=120.0, rate=1000.0, channels=None):
    """A prepared one-joint log of ``duration`` s at ``rate`` Hz, every sample used, split as prepare splits it."""
    t = np.arange(0.0, duration, 1.0 / rate)
    rows = np.arange(t.size)
    train, val = nominal.block_split(t, rows)
    jd = SimpleNamespace(t=t, rows=rows, train=train, val=val)
    return SimpleNamespace(joints={1: jd}, log=SimpleNamespace(channels=channels or {}))


def test_the_locked_frequency_is_half_the_alternation():
    prep = _prep()
    f = core.split_locked_frequency_hz(prep, 1)
    L = 119.999 / nominal.n_blocks_for(119.999)
    assert abs(f - 0.5 / L) < 1e-12 and abs(f - 0.5) < 1e-4
    # every training block starts at the same phase of a sinusoid at f: the same half of its cycle
    jd = prep.joints[1]
    s = np.sin(2 * np.pi * f * jd.t)
    assert (s[jd.train] >= -1e-6).all() and (s[jd.val] <= 1e-6).all()
    # several logs (whole logs held out): no locked frequency
    assert core.split_locked_frequency_hz(_prep(channels={"log_index": np.zeros(3)}), 1) is None
    # above 0.45 of the sampling rate (a 300 s log at 1 Hz would need 0.5 Hz): none
    assert core.split_locked_frequency_hz(_prep(duration=300.0, rate=1.0), 1) is None


def test_a_sinusoid_at_the_locked_frequency_is_found_and_others_are_not():
    prep = _prep()
    t = prep.joints[1].t
    rng = np.random.default_rng(0)
    noise = 0.1 * rng.standard_normal(t.size)
    got = core.split_locked_disturbance(prep, 1, 3.0 + np.sin(np.pi * t + 0.7) + noise)
    assert got is not None and got["share_of_training_residual"] > 0.95
    assert abs(got["frequency_hz"] - 0.5) < 1e-4 and abs(got["block_s"] - 1.0) < 1e-4
    # another frequency (not locked: the held-out blocks see its whole cycle), white noise, a ripple-like tone at 2 Hz
    assert core.split_locked_disturbance(prep, 1, np.sin(2 * np.pi * 0.7 * t) + noise) is None
    assert core.split_locked_disturbance(prep, 1, noise) is None
    assert core.split_locked_disturbance(prep, 1, np.sin(4 * np.pi * t) + noise) is None
    # under the share: a locked sinusoid that holds about a quarter of the training residual's variance (on the
    # training half-cycles only its shape counts: the constant takes its mean, 2 / pi)
    weak = np.sin(np.pi * t) + 0.5 * rng.standard_normal(t.size)
    assert core.split_locked_disturbance(prep, 1, weak) is None
    got = core.split_locked_disturbance(prep, 1, weak, min_share=0.2)
    assert got is not None and 0.2 < got["share_of_training_residual"] < 0.35


def test_spec_40305_is_ambiguous_with_the_disturbance_only_with_the_rule(monkeypatch):
    # fresh loop spec 40305: a time-periodic disturbance alone at 0.5 Hz, named a motor-position ripple outright
    mod, spec, log, _ = closed_loop_case(40305)
    for on in (False, True):
        monkeypatch.setattr(core, "RIPPLE_BESIDE_SPLIT_LOCKED_DISTURBANCE", on)
        d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
        assert [f["effect"] for f in d["findings"]] == ["motor_position_ripple"], d["findings"]
        f = d["findings"][0]
        if not on:
            assert f["status"] == "named" and mod.judge(spec, d)["wrong"] == ["motor_position_ripple"]
            continue
        assert f["ambiguous_between"] == ["motor_position_ripple", "time_periodic_disturbance"]
        c = f["competition"]["split_locked_disturbance"]
        assert abs(c["frequency_hz"] - 0.5) < 1e-3 and c["share_of_training_residual"] > 0.85
        assert "cannot judge a disturbance periodic in time" in f["competition"]["reason"]
        assert mod.judge(spec, d)["correct"]


def test_kept_and_its_table_is_its_jsons():
    """Kept: the switch is on; the screens (by preparation and the nominal fit) cover every touchable kept row,
    closed-loop (two lanes) and open-loop, and list only 40305 (whose folded row is no longer touchable); lane a
    diagnosed it, the rule marked its ripple, it lost its wrong name, and its rule-on row is its kept row; the docs'
    table holds the lane's row as --against-off-rows prints it."""
    import json
    from pathlib import Path
    from conftest import assert_rule_mended_only, bench_module, probe_lanes
    assert core.RIPPLE_BESIDE_SPLIT_LOCKED_DISTURBANCE is True
    probe = bench_module("probe_ripple_split_locked")
    root = Path(__file__).resolve().parents[1] / "benchmarks" / "results"
    screens = {x: json.loads((root / f"diagnose_ripple_split_locked_round99_screen_{x}.json").read_text())
               for x in ("0", "1", "testbench", "c", "d", "e", "f", "g", "h", "i", "j", "k", "l", "m", "n", "o", "p", "q", "r", "s", "t", "u", "v", "w", "x", "y", "z", "za", "zb", "zc", "zd", "ze", "zf", "zg")}
    loop = sorted(k for x in "01" for k in screens[x]["keys_screened"])
    assert len(loop) == 3611 and 40305 in loop and max(loop) < 40400
    # screen c: the 18 touchable rows of the fresh blocks 40400-40599, none listed
    fresh = screens["c"]["keys_screened"]
    assert len(fresh) == 18 and min(fresh) >= 40400 and max(fresh) < 40600 and screens["c"]["touched"] == []
    # screens d-zg: (logs screened, first spec of the fresh blocks), none listed; j's block refused 41886
    for x, n, first in (("d", 19, 40600), ("e", 18, 40800), ("f", 18, 41000), ("g", 18, 41200), ("h", 18, 41400),
                        ("i", 18, 41600), ("j", 17, 41800), ("k", 19, 42000), ("l", 18, 42200), ("m", 17, 42400), ("n", 16, 42600), ("o", 19, 42800), ("p", 35, 43000), ("q", 52, 43400), ("r", 18, 44000), ("s", 18, 44200), ("t", 18, 44400), ("u", 18, 44600), ("v", 18, 44800), ("w", 19, 45000), ("x", 18, 45200), ("y", 18, 45400), ("z", 18, 45600), ("za", 18, 45800), ("zb", 18, 46000), ("zc", 18, 46200), ("zd", 19, 46400), ("ze", 18, 46600), ("zf", 18, 46800), ("zg", 17, 47000)):
        assert len(screens[x]["keys_screened"]) == n and min(screens[x]["keys_screened"]) >= first, x
        assert screens[x]["touched"] == [], x
    fresh = fresh + sum((screens[x]["keys_screened"] for x in [*"defghijklmnopqrstuvwxyz", "za", "zb", "zc", "zd", "ze", "zf", "zg"]), [])     # "z" before "za"
    assert sorted(set(loop + fresh) - {40305}) == probe.touchable_keys("loop")
    assert screens["testbench"]["keys_screened"] == probe.touchable_keys("testbench")
    assert len(screens["testbench"]["keys_screened"]) == 22 and screens["testbench"]["touched"] == []
    assert all(d["refused"] == [] for d in screens.values())
    assert probe.screened_keys([root / f"diagnose_ripple_split_locked_round99_screen_{x}.json" for x in "01"]) == [40305]
    # the screens near the threshold (--min-share=0.2), run after the fresh blocks up to 41399 over every touchable
    # row as it stood: they list 22596 alone (share 0.21), which lane b diagnosed with the rule on: not marked
    near = {x: json.loads((root / f"diagnose_ripple_split_locked_round99_screen_near_{x}.json").read_text())
            for x in ("0", "1", "testbench")}
    assert all(d["min_share"] == 0.2 and d["refused"] == [] for d in near.values())
    near_loop = sorted(k for x in "01" for k in near[x]["keys_screened"])
    assert near_loop == [k for k in probe.touchable_keys("loop") if k < 41400] and len(near_loop) == 3701
    assert near["testbench"]["keys_screened"] == probe.touchable_keys("testbench")
    listed = [(k, j) for x in near for k, js in near[x]["touched"] for j in js.values()]
    assert [k for k, _ in listed] == [22596]
    assert 0.2 <= listed[0][1]["share_of_training_residual"] < core.SPLIT_LOCKED_SHARE
    doc, files, examined, s = probe_lanes(probe, "diagnose_ripple_split_locked_round99_lane_*.json", lanes="ab")
    assert files[1][1]["keys_examined"] == [22596] and files[1][1]["touched"] == []
    assert examined["loop"] == {40305, 22596} and not examined["testbench"]
    assert_rule_mended_only("diagnose_ripple_split_locked_round99_lane_*.json", files, s, 40305)
    (m,) = files[0][1]["touched"][0]["marked"]
    assert abs(m["frequency_hz"] - 0.5) < 1e-3 and m["share_of_training_residual"] >= core.SPLIT_LOCKED_SHARE
    flat = " ".join(doc.split())
    assert "The rule marked a ripple in one log of 3,633" in flat
    rule = (root / "diagnose_ripple_split_locked_round99_rule.txt").read_text()
    assert "Keep only if" in rule and "40305 loses its wrong name" in rule


def test_probe_min_share_is_checked_and_goes_with_the_screen():
    """``--min-share`` must be a share in [0, 1] and only lowers the screen's threshold: with a rule lane it is refused;
    the screen's measure carries it (and the screen's JSON records it), without it the rule's own threshold (None)."""
    from conftest import bench_module
    probe = bench_module("probe_ripple_split_locked")
    for argv, msg in ((["--min-share=x", "--screen", "OUT.json", "2"], "expected a number"),
                      (["--min-share=1.5", "--screen", "OUT.json", "2"], r"in \[0, 1\]"),
                      (["--min-share=0.2", "OUT.json", "2"], "goes with --screen")):
        with pytest.raises(SystemExit, match=msg):
            probe.main(argv)
    seen = []
    monkey = pytest.MonkeyPatch()
    try:
        monkey.setattr(probe.probe_state_check_speeds, "screen_probe_main",
                       lambda argv, *a, **kw: seen.append((argv, kw)))
        probe.main(["--min-share=0.2", "--screen", "OUT.json", "2"])
        probe.main(["--screen", "OUT.json", "2"])
    finally:
        monkey.undo()
    (argv0, kw0), (argv1, kw1) = seen
    assert argv0 == argv1 == ["--screen", "OUT.json", "2"]
    assert kw0["measure"].keywords == {"min_share": 0.2} and kw0["extra"] == {"min_share": 0.2}
    assert kw1["measure"].keywords == {"min_share": None} and "extra" not in kw1
