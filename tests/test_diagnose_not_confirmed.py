"""A later finding is confirmed only with a gain the misfit cannot explain (core.finding_not_confirmed,
core.MIN_GAIN_NOT_WHITE): when the final residual of its joint still holds structure, a finding accepted after
another one on its joint that lowered the held-out RMSE by less than MIN_GAIN_NOT_WHITE in its round is set aside
and the search run again.  The first finding of a joint keeps the usual tests."""
from types import SimpleNamespace

import pytest

from drake_est.diagnose import core, diagnose
from drake_est.diagnose.detectors import energy as _ENERGY     # the detector itself, before any monkeypatch
from drake_est.diagnose.testbench_loop import generate


def _step(effect, joint, reduction, competition=None):
    ext = SimpleNamespace(effect=effect, joint=joint, cols=[joint], shared=False)
    return SimpleNamespace(ext=ext, test={"rmse_reduction": reduction}, competition=dict(competition or {}))


def test_the_weakest_finding_on_a_joint_with_structure_is_not_confirmed():
    steps = [_step("stribeck", 1, 0.76), _step("abrupt_change", 1, 0.05), _step("position_dependent_load", 1, 0.10)]
    unexplained = [{"joint": 1, "variable": "time_correlation"}, {"joint": 1, "variable": "velocity"}]
    st, where = core.finding_not_confirmed(steps, unexplained)
    assert st.ext.effect == "abrupt_change"
    assert where == {1: ["time_correlation", "velocity"]}


def test_no_structure_or_structure_on_another_joint_confirms_everything():
    steps = [_step("stribeck", 1, 0.76), _step("abrupt_change", 1, 0.05)]
    assert core.finding_not_confirmed(steps, []) is None
    assert core.finding_not_confirmed(steps, [{"joint": 2, "variable": "position"}]) is None
    # a large gain is confirmed whatever remains
    assert core.finding_not_confirmed(steps[:1], [{"joint": 1, "variable": "position"}]) is None


def test_the_first_finding_of_a_joint_keeps_the_usual_tests():
    structure = [{"joint": 1, "variable": "jerk_excluded_samples"}, {"joint": 2, "variable": "time"}]
    assert core.finding_not_confirmed([_step("motor_position_ripple", 1, 0.12)], structure) is None
    # later on another joint is first there too
    steps = [_step("motor_position_ripple", 1, 0.12), _step("abrupt_change", 2, 0.05)]
    assert core.finding_not_confirmed(steps, structure) is None
    st, _ = core.finding_not_confirmed(steps + [_step("stribeck", 2, 0.08)], structure)
    assert st.ext.effect == "stribeck"


@pytest.mark.parametrize("threshold", [0.04, 0.06])
def test_the_threshold_decides(threshold):
    steps = [_step("stribeck", 1, 0.5), _step("abrupt_change", 1, 0.05)]
    got = core.finding_not_confirmed(steps, [{"joint": 1, "variable": "time"}], min_gain_not_white=threshold)
    assert (got is None) == (threshold < 0.05)


def _spec_948(ulps=0):
    # loop_cases(949)[948] of benchmarks/bench_diagnose_testbench.py: a motor-position ripple only, student-t noise
    log, _ = generate({"motor_position_ripple": 1.0}, seed=3948, duration=120.0, sample_rate=1000.0,
                      noise="student_t", noise_std=0.13582799905184845, check_visible=False, reference_ulps=ulps)
    return log


@pytest.mark.parametrize("ulps", [0, 3])
def test_a_small_time_periodic_candidate_beside_a_ripple_is_never_named(ulps):
    """Closed-loop spec 948 (a motor-position ripple only): a 0.47 Hz time-periodic candidate lowers the held-out
    RMSE by 2-3 % after the ripple while the residual stays correlated in time.  Its paired held-out block test sits
    at the level (p = 0.045 before the inertia backfit, 0.066 after, on an AVX2 machine; the CI machines' CPUs
    differ in the last digits of the numerics, and an earlier CI machine, where this test required the set-aside
    below, gave p < 0.05 after the backfit too).  Either way it is not named: rejected by the block test, or
    accepted and then set aside as not confirmed (the next test); the ripple stays and the structure is reported as
    unexplained.  Also with the reference moved by 3 ulps (testbench_loop.generate's reference_ulps)."""
    d = diagnose(_spec_948(ulps), robot="generic", seed=0, simulate=False).to_dict()
    assert [f["effect"] for f in d["findings"]] == ["motor_position_ripple"]
    assert d["unexplained"] and {u["joint"] for u in d["unexplained"]} == {1}
    for r in d["set_aside"]:
        assert r["effect"] == "time_periodic_disturbance" and r.get("not_confirmed"), r


@pytest.mark.long
def test_a_small_time_periodic_finding_beside_a_ripple_is_set_aside(monkeypatch):
    """Spec 948 with the paired block test's level at 0.10 instead of core.PAIRED_ALPHA (0.05), so that the 0.47 Hz
    candidate passes it on any machine (see above): accepted after the ripple with a 2.6 % gain while the residual
    stays correlated in time, it is set aside as not confirmed, the ripple stays, and report.json and report.md
    say why.  The ripple as the backfit placed it before the sixty-fifth round ([10.0046, 20.0297] cycles/rad): that
    round's joint search of the frequencies ([10.0228, 20.0512]) leaves no candidate to accept here (the next test),
    so the search is switched off to reach the set-aside."""
    from drake_est.diagnose import detectors as det
    monkeypatch.setattr(core, "PAIRED_ALPHA", 0.10)
    monkeypatch.setattr(det, "ripple_refined", lambda jd, r, ext, **kw: ext)
    d = diagnose(_spec_948(), robot="generic", seed=0, simulate=False).to_dict()
    assert [f["effect"] for f in d["findings"]] == ["motor_position_ripple"]
    aside = [r for r in d["set_aside"] if r.get("not_confirmed")]
    assert [r["effect"] for r in aside] == ["time_periodic_disturbance"]
    assert 0 < aside[0]["heldout_rmse_reduction"] < core.MIN_GAIN_NOT_WHITE
    assert "not confirmed" in aside[0]["reason"] and d["unexplained"]
    from drake_est.diagnose.report import markdown
    md = markdown(d)
    assert "- time_periodic_disturbance (joint 1): not confirmed" in md
    # under its own heading, not among the findings that the others explained
    assert "not confirmed while the final residual still holds structure" in md
    assert ("Each finding is checked against the others" in md) == any(not r.get("not_confirmed")
                                                                       for r in d["set_aside"])


@pytest.mark.long
def test_with_the_joint_frequency_search_the_candidate_is_not_accepted(monkeypatch):
    """The same log and level as above with the sixty-fifth round's joint search of the ripple's frequencies: the
    ripple's phase misfit that the 0.47 Hz candidate took is gone, so it is neither named nor set aside."""
    monkeypatch.setattr(core, "PAIRED_ALPHA", 0.10)
    res = diagnose(_spec_948(), robot="generic", seed=0, simulate=False)
    d = res.to_dict()
    assert [f["effect"] for f in d["findings"]] == ["motor_position_ripple"]
    assert not [r for r in d["set_aside"] if r["effect"] == "time_periodic_disturbance"]
    rip = res.result.final_model.exts[0]
    assert "jointly_refined_from_frequencies_per_arm_rad" in rip.evidence


def _rival(name, reduction, significant=True):
    return {"runner_up": name, "runner_up_significant": significant, "runner_up_rmse_reduction": reduction,
            "ambiguous": False}


def test_a_later_finding_close_to_its_runner_up_is_ambiguous_with_it():
    """core.mark_not_separated_under_misfit: 1 - (1 - 0.60) / (1 - 0.59) = 2.4 % < 15 %: ambiguous; a first
    finding, a runner-up that is not significant, a clear separation or no structure: unchanged."""
    structure = [{"joint": 1, "variable": "velocity"}]
    first = _step("stribeck", 1, 0.65, _rival("energy_dependent_friction", 0.60))
    close = _step("position_dependent_load", 1, 0.60, _rival("asymmetric_coulomb", 0.59))
    marked = core.mark_not_separated_under_misfit([first, close], structure)
    assert marked == [close] and first.competition["ambiguous"] is False
    assert close.competition["ambiguous"] and close.competition["ambiguous_with"] == ["asymmetric_coulomb"]
    assert close.competition["separation_from_runner_up"] == pytest.approx(1 - 0.40 / 0.41)
    for c in (_rival("asymmetric_coulomb", 0.59, significant=False), _rival("asymmetric_coulomb", 0.30)):
        st = _step("position_dependent_load", 1, 0.60, c)
        assert core.mark_not_separated_under_misfit([first, st], structure) == []
    st = _step("position_dependent_load", 1, 0.60, _rival("asymmetric_coulomb", 0.59))
    assert core.mark_not_separated_under_misfit([first, st], []) == []


def test_spec_1287_names_the_load_only_as_ambiguous_with_the_asymmetry():
    """Closed-loop spec 1287 (loop_cases(1288)[1287]: an asymmetric Coulomb level and a Stribeck law, 100 Hz,
    Student-t noise): after the Stribeck law a position load removes 60 % of the RMSE, mostly the constant an
    asymmetric level also is, 1.8 % better than the asymmetry while the residual still depends on velocity and
    time.  It is reported ambiguous with the asymmetry, not as a load (since the ninth round by the MIN_GAIN
    separation of core._competition)."""
    log, _ = generate({"asymmetric_coulomb": 1.0, "stribeck": 1.0}, seed=4287, duration=120.0, sample_rate=100.0,
                      noise="student_t", noise_std=0.12315548087723906, check_visible=False)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    names = {e for f in d["findings"] for e in f.get("ambiguous_between", [f["effect"]])}
    assert {"asymmetric_coulomb", "stribeck"} <= names
    for f in d["findings"]:
        if f["effect"] == "position_dependent_load":
            assert f["status"] == "ambiguous" and "asymmetric_coulomb" in f["ambiguous_between"]
            # 1.8 % is below MIN_GAIN: since the ninth round _competition already reports the pair (the third rule,
            # mark_not_separated_under_misfit, tested on its own above, would otherwise)
            c = f["competition"]
            sep = c.get("separation_below_min_gain", {}).get("asymmetric_coulomb", c.get("separation_from_runner_up"))
            assert sep < core.MIN_GAIN_NOT_WHITE


@pytest.mark.long
def test_a_fourth_weak_finding_is_not_named_either():
    # a Stribeck law twice the generator's size (loop seed 3, 100 Hz): on the CPU that ran the thirty-fifth round its
    # shape misfit was about five times the noise, and weak candidates soaked it up in turn; with MAX_NOT_CONFIRMED = 3
    # (before that round) the fourth, an energy drift of 6 %, was named, and four were set aside after it.  On an AVX2
    # CPU the search takes another path: a position friction first, Stribeck and a drift set aside as not significant
    # beside it, and the friction reported ambiguous with a load and Stribeck.  On both no weak finding is named, and
    # every finding is Stribeck or ambiguous with it
    assert core.MAX_NOT_CONFIRMED >= 4
    log, _ = generate({"stribeck": 2.0}, seed=3, duration=120.0, sample_rate=100.0, noise_std=0.1)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert len(d["findings"]) == 1
    assert "stribeck" in d["findings"][0].get("ambiguous_between", [d["findings"][0]["effect"]])
    weak = [s for s in d["set_aside"] if s.get("not_confirmed")]
    assert all(s["heldout_rmse_reduction"] < core.MIN_GAIN_NOT_WHITE for s in weak)
    assert not [s for s in weak if s["effect"] in [f["effect"] for f in d["findings"]]]


def test_docs_quote_the_large_effect_runs():
    # the docs' numbers come from the kept JSONs of benchmarks/bench_large_effects.py, before and with the round
    import json
    import sys
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    sys.path.insert(0, str(root / "benchmarks"))
    import bench_large_effects as bl
    doc = (root / "docs" / "readme" / "diagnose_testbench.md").read_text()
    for name in ("diagnose_large_effects_before_round35.json", "diagnose_large_effects_round35.json"):
        d = json.loads((root / "benchmarks" / "results" / name).read_text())
        assert f"`{name}`: {bl.counts_text(d)}" in doc
    assert bl.specs([2.0], [0])[0]["effects"] == {"stribeck": 2.0}


def test_what_the_large_effect_probe_leaves_is_what_the_docs_say():
    # bench_large_effects' remaining cases, as the thirty-fifth round's section describes them: the asymmetric level
    # of seed 2 is not identifiable (the selected samples move one way), and a large Stribeck hump biases the inertia
    # that prepare identifies (seed 3: 0.354 planted)
    import numpy as np
    from drake_est.diagnose.core import prepare
    log, _ = generate({"asymmetric_coulomb": 2.0}, seed=2, duration=120.0, sample_rate=100.0, noise_std=0.1)
    jd = prepare(log, robot="generic", seed=0).joints[1]
    v = jd.v[jd.rows]
    assert np.sum(v < 0) <= 3 and np.sum(v > 0) > 5000
    J = []
    for size in (1.0, 2.0, 3.0):
        log, truth = generate({"stribeck": size}, seed=3, duration=120.0, sample_rate=100.0, noise_std=0.1)
        J.append(prepare(log, robot="generic", seed=0).joints[1].counts["inertia"])
    assert truth["J"] == pytest.approx(0.354, abs=1e-3)
    assert J == sorted(J) and J[0] > 1.6 * truth["J"]
    assert J == pytest.approx([0.60, 0.71, 0.78], abs=0.01)


def _drift_search(seed, n_iter, monkeypatch):
    import numpy as np
    from drake_est.diagnose import detectors as det
    from drake_est.diagnose.core import prepare
    orig = _ENERGY

    def energy(jd, r, F, fit_train, **kw):
        return orig(jd, r, F, fit_train, **{**kw, "n_iter": n_iter})

    monkeypatch.setattr(det, "energy", energy)
    log, truth = generate({"energy_dependent_friction": 3.0}, seed=seed, duration=120.0, sample_rate=100.0,
                          noise_std=0.1)
    prep = prepare(log, robot="generic", seed=0)
    out = core._search(prep, core.MAX_FINDINGS, core.ALPHA, core.MIN_GAIN)
    jd = prep.joints[1]
    th = np.asarray(truth["signals"]["thermal_state"])[jd.rows]
    drift = [x for x in out[5].exts if x.effect == "energy_dependent_friction"][0]
    E = np.asarray(drift.obj, float)[jd.rows]
    return prep, out, th, float(np.corrcoef(E, th)[0, 1])


@pytest.mark.long
def test_a_warm_up_three_times_the_size_leaves_its_misfit_in_the_estimated_state(monkeypatch):
    # bench_large_effects' energy drifts at 3x (seed 2): the later position friction adds 25 % given the drift fitted
    # on the detector's state E, nothing given a law linear in the generator's own thermal state; E is Algorithm 6's
    # fixed point (friction power of the current friction estimate), which more passes do not settle (seed 3)
    import numpy as np
    from drake_est.diagnose import competition as comp
    from drake_est.diagnose.core import Model
    prep, out, th, _ = _drift_search(2, 2, monkeypatch)
    model = out[5]
    assert [s.ext.effect for s in out[3]] == ["energy_dependent_friction", "position_dependent_friction"]
    pf = [x for x in model.exts if x.effect == "position_dependent_friction"][0]
    m0 = Model(prep, [x for x in model.exts if x is not pf])
    v = prep.joints[1].v[prep.joints[1].rows]
    solve = core._model_solver(m0, 1)
    alone = comp._partial_test(prep, m0, 1, np.zeros((v.size, 0)), pf.cols[1], core.ALPHA, core.MIN_GAIN, solve)
    given = comp._partial_test(prep, m0, 1, np.column_stack([np.sign(v) * th, v * th]), pf.cols[1], core.ALPHA,
                               core.MIN_GAIN, solve)
    assert alone["rmse_reduction"] > 0.2 and given["rmse_reduction"] < 0.01 and not given["significant"]
    c = {n: _drift_search(3, n, monkeypatch)[3] for n in (2, 5, 10)}
    assert c == pytest.approx({2: 0.944, 5: 0.937, 10: 0.81}, abs=0.01)
