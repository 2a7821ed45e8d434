"""The hundred-and-first round: the rescue of a law in time held back by the torque ADC's guard, whose check against a
free function of the joint's state may also take the derivative filter's error through the friction curve's slope
where the joint's model holds a Stribeck law (``competition.filter_slope_columns``,
``core.rescue_explained_by_filter_slope``, ``core.TIME_LAW_RESCUE_FILTER_SLOPE_RULE``; rule file
``benchmarks/results/diagnose_rescue_filter_slope_round101_rule.txt``)."""
from types import SimpleNamespace

import numpy as np
import pytest

from drake_est.diagnose import competition as comp
from drake_est.diagnose import core


def _joint(n=4000, seed=101):
    """A joint's data with a smooth, slow-and-fast speed profile: (prep-like namespace, jd)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 40.0, n)
    v = 0.02 + 0.3 * (1 + np.sin(2 * np.pi * t / 20.0)) * (0.5 + 0.5 * np.sin(2 * np.pi * t / 3.1) ** 2)
    v = v * np.where(np.sin(2 * np.pi * t / 13.0) >= 0, 1.0, -1.0) + 1e-3 * rng.normal(size=n)
    a = np.gradient(v, t)
    rows = np.arange(n)
    train = (np.arange(n) // 200) % 2 == 0
    jd = SimpleNamespace(t=t, v=v, a=a, q=np.cumsum(v) * (t[1] - t[0]), rows=rows, train=train, val=~train)
    return SimpleNamespace(joints={1: jd}), jd


def test_filter_slope_columns_are_the_jerk_times_kernels_in_speed():
    """2 x 6 columns: the jerk times exp(-(qd/c_k)^2), then the same times sign(qd), c_k log spaced from the 2 % to
    the 98 % quantile of the training speeds; at every row the kernels fall with |qd|."""
    prep, jd = _joint()
    F = comp.filter_slope_columns(prep, 1)
    assert F.shape == (jd.rows.size, 2 * comp.FILTER_SLOPE_KERNELS)
    jerk = np.gradient(jd.a, jd.t)
    lo, hi = np.quantile(np.abs(jd.v[jd.train]), [0.02, 0.98])
    c = np.geomspace(lo, hi, comp.FILTER_SLOPE_KERNELS)
    K = np.exp(-(np.abs(jd.v)[:, None] / c) ** 2)
    assert np.allclose(F[:, :6], jerk[:, None] * K) and np.allclose(F[:, 6:], (jerk * np.sign(jd.v))[:, None] * K)
    # a joint standing still on its training rows has no speed range: no columns
    still = SimpleNamespace(joints={1: SimpleNamespace(**{**jd.__dict__, "v": np.zeros_like(jd.v)})})
    assert comp.filter_slope_columns(still, 1) is None


def test_filter_slope_columns_hold_a_filter_error_through_a_stribeck_slope():
    """A torque error dF/dqd * c * jerk (a velocity error growing with the jerk through a Stribeck hump's slope) is
    fitted by the columns to a small fraction of its size, and not by the jerk alone (a constant slope)."""
    prep, jd = _joint()
    ks, vs = 3.0, 0.08
    slope = -2.0 * ks * np.abs(jd.v) / vs ** 2 * np.exp(-(jd.v / vs) ** 2) * np.sign(jd.v)
    jerk = np.gradient(jd.a, jd.t)
    e = slope * 1e-3 * jerk
    F = comp.filter_slope_columns(prep, 1)
    tr, va = jd.train, jd.val

    def heldout_share(A):
        c = np.linalg.lstsq(A[tr], e[tr], rcond=None)[0]
        return float(np.sum((e[va] - A[va] @ c) ** 2) / np.sum(e[va] ** 2))
    assert heldout_share(F) < 0.1 < 0.5 < heldout_share(jerk[:, None])


def test_state_nuisance_refuses_an_extra_block_named_as_a_state_block():
    """An extra block may not take the name of one of the state's own blocks (it would replace it silently); one of
    another name is offered beside them."""
    from conftest import nominal_candidates
    prep, _, _ = nominal_candidates({"position_dependent_load": 1.0}, seed=3)
    model = core.Model(prep)
    with pytest.raises(ValueError, match="extra block jerk is already a state block"):
        comp.state_nuisance(prep, model, 1, extra={"jerk": np.zeros((10, 1))})
    chosen = []
    comp.state_nuisance(prep, model, 1, chosen=chosen, extra={"filter_slope": comp.filter_slope_columns(prep, 1)})
    assert chosen and set(chosen) <= set(comp.STATE_BLOCK_NAMES) | {"filter_slope"}


def test_off_or_out_of_its_case_it_lets_the_law_be(monkeypatch):
    """Switch off, a shared law, or no Stribeck law on the law's joint in the model without it: None (the sixty-ninth
    round's check decides alone), and nothing is fitted."""
    law = SimpleNamespace(effect="abrupt_change", joint=1, shared=False)
    strib = SimpleNamespace(effect="stribeck", joint=1, shared=False)
    m0 = SimpleNamespace(own=lambda j: [strib] if j == 1 else [])
    monkeypatch.setattr(core, "TIME_LAW_RESCUE_FILTER_SLOPE_RULE", False)
    assert core.rescue_explained_by_filter_slope(None, m0, law) is None
    monkeypatch.setattr(core, "TIME_LAW_RESCUE_FILTER_SLOPE_RULE", True)
    assert core.rescue_explained_by_filter_slope(None, m0, SimpleNamespace(effect="abrupt_change", joint=1,
                                                                            shared=True)) is None
    assert core.rescue_explained_by_filter_slope(None, m0, SimpleNamespace(effect="abrupt_change", joint=2,
                                                                            shared=False)) is None
    no_strib = SimpleNamespace(own=lambda j: [SimpleNamespace(effect="position_dependent_load", joint=1,
                                                              shared=False)])
    assert core.rescue_explained_by_filter_slope(None, no_strib, law) is None


def test_the_report_says_why_a_law_was_not_let_past():
    """A candidate held back by the ADC guard whose rescue this round's check refused is reported with that reason,
    before the guard's own."""
    from drake_est.diagnose.report import rejection_reason
    r = {"effect": "abrupt_change", "joint": 1, "p_value": 1e-30, "rmse_reduction": 0.05,
         "below_quantization_step": True}
    assert rejection_reason(r) == "its change of the prediction stays within the torque ADC's rounding"
    r["rescue_explained_by_filter_slope"] = {"p_value": 1e-5, "rmse_reduction": 0.007, "score": 12.0}
    assert rejection_reason(r).endswith("the derivative filter's error through the Stribeck law's slope explains it")


def test_probe_touchable_and_control():
    """The probe's screen: a quantized torque with a law in time and a Stribeck law among the findings, named or set
    aside; the control draws 100 quantized rows with a Stribeck law and no law in time, the same keys on every call,
    none of them touchable."""
    from conftest import bench_module
    probe = bench_module("probe_rescue_filter_slope")
    q = {"noise": "quantized"}
    assert probe.touchable({**q, "got": "ambiguous(abrupt_change|energy_dependent_friction)+stribeck"})
    assert probe.touchable({**q, "got": "stribeck", "set_aside": ["energy_dependent_friction"]})
    assert probe.touchable({**q, "got": "abrupt_change", "set_aside": ["stribeck"]})
    assert not probe.touchable({"noise": "gaussian", "got": "abrupt_change+stribeck"})
    assert not probe.touchable({**q, "got": "abrupt_change+position_dependent_load"})
    assert probe.control({**q, "got": "position_dependent_load+stribeck"})
    assert not probe.control({**q, "got": "stribeck", "set_aside": ["abrupt_change"]})
    assert not probe.control({"noise": "student_t", "got": "stribeck"})
    keys = probe.control_keys("loop")
    assert len(keys) == probe.CONTROL_ROWS and keys == sorted(set(keys)) == probe.control_keys("loop")
    assert not set(keys) & set(probe.kept_keys("loop", probe.touchable))


@pytest.fixture(scope="module")
def design_case():
    """Fresh spec 36374 (a position load beside Stribeck at 1000 Hz, a quantized torque) diagnosed with the
    hundred-and-first round's switch off and on: (module, spec, truth, off, on, the rule's refusals while on).  The
    hundred-and-second round's switch is held off in both: with this round's off, its check sets the change aside too
    (``test_spec_36374_without_this_round_the_next_one_sets_the_change_aside``)."""
    from conftest import closed_loop_off_and_on, recording

    # core calls it as rescue_explained_by_filter_slope(prep, m0, ext, alpha): the extension is the third argument
    while_on = recording("rescue_explained_by_filter_slope",
                         lambda got, a, kw: [] if got is None else [(a[2].effect, got)])
    return closed_loop_off_and_on(36374, "TIME_LAW_RESCUE_FILTER_SLOPE_RULE", while_on,
                                  held=("TIME_LAW_BESIDE_STRIBECK_FILTER_SLOPE_RULE",))


@pytest.mark.long
@pytest.mark.xfail(strict=False, reason="known, measured 2026-12-07: on an AMD EPYC (e944c51's code and the "
                   "hundred-and-eighth round's alike) the rule-off path of 36374 names no abrupt change, so there is "
                   "no wrong name for the rule to remove; it holds on the Intel Xeon of the hundred-and-first round: "
                   "the path depends on the CPU's last digits")
def test_spec_36374_loses_the_change(design_case):
    """Off: an abrupt change, ambiguous with an energy drift, is named beside the load and the Stribeck law (a wrong
    name), let past the ADC guard by the readings' likelihood.  On: the state's function with the jerk through the
    speed kernels explains the change (given it the change lowers the held-out RMSE by less than the least gain, the
    function alone by more than the change alone), the change is held back, and the load and the Stribeck law are
    named alone."""
    mod, spec, truth, off, on, seen = design_case
    assert mod.judge(spec, off)["wrong"] == ["abrupt_change"]
    ch = next(f for f in off["findings"] if f["effect"] == "abrupt_change")
    assert ch["status"] == "ambiguous" and ch["ambiguous_between"] == ["abrupt_change", "energy_dependent_friction"]
    j = mod.judge(spec, on)
    assert j["wrong"] == [] and j["missed"] == [] and j["correct"]
    assert sorted(f["effect"] for f in on["findings"]) == ["position_dependent_load", "stribeck"]
    assert seen and {e for e, _ in seen} <= set(core.TIME_LAWS)
    for _, (N, t, own, state) in seen:
        assert t["rmse_reduction"] < core.MIN_GAIN and state >= own
    # the report says why the change of the last round was held back
    from drake_est.diagnose.report import rejection_reason
    nf = {r["effect"]: r for r in on["not_found"]}
    assert nf["abrupt_change"]["below_quantization_step"]
    assert nf["abrupt_change"]["rescue_explained_by_filter_slope"]["rmse_reduction"] < core.MIN_GAIN
    assert "the Stribeck law's slope explains it" in rejection_reason(nf["abrupt_change"])


@pytest.mark.long
@pytest.mark.xfail(strict=False, reason="known, measured 2026-12-07: on an AMD EPYC (e944c51's code and the "
                   "hundred-and-eighth round's alike) the change never enters 36374's model on this path, so none is "
                   "set aside (no wrong name either); it holds on the Intel Xeon of the hundred-and-second round: the "
                   "path depends on the CPU's last digits")
def test_spec_36374_without_this_round_the_next_one_sets_the_change_aside(monkeypatch):
    """With this round's switch off and the hundred-and-second round's on (the check of a law in time beside a
    Stribeck law, offered the same block), the change let past the guard enters the model and is then set aside as
    explained by the state's function holding the filter's error through the slope: no wrong name either way."""
    from conftest import closed_loop_case
    from drake_est.diagnose import diagnose
    mod, spec, log, truth = closed_loop_case(36374)
    monkeypatch.setattr(core, "TIME_LAW_RESCUE_FILTER_SLOPE_RULE", False)
    monkeypatch.setattr(core, "TIME_LAW_BESIDE_STRIBECK_FILTER_SLOPE_RULE", True)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert mod.judge(spec, d)["wrong"] == []
    aside = [s for s in d["set_aside"] if s["effect"] == "abrupt_change"]
    assert aside and aside[0].get("filter_slope_chosen")


def test_kept_and_its_table_is_its_jsons():
    """Kept: the switch is on; lanes a and b examined every touchable closed-loop row (36374 in b), lane c the 100
    control rows; the rule acted in 6215, 19888, 36374 and 20999, changed names in 36374 only (mended); no row
    gained a wrong name, a finding on a null log or lost `unexplained` or an outright name, the missed effects did not
    rise, every rule-on row is its log's kept row (36374's folded), and the docs' table holds each lane's row as
    --against-off-rows prints it."""
    from conftest import REFOLDED_ROUND_101, bench_module, probe_lanes, probe_results
    assert core.TIME_LAW_RESCUE_FILTER_SLOPE_RULE is True
    probe = bench_module("probe_rescue_filter_slope")
    doc, files, examined, s = probe_lanes(probe, "diagnose_rescue_filter_slope_round101_lane_*.json", lanes="abcdefghijklmnopqrstuvwxyz")
    keys = [d["keys_examined"] for _, d in files]
    assert len(keys[0]) == len(keys[1]) == 130 and max(keys[0]) < min(keys[1]) and 36374 in keys[1]
    # as drawn: 36374, folded, names no law in time any more and left the touchable rows
    assert REFOLDED_ROUND_101 == {36374}
    touchable = probe.kept_keys("loop", probe.touchable)
    # lane d: the touchable rows of the fresh blocks 41400-41599, run with the rule on
    assert keys[3] == [k for k in touchable if 41400 <= k < 41600] == [41522, 41591]
    # lane e: the one of the fresh blocks 41600-41799
    assert keys[4] == [k for k in touchable if 41600 <= k < 41800] == [41723]
    assert keys[5] == [k for k in touchable if 41800 <= k < 42000] == [41921, 41984]
    assert keys[6] == [k for k in touchable if 42000 <= k < 42200] == [42050]
    assert keys[7] == [k for k in touchable if 42200 <= k < 42400] == [42317, 42363]
    assert keys[8] == [k for k in touchable if 42400 <= k < 42600] == [42495]
    assert keys[9] == [k for k in touchable if 42600 <= k < 42800] == [42790]
    assert keys[10] == [k for k in touchable if 42800 <= k < 43000] == [42845, 42971]
    assert keys[11] == [k for k in touchable if 43000 <= k < 43400] == [43172, 43333, 43373]
    assert keys[12] == [k for k in touchable if 43400 <= k < 44000] == [43505, 43703, 43714, 43898, 43967]
    assert [k for k in touchable if 44000 <= k < 44400] == []
    assert keys[13] == [k for k in touchable if 44400 <= k < 44600] == [44429, 44440]
    assert keys[14] == [k for k in touchable if 44600 <= k < 44800] == [44756]
    assert keys[15] == [k for k in touchable if 44800 <= k < 45000] == [44836, 44957]
    assert keys[16] == [k for k in touchable if 45000 <= k < 45400] == [45232, 45298]     # 45000-45199: none
    assert keys[17] == [k for k in touchable if 45400 <= k < 45600] == [45419, 45430]
    assert keys[18] == [k for k in touchable if 45600 <= k < 45800] == [45631, 45749, 45795]
    assert keys[19] == [k for k in touchable if 45800 <= k < 46000] == [45993]
    assert keys[20] == [k for k in touchable if 46000 <= k < 46200] == [46145]
    assert keys[21] == [k for k in touchable if 46200 <= k < 46400] == [46277, 46343]
    assert keys[22] == [k for k in touchable if 46400 <= k < 46600] == [46475]
    assert keys[23] == [k for k in touchable if 46600 <= k < 46800] == [46607]
    assert keys[24] == [k for k in touchable if 46800 <= k < 47000] == [46934]
    assert keys[25] == [k for k in touchable if 47000 <= k < 47200] == [47069]
    assert [k for k in keys[0] + keys[1] if k not in REFOLDED_ROUND_101] == [k for k in touchable if k < 41400]
    assert probe.kept_keys("testbench", probe.touchable) == []
    kept = {k: r for (f, _, k), (_, r) in bench_module("bench_diagnose_testbench").kept_rows_naming("any").items()
            if f == "loop"}
    # (drawn before the fold, which put 36374 into the control rows' pool: today's draw differs)
    assert len(keys[2]) == probe.CONTROL_ROWS and keys[2] == sorted(set(keys[2]))
    assert all(probe.control(kept[k]) for k in keys[2]) and not set(keys[2]) & set(keys[0] + keys[1])
    assert [t["k"] for _, d in files for t in d["touched"]] == [6215, 19888, 36374, 20999]
    assert s["wrong_gained"] == s["null_findings_gained"] == s["oov_unexplained_lost"] == s["outright_lost"] == []
    assert s["wrong_lost"] == [36374] and s["missed_on"] <= s["missed_off"]
    for _, d in files:
        for t in d["touched"]:
            assert all(x["effect"] in core.TIME_LAWS and x["rmse_reduction_given_state"] < core.MIN_GAIN
                       for x in t["refused"])
    _, _, differences = probe_results("diagnose_rescue_filter_slope_round101_lane_*.json")
    for f, d in files:
        assert differences(d) == [], f.name
    assert "The rule acted in four logs of 400." in " ".join(doc.split())
