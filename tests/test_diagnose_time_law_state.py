"""A friction law in time beside a law of the state must predict the held-out residual given a free function of the
joint's state (core.time_law_explained_by_state; the forty-sixth round beside Stribeck, the forty-eighth beside any
law of the state when the law in time is not reported ambiguous with one): the misfit of a law of the state's fixed
shape is a function of the state (speed, direction, the time since the last reversal), a change of the friction over
the log is not."""
from types import SimpleNamespace

import pytest

from drake_est.diagnose import core, diagnose
from drake_est.diagnose.report import markdown
from drake_est.diagnose.testbench import generate

from conftest import closed_loop_case, nominal_candidates


@pytest.mark.parametrize("ulps", [0, 1, 2, 5])
def test_the_misfit_of_a_stribeck_shape_is_not_named_as_a_change(ulps):
    # loop spec 13761: an asymmetric level beside Stribeck at 10 Hz with Student-t noise; before the forty-sixth round
    # an abrupt change took the level's part, ambiguous with a load, beside Stribeck ambiguous with an energy drift.
    # Given a free curve of the speed the change kept 6.7 % of the held-out RMSE; given the state's function, 1.3 %.
    # The log sits near a decision of the search: on an AVX2 CPU the log as generated (0 ulps) ends with the change
    # alone (a wrong name there), while the CPU that ran the round named the level and Stribeck; with the reference
    # moved by 1, 2 and 5 ulps (other last digits) the change is set aside on the AVX2 CPU too, by this check or by an
    # earlier one of the confirmation loop; since the fifty-second round the change alone is set aside as well
    # (core.sole_time_law_explained_by_state), so the log as generated is followed too
    mod, spec, log, truth = closed_loop_case(13761, reference_ulps=ulps)
    rep = diagnose(log, robot="generic", seed=0, simulate=False)
    d = rep.to_dict()
    assert sorted(f["effect"] for f in d["findings"]) == ["asymmetric_coulomb", "stribeck"]
    j = mod.judge(spec, d)
    assert j["correct"] and not j["wrong"] and not j["missed"]
    assert "abrupt_change" in [x["effect"] for x in d["set_aside"]]
    for x in d["set_aside"]:
        if x.get("explained_by_state"):
            assert x["state_law_test"]["rmse_reduction"] < core.MIN_GAIN
            assert x["state_heldout_rmse_reduction"] >= x["heldout_rmse_reduction_alone"] >= core.MIN_GAIN
    assert "## Findings set aside" in markdown(d)


@pytest.mark.parametrize("effect,seed,rate", [("energy_dependent_friction", 0, 100.0),
                                              ("energy_dependent_friction", 3, 50.0),
                                              ("abrupt_change", 1, 250.0)])
def test_a_planted_law_in_time_beside_stribeck_survives_the_state(effect, seed, rate):
    # both planted (open-loop testbench): a drift or a change of the friction over the log is not a function of the
    # joint's state, and given the state's function it still lowers the held-out RMSE by far more than MIN_GAIN
    log, truth = generate({effect: 1.0, "stribeck": 1.0}, seed=seed, duration=120.0, sample_rate=rate,
                          noise_std=0.05)
    rep = diagnose(log, robot="generic", seed=0, simulate=False)
    d = rep.to_dict()
    assert sorted(f["effect"] for f in d["findings"]) == sorted([effect, "stribeck"])
    assert not [x for x in d["set_aside"] if x.get("explained_by_state")]
    s = d["settings"]
    r = rep.result
    assert core.time_law_explained_by_state(r.prep, r.final_model, r.steps, s["alpha"],
                                            s["min_rmse_reduction"]) is None


@pytest.mark.long
@pytest.mark.parametrize("ulps", [0, 1, 2])
def test_no_drift_is_named_beside_a_position_friction_for_an_asymmetric_level(ulps):
    # loop spec 4345 (forty-eighth round): an asymmetric level beside Stribeck at 100 Hz; before the round a position
    # friction took the level's and Stribeck's part and an energy drift, named outright, the misfit of its shape.  With
    # the round the drift is set aside by this check (-0.6 % given the state, the state alone 23 %); at other last
    # digits of the reference the search may not name a drift at all.  Either way: no wrong name, no drift
    mod, spec, log, truth = closed_loop_case(4345, reference_ulps=ulps)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert not mod.judge(spec, d)["wrong"]
    assert "energy_dependent_friction" not in [f["effect"] for f in d["findings"]]
    for x in d["set_aside"]:
        if x.get("explained_by_state"):
            assert x["effect"] in ("energy_dependent_friction", "abrupt_change")
            assert x["state_heldout_rmse_reduction"] >= x["heldout_rmse_reduction_alone"]


@pytest.mark.parametrize("k", [4320, 1152])
def test_a_drift_ambiguous_with_stribeck_beside_a_load_is_not_held_against_the_state(k):
    # loop specs 4320 and 1152 (10 Hz): a load and Stribeck, reported as the load and an energy drift ambiguous with
    # Stribeck; the drift stands for the Stribeck law, and the forty-seventh round, which set it aside, lost Stribeck
    mod, spec, log, truth = closed_loop_case(k)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert not mod.judge(spec, d)["wrong"]
    assert not [x for x in d["set_aside"] if x.get("explained_by_state")]


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("law", ["position_dependent_load", "asymmetric_coulomb"])
@pytest.mark.parametrize("time_law", ["energy_dependent_friction", "abrupt_change"])
def test_a_law_in_time_for_a_misfit_of_the_state_is_explained_by_it(seed, law, time_law):
    # open-loop testbench, a position friction beside Stribeck (no law in time planted): the first round's candidate
    # of a law in time beside a law of the state that does not hold the planted effects is explained by a free
    # function of the joint's state, which alone predicts the residual far better
    prep, sigma, c = nominal_candidates({"position_dependent_friction": 1.0, "stribeck": 1.0}, seed)
    got = core.time_law_explained_by_state(prep, core.Model(prep, [c[law], c[time_law]]), [], core.ALPHA,
                                           core.MIN_GAIN)
    assert got is not None and got[0] == time_law
    why = got[2]
    assert why["explained_by_state"] and why["state_law_test"]["rmse_reduction"] < core.MIN_GAIN
    assert why["state_heldout_rmse_reduction"] > why["heldout_rmse_reduction_alone"]
    assert f"beside its {law.replace('_', ' ')}" in why["reason"]


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("planted,law,time_law", [
    ({"position_dependent_load": 1.0, "energy_dependent_friction": 1.0}, "position_dependent_load",
     "energy_dependent_friction"),
    ({"asymmetric_coulomb": 1.0, "energy_dependent_friction": 1.0}, "asymmetric_coulomb", "energy_dependent_friction"),
    ({"position_dependent_friction": 1.0, "abrupt_change": 1.0}, "position_dependent_friction", "abrupt_change")])
def test_a_planted_law_in_time_beside_a_law_of_the_state_survives_the_state(seed, planted, law, time_law):
    prep, sigma, c = nominal_candidates(planted, seed)
    assert core.time_law_explained_by_state(prep, core.Model(prep, [c[law], c[time_law]]), [], core.ALPHA,
                                            core.MIN_GAIN) is None


def _ext(effect, joint=1, shared=False):
    return SimpleNamespace(effect=effect, joint=joint, shared=shared)


def _step(ext, *rivals):
    c = {"ambiguous": True, "ambiguous_with": list(rivals), "runner_up": rivals[0]} if rivals else {}
    return SimpleNamespace(ext=ext, competition=c)


def test_which_laws_in_time_the_state_check_holds():
    drift, load, stri = _ext("energy_dependent_friction"), _ext("position_dependent_load"), _ext("stribeck")
    change0 = _ext("abrupt_change", joint=0)

    def laws(exts, steps):
        return [(e.effect, e.joint, b) for e, b in core._time_laws_beside_state(SimpleNamespace(exts=exts), steps)]

    # beside Stribeck: every one, ambiguous or not (the forty-sixth round)
    assert laws([drift, stri], [_step(drift, "stribeck"), _step(stri)]) == [
        ("energy_dependent_friction", 1, ["stribeck"])]
    # beside another law of the state: only one not ambiguous with a law of the state
    assert laws([load, drift], [_step(load), _step(drift)]) == [
        ("energy_dependent_friction", 1, ["position_dependent_load"])]
    assert laws([load, drift], [_step(load), _step(drift, "stribeck")]) == []
    assert laws([load, drift], [_step(load), _step(drift, "abrupt_change")]) == [
        ("energy_dependent_friction", 1, ["position_dependent_load"])]
    # alone on its joint, or beside a law in time only, or a law of the state on another joint: none
    assert laws([drift], [_step(drift)]) == []
    assert laws([drift, change0, _ext("position_dependent_load", joint=0)], []) == [
        ("abrupt_change", 0, ["position_dependent_load"])]
    assert laws([_ext("energy_dependent_friction", shared=True), load], []) == []


@pytest.mark.long
def test_a_change_and_the_state_function_that_explain_each_other_keep_the_change():
    # loop spec 11098: an abrupt change and a motor ripple at 1000 Hz with Student-t noise; on an AVX2 CPU the check
    # set the planted change aside beside the ripple (given the state's function it lowered the held-out RMSE by
    # 0.6 %; the function alone by 64.7 %, the change alone by 64.3 %) and the search run again named an energy drift
    # and a load.  Since the fifty-third round the law is set aside only one way: the function, given the change, must
    # still predict the held-out residual
    mod, spec, log, truth = closed_loop_case(11098)
    rep = diagnose(log, robot="generic", seed=0, simulate=False)
    d = rep.to_dict()
    j = mod.judge(spec, d)
    assert j["correct"] and not j["wrong"] and not j["missed"]
    assert sorted(f["effect"] for f in d["findings"]) == ["abrupt_change", "motor_position_ripple"]
    assert not [x for x in d["set_aside"] if x["effect"] == "abrupt_change" and x.get("explained_by_state")]
