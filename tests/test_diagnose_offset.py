"""A constant torque while moving (an asymmetric Coulomb level) against a position load that contains it
(core._is_offset, core._contains): ambiguous when the load predicts the held-out data as well, even where the
load's F-test, with its shape's extra parameters, is not significant."""
import numpy as np

from conftest import closed_loop_case
from drake_est.diagnose import core, diagnose
from drake_est.diagnose.nominal import prepare
from drake_est.diagnose.testbench import generate


def test_an_asymmetric_level_is_an_offset_that_a_load_contains():
    log, truth = generate({"asymmetric_coulomb": 1.0}, seed=11, duration=120.0, sample_rate=100.0, noise_std=0.05)
    prep = prepare(log, robot="generic")
    model = core.Model(prep)
    fit = model.fit()
    cands = {e.effect: e for e in core._candidates(prep, model, fit, set())}
    asym, load = cands["asymmetric_coulomb"], cands["position_dependent_load"]
    assert core._is_offset(prep, asym)
    assert not core._is_offset(prep, load)
    assert core._contains(prep, load, asym)
    assert not core._contains(prep, asym, load)
    for other in ("position_dependent_friction", "motor_position_ripple", "stribeck"):
        if other in cands:
            assert not core._contains(prep, cands[other], asym), other


def test_the_offset_of_a_load_is_not_named_as_an_asymmetric_level():
    """Closed-loop spec 3840 (10 Hz): a third-size position load that the generator counts as not visible; its
    constant part over the positions visited was named `asymmetric_coulomb` outright (the load, 10 parameters,
    lowered the held-out RMSE almost as much, 3.7 % against 3.9 %, but was not significant).  Now the two are
    reported ambiguous: no wrong name."""
    mod, spec, log, truth = closed_loop_case(3840)
    assert truth["not_visible"] and "position_dependent_load" in truth["not_visible"]
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert not mod.judge(spec, d, truth["not_visible"])["wrong"]
    (f,) = d["findings"]
    assert f["effect"] == "asymmetric_coulomb"
    assert f["ambiguous_between"] == ["asymmetric_coulomb", "position_dependent_load"]
    c = f["competition"]
    assert c["runner_up"] == "position_dependent_load" and not c["runner_up_significant"]
    assert 0.0 <= c["separation_below_min_gain"]["position_dependent_load"] < core.MIN_GAIN
    assert np.isfinite(c["margin"])
