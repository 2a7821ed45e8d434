"""Stribeck / time-periodic candidates, competing explanations, the unexplained verdict and next_experiment."""
import numpy as np
import pytest

from drake_est.diagnose.testbench import generate
from drake_est.diagnose.unexplained import _anova, _whiteness


def test_anova_flags_dependence_and_passes_noise():
    rng = np.random.default_rng(0)
    x = rng.uniform(-1, 1, 4000)
    e = rng.normal(0, 1, 4000)
    p0, share0, _ = _anova(x, e)
    p1, share1, _ = _anova(x, e + 0.8 * np.sin(3 * x))
    assert p0 > 1e-3 and share0 < 0.02
    assert p1 < 1e-10 and share1 > 0.1


def test_whiteness_flags_correlated_residual():
    rng = np.random.default_rng(1)
    w = rng.normal(0, 1, 5000)
    ar = np.zeros_like(w)
    for i in range(1, w.size):
        ar[i] = 0.7 * ar[i - 1] + w[i]
    block = np.repeat(np.arange(50), 100)
    assert _whiteness(w, block)[0] > 1e-3
    p, share, c1 = _whiteness(ar, block)
    assert p < 1e-10 and share > 0.3 and c1 == pytest.approx(0.7, abs=0.1)


def test_testbench_plants_what_it_says():
    log0, _ = generate({}, seed=3, duration=30, sample_rate=50, noise_std=0.0)
    log1, tr = generate({"stribeck": 1.0}, seed=3, duration=30, sample_rate=50, noise_std=0.0)
    d = log1.tau[:, 0] - log0.tau[:, 0]
    s = tr["stribeck"]
    v = log0.dq[:, 0]
    assert np.max(np.abs(d)) == pytest.approx(s["ks"], rel=0.3)
    assert np.abs(d[np.abs(v) > 5 * s["vs"]]).max() < 0.05 * s["ks"]


@pytest.mark.parametrize("effect,kw", [("stribeck", {"_vs": 0.1}), ("time_periodic_disturbance", {"_f_hz": 3.0})])
def test_new_effects_named_not_confused(effect, kw):
    from drake_est.diagnose import diagnose
    log, truth = generate({effect: 1.0, **kw}, seed=5, duration=90, sample_rate=50, noise_std=0.05)
    d = diagnose(log, robot="generic", simulate=False).to_dict()
    names = [f["effect"] for f in d["findings"]]
    assert names and names[0] == effect, names
    assert set(names) <= {effect}, names
    f = d["findings"][0]
    assert f["competition"]["runner_up"] not in (None, effect)
    assert f["competition"]["margin"] > 0
    if effect == "time_periodic_disturbance":
        assert f["evidence"]["frequency_hz"] == pytest.approx(3.0, rel=0.01)
    else:
        assert f["parameters"].get("vs", f["evidence"]["stribeck_velocity"]) == pytest.approx(0.1, rel=0.6)
    assert isinstance(d["unexplained"], list) and isinstance(d["next_experiment"], list)


@pytest.mark.slow
def test_null_log_nothing_named_nothing_unexplained():
    from drake_est.diagnose import diagnose
    for noise in ("gaussian", "student_t", "quantized"):
        log, _ = generate({}, seed=7, duration=90, sample_rate=100, noise=noise)
        d = diagnose(log, robot="generic", simulate=False).to_dict()
        assert d["findings"] == [] and d["unexplained"] == [], noise


def test_out_of_vocabulary_delay_is_unexplained_not_named():
    from drake_est.diagnose import diagnose
    log, _ = generate({"delay": 1.0}, seed=11, duration=120, sample_rate=100)
    d = diagnose(log, robot="generic", simulate=False).to_dict()
    assert d["findings"] == []
    assert d["unexplained"] and d["unexplained"][0]["share_of_residual_variance"] > 0.08


def test_concatenate_logs_holds_out_whole_logs():
    from drake_est.diagnose import concatenate_logs
    from drake_est.diagnose.nominal import prepare
    from drake_est.errors import DataError
    logs = [generate({}, seed=s, duration=30, sample_rate=50)[0] for s in (1, 2, 3)]
    cat = concatenate_logs(logs)
    assert cat.n_samples == sum(lg.n_samples for lg in logs)
    assert np.all(np.diff(cat.t) > 0)
    prep = prepare(cat, robot="generic")
    jd = prep.joints[1]
    li = cat.channels["log_index"][jd.rows].astype(int)
    assert set(li[jd.train]) == {0, 2} and set(li[jd.val]) == {1}
    with pytest.raises(DataError):
        concatenate_logs(logs[:1])
