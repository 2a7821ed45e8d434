"""The hundred-and-sixth round: the free function of the state that a time-periodic candidate at a line of the motion
must beat is also offered a free linear response to the joint's acceleration (``core.motion_line_state_extra``,
``core.motion_line_state_test``, ``core.MOTION_LINE_LINEAR_RESPONSE_RULE``; rule file
``benchmarks/results/diagnose_motion_line_linear_response_round106_rule.txt``)."""
import json
from types import SimpleNamespace

import numpy as np
import pytest

from drake_est.diagnose import competition as comp
from drake_est.diagnose import core

RULE = "MOTION_LINE_LINEAR_RESPONSE_RULE"


def _prep(n=400, dt=0.01, seed=0):
    """A prepared log's joint 1 as far as the linear response reads it."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    a = rng.standard_normal(n)
    rows = np.ones(n, bool)
    rows[:7] = False
    return SimpleNamespace(joints={1: SimpleNamespace(t=t, a=a, rows=rows)})


def test_the_extra_block_is_the_linear_response_only_with_the_rule(monkeypatch):
    """Off: nothing offered.  On: one block, ``linear_response``, the columns of ``core.linear_response_nuisance``
    at the joint's used rows."""
    prep = _prep()
    monkeypatch.setattr(core, RULE, False)
    assert core.motion_line_state_extra(prep, 1) is None
    monkeypatch.setattr(core, RULE, True)
    got = core.motion_line_state_extra(prep, 1)
    assert list(got) == ["linear_response"]
    np.testing.assert_array_equal(got["linear_response"], core.linear_response_nuisance(prep, 1))
    assert got["linear_response"].shape == (393, core.LINEAR_RESPONSE_TAPS)


@pytest.mark.parametrize("rule", [False, True])
def test_the_state_test_offers_the_block_and_caches_the_function_per_joint(monkeypatch, rule):
    """The state's function is built once per joint and round (``state``), offered the rule's block, and the
    candidate is tested given it."""
    monkeypatch.setattr(core, RULE, rule)
    built, tested = [], []

    def state_nuisance(prep, model, j, solve=None, after=None, **kw):
        assert "extra" not in kw          # offered after the state's blocks, not among them
        built.append((j, None if after is None else sorted(after)))
        return np.full((5, 2), float(j))

    def survives(prep, model, fit, ext, alpha, min_gain, nuisance=None, solve=None):
        tested.append((ext.joint, nuisance[0, 0]))
        return {"significant": False, "rmse_reduction": 0.001}

    monkeypatch.setattr(comp, "state_nuisance", state_nuisance)
    monkeypatch.setattr(comp, "survives_state_law", survives)
    monkeypatch.setattr(core, "motion_line_state_extra",
                        lambda prep, j: {"linear_response": np.zeros((5, 1))} if core.MOTION_LINE_LINEAR_RESPONSE_RULE
                        else None)
    state = {}
    for j in (1, 1, 2):
        ext = SimpleNamespace(joint=j)
        assert core.motion_line_state_test(None, None, None, ext, core.ALPHA, core.MIN_GAIN, state)["significant"] \
            is False
    assert built == [(1, ["linear_response"] if rule else None), (2, ["linear_response"] if rule else None)]
    assert tested == [(1, 1.0), (1, 1.0), (2, 2.0)]
    assert sorted(state) == [1, 2]


def test_blocks_offered_after_keep_the_functions_own_choice(monkeypatch):
    """``state_nuisance(after=...)``: the blocks chosen without the late ones are all kept, in their order, and a late
    block joins only where it lowers the held-out error further."""
    rng = np.random.default_rng(7)
    n = 2000
    X = np.column_stack([rng.standard_normal(n), np.sign(rng.standard_normal(n))])
    A = rng.standard_normal((n, 2))
    Lr = A[:, :1] + 0.3 * rng.standard_normal((n, 1))           # close to A's first column
    eps = 0.05 * rng.standard_normal(n)
    y = X @ [0.5, 1.0] + A @ [1.0, 0.5] + 0.8 * Lr[:, 0] + eps
    train = np.arange(n) % 2 == 0
    bad = np.where(train, eps, -eps)[:, None]                   # fits the training noise, predicts its opposite
    prep = SimpleNamespace(robot_kind="generic", joints={1: SimpleNamespace(y=y, train=train, val=~train)})
    model = SimpleNamespace(design_with_shared=lambda j: X)
    monkeypatch.setattr(comp, "state_blocks", lambda prep, j, kernels=None: {"load": A})
    chosen0, chosen1, chosen2, chosen3 = [], [], [], []
    N0 = comp.state_nuisance(prep, model, 1, chosen=chosen0)
    N1 = comp.state_nuisance(prep, model, 1, chosen=chosen1, after={"linear_response": Lr})
    assert chosen0 == ["load"] and chosen1 == ["load", "linear_response"]
    np.testing.assert_array_equal(N1[:, :N0.shape[1]], N0)
    np.testing.assert_array_equal(N1[:, N0.shape[1]:], Lr)
    N3 = comp.state_nuisance(prep, model, 1, chosen=chosen3, after={"noise": bad})
    assert chosen3 == ["load"] and N3.shape == N0.shape        # a block that does not help is not joined
    comp.state_nuisance(prep, model, 1, chosen=chosen2, extra={"linear_response": Lr})
    assert sorted(chosen2) == ["linear_response", "load"]
    with pytest.raises(ValueError, match="already a state block"):
        comp.state_nuisance(prep, model, 1, after={"load": A})


def test_the_response_explains_a_filter_of_the_motion_that_a_sinusoid_takes():
    """On numbers: a residual that is a filter of the acceleration of a slow multisine motion holds a sinusoid at the
    motion's line; given the free response to the acceleration that sinusoid adds nothing, while the response given
    the sinusoid still lowers the held-out error (what the rule lets the state test see)."""
    rng = np.random.default_rng(106)
    dt, n = 0.01, 30000
    t = np.arange(n) * dt
    f0 = 0.15
    q = np.sin(2 * np.pi * f0 * t) + 0.6 * np.sin(2 * np.pi * 0.07 * t + 1.0) + 0.3 * np.sin(2 * np.pi * 0.23 * t)
    a = np.gradient(np.gradient(q, t), t) + 0.05 * rng.standard_normal(n)
    # a lightly damped second-order response of the torque to the acceleration, lag 0.3 s
    lag = 30
    y = np.zeros(n)
    y[lag:] = 0.8 * a[:-lag]
    y += 0.3 * np.convolve(a, np.exp(-np.arange(60) / 20.0) / 20.0)[:n]
    y += 0.02 * rng.standard_normal(n)
    rows = np.ones(n, bool)
    prep = SimpleNamespace(joints={1: SimpleNamespace(t=t, a=a, rows=rows)})
    L = core.linear_response_nuisance(prep, 1)
    S = np.column_stack([np.cos(2 * np.pi * f0 * t), np.sin(2 * np.pi * f0 * t)])
    train = (np.arange(n) // 500) % 2 == 0
    val = ~train

    def rss(X):
        c, *_ = np.linalg.lstsq(X[train], y[train], rcond=None)
        return float(np.sum((y[val] - X[val] @ c) ** 2))

    one = np.ones((n, 1))
    base, sin_only = rss(one), rss(np.hstack([one, S]))
    resp, both = rss(np.hstack([one, L])), rss(np.hstack([one, L, S]))
    assert sin_only < 0.95 * base                      # the sinusoid alone takes part of it
    gain = lambda before, after: 1 - np.sqrt(after / before)     # held-out RMSE reduction
    assert gain(resp, both) < core.MIN_GAIN / 5        # given the response the sinusoid adds nothing
    assert gain(sin_only, both) > 0.5                  # the response given the sinusoid still gains


def test_probe_keys_are_the_gate_screens_logs(tmp_path, capsys):
    """``--keys gate G.json ...`` prints the logs the bench's motion_line_gate screens list and ``--keys screened
    S.json ...`` those the probe's own screens list (sorted, each once, of the family asked); a bench screen of
    another count is refused, and so is a mode the probe does not know."""
    from conftest import bench_module
    probe = bench_module("probe_motion_line_linear_response")
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps({"count": "motion_line_gate", "touched": [["loop", 44020, {"1": 1}],
                                                                      ["testbench", 7, {"1": 1}]]}))
    b.write_text(json.dumps({"count": "motion_line_gate", "touched": [["loop", 12, {"1": 1}], ["loop", 44020,
                                                                                                {"1": 1}]]}))
    probe.keys_cli(["--keys", "gate", str(a), str(b)])
    assert capsys.readouterr().out.split() == ["12", "44020"]
    probe.keys_cli(["--keys", "--family=testbench", "gate", str(a)])
    assert capsys.readouterr().out.split() == ["7"]
    s = tmp_path / "s.json"
    s.write_text(json.dumps({"family": "loop", "keys_screened": [5, 9, 3], "touched": [[9, {"1": 1}], [3, {"1": 1}]],
                             "refused": []}))
    probe.keys_cli(["--keys", "screened", str(s)])
    assert capsys.readouterr().out.split() == ["3", "9"]
    c = tmp_path / "c.json"
    c.write_text(json.dumps({"count": "outliers", "touched": []}))
    with pytest.raises(SystemExit, match="not an motion_line_gate screen"):
        probe.keys_cli(["--keys", "gate", str(c)])
    with pytest.raises(SystemExit, match="expected 'all'"):
        probe.keys_cli(["--keys", "touchable"])


def test_probe_screen_lists_the_gated_logs(tmp_path):
    """The probe's screen prepares kept logs (no diagnosis) and lists those whose gate is not empty: 18456 (an elastic
    gear on multisine moves, gated) and not spec 100."""
    from conftest import bench_module
    probe = bench_module("probe_motion_line_linear_response")
    out = tmp_path / "s.json"
    assert probe.main(["--screen", str(out), "18456", "100"]) is None
    d = json.loads(out.read_text())
    assert d["keys_screened"] == [18456, 100] and d["touched"] == [[18456, {"1": 1}]] and d["refused"] == []


@pytest.fixture(scope="module")
def design_case():
    """Fresh spec 44020 (an elastic gear at 100 Hz on multisine moves over 300 s) diagnosed with the hundred-and-sixth
    round's switch off and on: (module, spec, truth, off, on, the state tests' results while on)."""
    from conftest import closed_loop_off_and_on, recording
    return closed_loop_off_and_on(44020, RULE, recording("motion_line_state_test", lambda got, a, kw: [
        (a[3].evidence.get("at_motion_line_hz"), got)]))


@pytest.mark.long
def test_spec_44020_sets_the_disturbance_at_the_line_aside(design_case):
    """Off: a time-periodic disturbance at 0.149 Hz on the multisine's 0.150 Hz line, ambiguous with a ripple: a wrong
    name.  On: no finding, the gear reported as `unexplained`; the state test of the candidate at that line, with the
    response offered, finds it below the least gain."""
    mod, spec, truth, off, on, seen = design_case
    assert truth["effects"] == ["compliance"]
    assert [f["effect"] for f in off["findings"]] == ["time_periodic_disturbance"]
    assert mod.judge(spec, off)["wrong"] == ["time_periodic_disturbance"]
    assert on["findings"] == [] and on["unexplained"]
    assert mod.judge(spec, on)["wrong"] == []
    at_line = [(f, t) for f, t in seen if f is not None and abs(f - 0.15) < 0.01]
    assert at_line and all(not t["significant"] and t["rmse_reduction"] < core.MIN_GAIN for _, t in at_line)


def test_kept_and_its_table_is_its_jsons():
    """Kept: the switch is on.  The gate screens cover the rows the rule file names (every kept row involving a
    time-periodic disturbance at 6b159ab, 4,054 logs; a control of 2,000 others; the fresh blocks 44200-44399 in full)
    and the lanes examined exactly the gated logs: a 44020, b the other six of the first screen, c the five of the
    control, d the one of the fresh blocks.  The rule acted in 44020 (mended), 18456, 18768, 21591 (its missed friction
    named) and 2342; no row gained a wrong name, a finding on a null log or lost `unexplained` or an outright name, the
    missed effects fell, every rule-on row is its log's kept row (three folded), and the docs' table holds each
    lane's row as --against-off-rows prints it."""
    from pathlib import Path

    from conftest import REFOLDED_ROUND_106, bench_module, probe_lanes, probe_results
    assert core.MOTION_LINE_LINEAR_RESPONSE_RULE is True
    probe = bench_module("probe_motion_line_linear_response")
    pre = "diagnose_motion_line_linear_response_round106"
    root = Path(__file__).resolve().parents[1] / "benchmarks" / "results"
    doc, files, examined, s = probe_lanes(probe, f"{pre}_lane_*.json", lanes="abcdefghijklmnopq")
    keys = [d["keys_examined"] for _, d in files]
    only = {x: [tuple(line.split()) for line in (root / f"{pre}_only_{x}.txt").read_text().splitlines()]
            for x in ("involved", "control")}
    assert len(only["involved"]) == 4054 and len(only["control"]) == 2000
    assert not set(only["involved"]) & set(only["control"])
    assert {f for f, _ in only["control"]} == {"loop"}
    gates = {x: json.loads((root / f"{pre}_gate_{x}.json").read_text()) for x in ("involved_0", "involved_1", "control")}
    assert gates["involved_0"]["logs"] + gates["involved_1"]["logs"] == 4054 and gates["control"]["logs"] == 2000
    assert all(g["count"] == "motion_line_gate" and g["refused"] == [] for g in gates.values())
    involved = probe.screened_keys([root / f"{pre}_gate_involved_{i}.json" for i in "01"], "motion_line_gate")
    assert involved == [1629, 17581, 18456, 18768, 21591, 29468, 44020]
    assert probe.screened_keys([root / f"{pre}_gate_involved_{i}.json" for i in "01"], "motion_line_gate",
                               "testbench") == []
    assert keys[0] == [44020] and keys[1] == [k for k in involved if k != 44020]
    assert keys[2] == probe.screened_keys([root / f"{pre}_gate_control.json"], "motion_line_gate") == \
        [2342, 10350, 17695, 35122, 35540]
    every_loop = probe.kept_keys("loop", lambda r: True)
    # screen a (44200-44399, lane d) and the fresh blocks since, each screened with the rule off: (screen, first spec,
    # logs, gated, the lane that diagnosed them or None)
    for x, start, n, gated, lane in (("a", 44200, 199, [44367], 3), ("b", 44400, 199, [], None),
                                     ("c", 44600, 200, [44609, 44697], 4), ("d", 44800, 200, [44824], 5),
                                     ("e", 45000, 199, [], None), ("f", 45200, 199, [45371], 8),
                                     ("g", 45400, 200, [45423], 9),
                                     ("h", 45600, 200, [45613], 10),
                                     ("i", 45800, 200, [45814, 45858, 45924], 11),
                                     ("j", 46000, 200, [46078], 12),
                                     ("k", 46200, 200, [46281, 46317, 46364], 13),
                                     ("l", 46400, 200, [46452, 46518, 46523], 14),
                                     ("m", 46600, 200, [], None),
                                     ("n", 46800, 200, [46875], 15),
                                     ("o", 47000, 200, [47090], 16)):
        screen = json.loads((root / f"{pre}_screen_{x}.json").read_text())
        assert screen["keys_screened"] == [k for k in every_loop if start <= k < start + 200], x
        assert len(screen["keys_screened"]) == n and [k for k, _ in screen["touched"]] == gated, x
        assert screen["refused"] == [] and (lane is None or keys[lane] == gated), x
    assert [t["k"] for _, d in files for t in d["touched"]] == [44020, 18456, 18768, 21591, 2342, 3046, 4190, 6294, 47090]
    # (d) the first share of the rows not screened in the round: the open-loop rows and the closed-loop rows below
    # 12000 outside the involved and control files, gated with the rule off; lanes g (closed-loop) and h (open-loop)
    only["rest_a"] = [tuple(line.split()) for line in (root / f"{pre}_only_rest_a.txt").read_text().splitlines()]
    assert len(only["rest_a"]) == 10465 and not set(only["rest_a"]) & (set(only["involved"]) | set(only["control"]))
    every = {("loop", str(k)) for k in every_loop if k < 12000} | {
        ("testbench", str(k)) for k in probe.kept_keys("testbench", lambda r: True)}
    assert set(only["rest_a"]) == every - set(only["involved"]) - set(only["control"])
    rest_files = [root / f"{pre}_gate_rest_a_{i}.json" for i in "01"]
    rest = [json.loads(f.read_text()) for f in rest_files]
    assert sum(g["logs"] for g in rest) == 10465 and all(g["refused"] == [] for g in rest)
    assert keys[6] == probe.screened_keys(rest_files, "motion_line_gate") and len(keys[6]) == 45
    assert keys[7] == probe.screened_keys(rest_files, "motion_line_gate", "testbench") == [136]
    for _, d in files:
        for t in d["touched"]:
            for x in t["set_aside"]:
                assert x["rmse_reduction_given_state"] >= core.MIN_GAIN > x["rmse_reduction_given_state_and_response"]
                assert abs(x["frequency_hz"] - x["at_motion_line_hz"]) < 0.01
    assert s["wrong_gained"] == s["null_findings_gained"] == s["oov_unexplained_lost"] == s["outright_lost"] == []
    assert s["wrong_lost"] == [44020] and s["missed_on"] < s["missed_off"]
    assert REFOLDED_ROUND_106 == {18768, 21591, 44020}
    _, _, differences = probe_results(f"{pre}_lane_*.json")
    for f, d in files:
        assert differences(d) == [], f.name
    assert "The rule acted in five logs of 13 (16 with lane e's two and lane f's one, where it did not act; eight of 62 with lanes g and h, where it changed no named effect; 76 with lane i's, lane j's, lane k's, lane l's, lane m's, lane n's, lane o's and lane p's, where it did not act; nine of 77 with lane q's 47090, an abrupt change beside a motor-position ripple at 250 Hz over 300 s, where it set aside three disturbances at a line of the motion and changed no named effect)." in " ".join(doc.split())
