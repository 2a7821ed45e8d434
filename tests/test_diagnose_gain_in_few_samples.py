"""A later finding whose held-out squared-error gain sits in a few samples must also lower the absolute errors across
the held-out blocks (core.gain_in_few_samples): under heavy-tailed noise a few large errors carry such a gain, while a
law of the joint changes the prediction wherever its regressors move."""
from types import SimpleNamespace

import numpy as np
import pytest

from drake_est.diagnose import competition as comp
from drake_est.diagnose import core, diagnose
from drake_est.diagnose.core import run_diagnosis
from drake_est.diagnose.report import markdown

from conftest import closed_loop_case


def _two_fits(n=2000, heavy=False, seed=0):
    """A one-joint prep and two fits a, b: b lowers every error a little (a broad gain), or (``heavy``) b shrinks
    the few large errors of heavy-tailed noise by 30 % and makes every small one 0.03 larger."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 10.0
    rows = np.arange(n)
    val = (np.arange(n) // 10) % 2 == 1
    y = np.zeros(n)
    if heavy:
        ea = 0.1 * rng.standard_t(2, n)
        eb = np.where(np.abs(ea) > 0.3, 0.7 * ea, ea + 0.03 * np.sign(ea))
    else:
        eb = 0.1 * rng.standard_normal(n)
        ea = eb + 0.05 * np.sign(eb)
    jd = SimpleNamespace(t=t, rows=rows, val=val, y=y)
    prep = SimpleNamespace(joints={1: jd})
    return prep, SimpleNamespace(pred={1: y - ea}), SimpleNamespace(pred={1: y - eb})


def test_absolute_pairing_is_not_carried_by_a_few_large_errors():
    prep, fa, fb = _two_fits(heavy=True)
    assert comp.paired_block_test(prep, fa, fb, [1])["p_value"] < 0.05             # squared errors: b wins
    assert comp.paired_block_test(prep, fa, fb, [1], loss="absolute")["p_value"] > 0.5
    prep, fa, fb = _two_fits(heavy=False)
    assert comp.paired_block_test(prep, fa, fb, [1])["p_value"] < 1e-4
    assert comp.paired_block_test(prep, fa, fb, [1], loss="absolute")["p_value"] < 1e-4


def test_unknown_loss_is_refused():
    prep, fa, fb = _two_fits()
    with pytest.raises(ValueError, match="loss"):
        comp.paired_block_test(prep, fa, fb, [1], loss="huber")


@pytest.mark.parametrize("ulps", [0, 3])
def test_a_gain_in_a_few_heavy_tailed_samples_is_not_named(ulps):
    # loop spec 11752: a spring-like load at 10 Hz with Student-t noise; before the thirty-seventh round an asymmetric
    # level was named beside it (7.1 % lower held-out RMSE, 88 % of the gain in 5 of 133 held-out samples)
    mod, spec, _, _ = closed_loop_case(11752)
    log, _ = mod.loop_log(spec, reference_ulps=ulps)
    rep = diagnose(log, robot="generic", seed=0, simulate=False)
    d = rep.result
    assert [st.ext.effect for st in d.steps] == ["position_dependent_load"]
    few = [x for x in d.prep.meta["set_aside"] if x.get("gain_in_few_samples")]
    assert [(x["effect"], x["joint"]) for x in few] == [("asymmetric_coulomb", 1)]
    assert few[0]["share_of_squared_error_gain"] >= core.FEW_SAMPLES_GAIN
    assert few[0]["paired_p_value_absolute"] >= core.PAIRED_ALPHA
    assert few[0]["heavy_tails_p_value"] < core.HEAVY_TAILS_ALPHA
    md = markdown(rep.to_dict())
    assert "a few large errors" in md and "asymmetric_coulomb (joint 1)" in md and "heavy-tailed" in md


def test_a_real_later_finding_under_heavy_tails_is_kept():
    # loop spec 7554: Stribeck beside a position load at 10 Hz with Student-t noise; Stribeck's gain is broad
    mod, spec, log, truth = closed_loop_case(7554)
    d = run_diagnosis(log, robot="generic")
    assert {st.ext.effect for st in d.steps} == {e for e in spec["effects"] if not e.startswith("_")}
    assert core.gain_in_few_samples(d.prep, d.steps, d.final_model, d.final_fit, d.sigma) is None
    assert not [x for x in d.prep.meta["set_aside"] if x.get("gain_in_few_samples")]


def test_a_law_on_a_few_slow_samples_under_gaussian_noise_is_kept():
    # loop spec 7378: a Lorentzian Stribeck law beside a load at 10 Hz with Gaussian noise; 17 of the 340 held-out
    # samples (the slow ones) hold Stribeck's whole gain, and the paired absolute errors alone would not show it
    # (p = 0.07): the residual is not heavy-tailed, so the check does not apply
    mod, spec, log, truth = closed_loop_case(7378)
    d = run_diagnosis(log, robot="generic")
    assert [st.ext.effect for st in d.steps] == ["position_dependent_load", "stribeck"]
    assert core.gain_in_few_samples(d.prep, d.steps, d.final_model, d.final_fit, d.sigma) is None
    st = d.steps[1]
    f0 = core.Model(d.prep, [x for x in d.final_model.exts if x is not st.ext]).fit(d.sigma)
    jd = d.prep.joints[1]
    ea, eb = (jd.y - f0.pred[1])[jd.val], (jd.y - d.final_fit.pred[1])[jd.val]
    g = np.sort(ea ** 2 - eb ** 2)[::-1]
    assert g[:int(np.ceil(core.FEW_SAMPLES_SHARE * g.size))].sum() >= core.FEW_SAMPLES_GAIN * g.sum()
    assert comp.paired_block_test(d.prep, f0, d.final_fit, [1], loss="absolute")["p_value"] >= core.PAIRED_ALPHA
    import scipy.stats
    assert scipy.stats.kurtosistest(eb, alternative="greater").pvalue >= core.HEAVY_TAILS_ALPHA
