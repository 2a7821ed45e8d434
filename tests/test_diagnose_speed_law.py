"""A law in time against a speed law (issue 16, item 2: "energy drift vs an abrupt change vs a speed-dependent
law"): the free friction curve that a drift or a change must beat (competition.speed_law_nuisance /
survives_speed_law), the dissipation check of a change or drift (core.negative_friction), Stribeck laws whose
speed lies beyond the data (detectors.stribeck_speeds with ``falling``), the Gaussian-kernel basis, ks >= 0, and
findings ambiguous with more than one rival (core._competition)."""
import numpy as np
import pytest

from drake_est.data import from_arrays
from drake_est.diagnose import competition as comp
from drake_est.diagnose import core
from drake_est.diagnose import detectors as det
from drake_est.diagnose.nominal import prepare
from drake_est.identification.friction.extensions import columns_at, stribeck_columns

from conftest import bench_module


def _square_axis(levels_first, levels_second, law, change=None, n=24000, h=0.01, seed=0, noise=0.02, log=False):
    """A generic axis (J = 0.2) at constant speed levels, back and forth, smoothed ramps: ``levels_first`` during
    the first half of the log, ``levels_second`` during the second; friction 0.5 qd + 2 sign(qd) + sign(qd)
    law(|qd|); ``change``: (t, dkc) a Coulomb step at time t."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * h
    target = np.zeros(n)
    i, k = 0, 0
    while i < n:
        lv = (levels_first if i < n // 2 else levels_second)[k % (len(levels_first) if i < n // 2 else len(levels_second))]
        m = int(min(3.0, 1.5 / lv) / h)
        target[i:i + m] = lv
        target[i + m:i + 2 * m] = -lv
        i += 2 * m
        k += 1
    kern = np.hanning(31)
    v = np.convolve(target, kern / kern.sum(), mode="same")
    q = np.cumsum(v) * h
    a = np.gradient(v, h)
    s = np.sign(v)
    kc = np.full(n, 2.0)
    if change is not None:
        kc[t >= change[0]] += change[1]
    tau = 0.2 * a + 0.5 * v + kc * s + s * law(np.abs(v)) + noise * rng.standard_normal(n)
    out = from_arrays(t, np.round(q / 1e-6)[:, None] * 1e-6, tau[:, None], joints=[1], meta={"file": "axis"},
                      derivatives=True)
    return out if log else prepare(out, robot="generic")


def _round0(prep):
    model = core.Model(prep)
    fit = model.fit()
    sigma = {j: float(np.sqrt(fit.rss_val[j] / prep.joints[j].val.sum())) for j in prep.joints}
    return model, fit, sigma


def _candidate(prep, model, fit, effect):
    return next(e for e in core._candidates(prep, model, fit, set()) if e.effect == effect)


def test_speed_law_nuisance_is_a_partition_of_unity_per_direction():
    prep = _square_axis([0.05, 0.2, 0.6], [0.05, 0.2, 0.6], lambda s: 0.0 * s)
    N = comp.speed_law_nuisance(prep, 1)
    jd = prep.joints[1]
    v = jd.v[jd.rows]
    half = N.shape[1] // 2
    assert N.shape == (v.size, 2 * comp.SPEED_LAW_KNOTS) and np.all(N >= 0)
    np.testing.assert_allclose(N[:, :half].sum(axis=1), (v > 0).astype(float), atol=1e-12)
    np.testing.assert_allclose(N[:, half:].sum(axis=1), (v < 0).astype(float), atol=1e-12)


def test_a_change_in_time_that_only_follows_the_speeds_is_explained_by_the_speed_law():
    """Slow moves in the first half, fast ones in the second, and a friction excess at low speed that the nominal
    model does not hold: a Coulomb 'change' at mid-log fits it (significant by itself), but not beyond a free
    friction curve; a real Coulomb step on the same axis survives it."""
    law = lambda s: 1.5 / (1.0 + (s / 0.08) ** 2)      # noqa: E731  (Lorentzian excess)
    prep = _square_axis([0.02, 0.04, 0.08], [0.3, 0.6, 1.0], law)
    model, fit, sigma = _round0(prep)
    ext = _candidate(prep, model, fit, "abrupt_change")
    f1 = core.Model(prep, [ext]).fit(sigma)
    alone = core._test(prep, fit, f1, ext)
    assert alone["p_value"] < core.ALPHA and alone["rmse_reduction"] > core.MIN_GAIN
    t = comp.survives_speed_law(prep, model, fit, ext, core.ALPHA, core.MIN_GAIN)
    assert not t["significant"] and t["nuisance_columns"] == 2 * comp.SPEED_LAW_KNOTS

    prep2 = _square_axis([0.05, 0.2, 0.6], [0.05, 0.2, 0.6], lambda s: 0.0 * s, change=(120.0, -0.6))
    model2, fit2, _ = _round0(prep2)
    ext2 = _candidate(prep2, model2, fit2, "abrupt_change")
    assert ext2.spec["t_change"] == pytest.approx(120.0, abs=2.0)
    assert comp.survives_speed_law(prep2, model2, fit2, ext2, core.ALPHA, core.MIN_GAIN)["significant"]
    # a real step with the speeds before and after it disjoint: neither the free curve nor the step adds to the
    # other (time and speed confounded in this log), and the law in time stands
    prep3 = _square_axis([0.02, 0.04, 0.08], [0.3, 0.6, 1.0], lambda s: 0.0 * s, change=(120.0, -0.6))
    model3, fit3, _ = _round0(prep3)
    ext4 = _candidate(prep3, model3, fit3, "abrupt_change")
    t4 = comp.survives_speed_law(prep3, model3, fit3, ext4, core.ALPHA, core.MIN_GAIN)
    assert t4["significant"] and t4["confounded_with_speed"] and t4["speed_law_given_it"]["p_value"] > core.ALPHA
    # diagnosed, that step is named ambiguous between the change and a speed law (whichever wins the round by a few
    # points), and the next experiment repeats the speeds early and late
    from drake_est.diagnose import diagnose
    d = diagnose(_square_axis([0.02, 0.04, 0.08], [0.3, 0.6, 1.0], lambda s: 0.0 * s, change=(120.0, -0.6), log=True),
                 robot="generic", seed=0, simulate=False).to_dict()
    assert len(d["findings"]) == 1
    assert set(d["findings"][0]["ambiguous_between"]) == {"abrupt_change", "stribeck"}
    assert any("repeated early and late" in e.get("experiment", "") for e in d["next_experiment"])
    # a speed law is not a law in time: not tested
    ext3 = _candidate(prep2, model2, fit2, "stribeck")
    assert comp.survives_speed_law(prep2, model2, fit2, ext3, core.ALPHA, core.MIN_GAIN)["skipped"]


def test_a_change_that_leaves_negative_friction_is_not_a_friction_change():
    prep = _square_axis([0.05, 0.2, 0.6], [0.05, 0.2, 0.6], lambda s: 0.0 * s, change=(120.0, -0.6))
    model, fit, sigma = _round0(prep)
    ext = _candidate(prep, model, fit, "abrupt_change")
    m1 = core.Model(prep, [ext])
    f1 = m1.fit(sigma)
    assert core.negative_friction(prep, m1, f1, ext, sigma) is None
    cs = m1.coef_slices(f1, 1)
    assert cs["nominal"]["kc"] + cs["abrupt_change"][1] == pytest.approx(1.4, abs=0.05)
    # the same change with the viscous coefficient after it pushed to -10: at the fastest speed of the log the
    # friction torque 1.4 - 10 * 0.6 N m is negative (the check uses the speeds of the whole log)
    f1.coef[1] = f1.coef[1].copy()
    f1.coef[1][2] = -10.0 - cs["nominal"]["kv"]
    neg = core.negative_friction(prep, m1, f1, ext, sigma)
    assert neg is not None and neg["where"] == "after the change" and neg["friction_torque"] < 0
    assert neg["speed"] == pytest.approx(np.max(np.abs(prep.joints[1].v[prep.joints[1].rows])))


def test_gaussian_kernel_basis_columns():
    v = np.linspace(-1.0, 1.0, 41)
    spec = {"effect": "stribeck", "basis_speeds": [0.1, 0.3], "basis_kernel": "gauss"}
    C = stribeck_columns(v, spec)
    np.testing.assert_allclose(C, np.sign(v)[:, None] * np.exp(-(v[:, None] / np.array([0.1, 0.3])) ** 2))
    np.testing.assert_allclose(columns_at(spec, v, v, v), C)
    # without the key: the exponentials of the earlier reports
    C0 = stribeck_columns(v, {"basis_speeds": [0.1, 0.3]})
    np.testing.assert_allclose(C0, np.sign(v)[:, None] * np.exp(-np.abs(v)[:, None] / np.array([0.1, 0.3])))


def test_a_stribeck_speed_beyond_the_data_is_found_when_the_friction_falls_throughout():
    """Mostly slow moves (0.01-0.08 rad/s, 95 % of the samples) and a few at 0.6 rad/s, with a flat-topped
    (Lorentzian) hump ks / (1 + (qd/vs)^2), vs = 0.2 beyond the 95 % speed: the friction falls over the speeds of
    the log and the nominal viscous coefficient is held at 0.  With ``falling`` the scan reaches three times the
    95 % speed and the fitted friction follows the planted one within 10 % of ks up to 0.6 rad/s (a grid stopped at
    the 95 % speed, as before, missed it by 44 %); the grid of a rising friction stops at a third of the 95 % speed."""
    ks, vs = 2.0, 0.2
    levels = [0.01, 0.02, 0.03, 0.05, 0.08] * 4 + [0.6]
    prep = _square_axis(levels, levels[::-1], lambda s: ks / (1.0 + (s / vs) ** 2))
    model, fit, sigma = _round0(prep)
    assert 1 in fit.kv_held
    jd = prep.joints[1]
    v = jd.v[jd.rows]
    grid = det.stribeck_speeds(v[jd.train], falling=True)
    q95 = np.quantile(np.abs(v[jd.train]), 0.95)
    assert grid[-1] == pytest.approx(3.0 * q95) and det.stribeck_speeds(v[jd.train])[-1] == pytest.approx(q95 / 3)
    assert vs > q95
    ext = _candidate(prep, model, fit, "stribeck")
    m1 = core.Model(prep, [ext])
    f1 = m1.fit(sigma)
    cs = m1.coef_slices(f1, 1)
    s = np.linspace(0.02, 0.6, 50)
    fitted = cs["nominal"]["kc"] + cs["nominal"]["kv"] * s + det.stribeck_curve(ext.spec, cs["stribeck"], s)
    planted = 2.0 + 0.5 * s + ks / (1.0 + (s / vs) ** 2)
    assert np.max(np.abs(fitted - planted)) < 0.1 * ks


def test_stribeck_coefficients_are_nonnegative():
    """ks >= 0 for the law as for the basis (Model.nonneg): a friction that rises faster than viscous from
    standstill is not a Stribeck hump; fitted with the Stribeck column its ks is held at 0."""
    law = lambda s: -1.0 * np.exp(-s / 0.05)      # noqa: E731  (a dip at standstill)
    prep = _square_axis([0.01, 0.03, 0.1, 0.3, 0.8], [0.01, 0.03, 0.1, 0.3, 0.8], law)
    ext = det.Extension("stribeck", 1, {1: stribeck_columns(prep.joints[1].v[prep.joints[1].rows],
                                                            {"vs": 0.05, "delta": 1.0})},
                        ["ks"], {"effect": "stribeck", "vs": 0.05, "delta": 1.0}, {})
    m1 = core.Model(prep, [ext])
    assert m1.nonneg(1) == [0, core.N_NOMINAL]
    f1 = m1.fit()
    assert m1.coef_slices(f1, 1)["stribeck"][0] == pytest.approx(0.0, abs=1e-12)
    # unconstrained, the same column takes the dip with a negative ks
    jd = prep.joints[1]
    A = m1.design(1)
    c = np.linalg.lstsq(A[jd.train], jd.y[jd.train], rcond=None)[0]
    assert c[-1] < -0.5


def test_a_finding_can_be_ambiguous_with_several_rivals():
    """_competition lists every significant rival within the margin, best first, in ``ambiguous_with``; the
    report's ``ambiguous_between`` is the finding followed by them."""
    class E:
        def __init__(self, effect, n):
            self.effect, self.joint, self.cols, self.n_params = effect, 1, {1: None}, n

    w, a, b, c = E("position_dependent_load", 10), E("asymmetric_coulomb", 1), E("abrupt_change", 2), E("stribeck", 1)
    results = [(w, {"score": 100.0, "significant": True}, None, None),
               (a, {"score": 95.0, "significant": True}, None, None),
               (b, {"score": 92.0, "significant": True}, None, None),
               (c, {"score": 50.0, "significant": True}, None, None)]
    out = core._competition(w, results[0][1], results)
    assert out["ambiguous"] and out["ambiguous_with"] == ["asymmetric_coulomb", "abrupt_change"]
    assert out["runner_up"] == "asymmetric_coulomb" and out["margin"] == pytest.approx(5.0)
    results[1] = (a, {"score": 95.0, "significant": False}, None, None)
    out = core._competition(w, results[0][1], results)
    assert out["ambiguous_with"] == ["abrupt_change"] and out["runner_up"] == "asymmetric_coulomb"
    results[2] = (b, {"score": 80.0, "significant": True}, None, None)
    assert not core._competition(w, results[0][1], results)["ambiguous"]


def test_closed_loop_change_with_the_after_change_samples_kept_is_named():
    """Closed-loop spec 50 of the benchmark (an abrupt change of Coulomb and viscous friction, 10 Hz, point-to-point
    moves).  Until the ninth round the nominal outlier screen took out 177 of the ~700 selected samples, most of
    them after the change; the moves left after it ran at other speeds than those before, a free friction curve
    explained the held-out data as well, and the change was reported ambiguous with a speed law (the confound path,
    tested on its own above and in test_diagnose_set_aside.py).  A screen that flags more than
    nominal.OUTLIER_MAX_SHARE of the rows is no longer applied: with every sample kept the change is named outright,
    at the right time, well ahead of its runner-up."""
    loop_log = bench_module("bench_diagnose_testbench").loop_log

    from drake_est.diagnose import diagnose
    log, truth = loop_log(50)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert [f["effect"] for f in d["findings"]] == ["abrupt_change"]
    f = d["findings"][0]
    assert f["status"] == "named" and not f["competition"]["ambiguous"]
    assert d["data"]["excluded"]["1"]["outlier_screen_skipped"] > 0
    # moves are seconds apart at 10 Hz: the change is placed between the move before and the move after it
    assert abs(f["parameters"]["t_change_s"] - truth["abrupt_change"]["t_change"]) < 3.0


def _position_axis(speed_of_q, fric_of_q_v, n=24000, h=0.01, seed=0, noise=0.02, extra=None):
    """A generic axis (J = 0.2) going back and forth over q in [0, 1] with |qd| = speed_of_q(q, pass number);
    friction 0.5 qd + 2 sign(qd) + sign(qd) fric_of_q_v(q, |qd|), plus ``extra(q, qd)`` when given."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * h
    q = np.zeros(n)
    d, k = 1.0, 0
    for i in range(1, n):
        q[i] = q[i - 1] + d * speed_of_q(q[i - 1], k) * h
        if not 0.0 <= q[i] <= 1.0:
            q[i] = min(max(q[i], 0.0), 1.0)
            d, k = -d, k + 1
    kern = np.hanning(31)
    q = np.convolve(np.pad(q, 15, mode="edge"), kern / kern.sum(), mode="valid")
    v = np.gradient(q, h)
    a = np.gradient(v, h)
    s = np.sign(v)
    tau = 0.2 * a + 0.5 * v + 2.0 * s + s * fric_of_q_v(q, np.abs(v)) + noise * rng.standard_normal(n)
    if extra is not None:
        tau = tau + extra(q, v)
    out = from_arrays(t, np.round(q / 1e-6)[:, None] * 1e-6, tau[:, None], joints=[1], meta={"file": "axis"},
                      derivatives=True)
    return prepare(out, robot="generic")


def _position_friction_candidate(prep):
    model, fit, sigma = _round0(prep)
    ext = _candidate(prep, model, fit, "position_dependent_friction")
    return model, fit, ext


def test_position_friction_confounded_with_a_speed_law_when_each_position_has_one_speed():
    """Each position is passed at one speed (|qd| = 0.03 + 0.4 q) and the friction excess is a Lorentzian in |qd|:
    the position kernels fit it, but not beyond a free friction curve (competition.position_law_confounded); with
    three speeds per position and a friction bump in q they are separated."""
    law = lambda q, s: 1.0 / (1.0 + (s / 0.06) ** 2)      # noqa: E731
    prep = _position_axis(lambda q, k: 0.03 + 0.4 * q, law)
    model, fit, ext = _position_friction_candidate(prep)
    c = comp.position_law_confounded(prep, model, fit, ext, core.ALPHA, core.MIN_GAIN)
    assert c is not None
    g = c["position_law_given_speed_law"]
    assert g["p_value"] >= core.ALPHA or g["rmse_reduction"] < core.MIN_GAIN or g["score"] <= 0
    bump = lambda q, s: 0.8 * np.exp(-0.5 * ((q - 0.6) / 0.08) ** 2)      # noqa: E731
    prep = _position_axis(lambda q, k: (0.05, 0.15, 0.45)[(k // 2) % 3], bump)
    model, fit, ext = _position_friction_candidate(prep)
    assert comp.position_law_confounded(prep, model, fit, ext, core.ALPHA, core.MIN_GAIN) is None
    # it applies to the position laws only (friction, load)
    other = _candidate(prep, model, fit, "asymmetric_coulomb")
    assert comp.position_law_confounded(prep, model, fit, other, core.ALPHA, core.MIN_GAIN) is None


def test_position_load_confounded_with_a_speed_law_when_each_position_has_one_speed():
    """A friction excess in one direction only (a Lorentzian in |qd|, none going back), each position passed at
    one speed: a position load (no sign(qd)) takes the half of it common to both directions, but not beyond a free
    friction curve of each direction, so it is confounded with a speed law; a genuine load (a spring-like torque
    in q) under the same motion is separated."""
    zero = lambda q, s: 0.0 * q      # noqa: E731
    one_way = lambda q, v: (v > 0) * 1.0 / (1.0 + (np.abs(v) / 0.06) ** 2)      # noqa: E731
    prep = _position_axis(lambda q, k: 0.03 + 0.4 * q, zero, extra=one_way)
    model, fit, _ = _round0(prep)
    ext = _candidate(prep, model, fit, "position_dependent_load")
    c = comp.position_law_confounded(prep, model, fit, ext, core.ALPHA, core.MIN_GAIN)
    assert c is not None
    g = c["position_law_given_speed_law"]
    assert g["p_value"] >= core.ALPHA or g["rmse_reduction"] < core.MIN_GAIN or g["score"] <= 0
    spring = lambda q, v: 1.5 * (q - 0.5) + 0.6 * np.cos(6.0 * q)      # noqa: E731
    prep = _position_axis(lambda q, k: 0.03 + 0.4 * q, zero, extra=spring)
    model, fit, _ = _round0(prep)
    ext = _candidate(prep, model, fit, "position_dependent_load")
    assert comp.position_law_confounded(prep, model, fit, ext, core.ALPHA, core.MIN_GAIN) is None


@pytest.mark.long
def test_position_friction_that_a_speed_curve_explains_is_not_named_in_spec_165():
    """Loop spec 165 (250 Hz, point-to-point moves, Student-t noise, asymmetric Coulomb + a Lorentzian Stribeck law):
    the Gaussian basis leaves a speed-shaped misfit that 16 position kernels take (2.5 % of the RMSE), once named
    ``ambiguous(position_dependent_friction|abrupt_change)``, neither of them planted, and in the seventh round also
    ambiguous with ``stribeck`` (a free friction curve of each direction explains all the kernels do; the rule is
    tested on its own above).  From the eighth to the twelfth round the finding, accepted after the Stribeck law and
    the asymmetric level with 2.5 % while the residual still held structure, was set aside as not confirmed
    (core.finding_not_confirmed); that structure was the jerk test's false alarm (the viscous coefficient's error,
    a nuisance column since the thirteenth round), and with a white final residual the position friction is
    reported only as ambiguous with the planted Stribeck law: what is named outright is planted."""
    loop_log = bench_module("bench_diagnose_testbench").loop_log

    from drake_est.diagnose import diagnose
    log, truth = loop_log(165)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    planted = set(truth["effects"])
    assert "stribeck" in planted and "position_dependent_friction" not in planted
    pdf = [f for f in d["findings"] if f["effect"] == "position_dependent_friction"]
    assert all("stribeck" in f.get("ambiguous_between", []) for f in pdf), pdf
    for f in d["findings"]:
        assert set(f.get("ambiguous_between", [f["effect"]])) & planted, f["effect"]
        if not f.get("ambiguous_between"):
            assert f["effect"] in planted, f["effect"]


def test_a_rival_within_min_gain_of_the_winners_rmse_is_not_separated():
    """core._competition: a significant rival far behind in score (many held-out samples) but within MIN_GAIN of the
    winner's held-out RMSE, 1 - (1 - r_winner) / (1 - r_rival), is not separated from it (closed-loop spec 1837: a
    position load 0.56 % better than an asymmetric Coulomb level, its load -0.27 to -0.20 N m over the range)."""
    class E:
        def __init__(self, effect, n):
            self.effect, self.joint, self.cols, self.n_params = effect, 1, {1: None}, n

    w, a = E("position_dependent_load", 10), E("asymmetric_coulomb", 1)
    results = [(w, {"score": 13133.5, "significant": True, "rmse_reduction": 0.697266}, None, None),
               (a, {"score": 13090.0, "significant": True, "rmse_reduction": 0.69557}, None, None)]
    out = core._competition(w, results[0][1], results)
    assert out["ambiguous"] and out["ambiguous_with"] == ["asymmetric_coulomb"]
    assert out["separation_below_min_gain"]["asymmetric_coulomb"] == pytest.approx(0.00557, abs=1e-4)
    assert "not separated" in out["reason"]
    # the same scores with the rival 5 % behind in RMSE: separated
    results[1] = (a, {"score": 13090.0, "significant": True, "rmse_reduction": 0.68}, None, None)
    out = core._competition(w, results[0][1], results)
    assert not out["ambiguous"] and "separation_below_min_gain" not in out
    # a rival that is not significant never makes a finding ambiguous
    results[1] = (a, {"score": 13090.0, "significant": False, "rmse_reduction": 0.6969}, None, None)
    assert not core._competition(w, results[0][1], results)["ambiguous"]


def test_a_time_periodic_disturbance_that_follows_a_speed_law_misfit_is_not_named():
    """Closed-loop spec 2032 of the benchmark (a position load and a Lorentz-shaped Stribeck law, 100 Hz,
    point-to-point moves): the exponential Stribeck law fitted leaves a misfit at low speed, and the repeated moves
    make it periodic in time.  Before the tenth round a 0.17 Hz 'time-periodic disturbance' was named on top of
    it; as a law in time it must now beat a free friction curve, which it does not."""
    from drake_est.diagnose import diagnose
    from drake_est.diagnose.testbench_loop import generate
    assert "time_periodic_disturbance" in comp.TIME_LAWS
    # loop_cases(2033)[2032] of benchmarks/bench_diagnose_testbench.py
    log, truth = generate({"stribeck": 1.0, "position_dependent_load": 1.0}, seed=5032, duration=120.0,
                          sample_rate=100.0, noise="gaussian", noise_std=0.04151615071282015, check_visible=False)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    names = {n for f in d["findings"] for n in (f.get("ambiguous_between") or [f["effect"]])}
    assert "time_periodic_disturbance" not in names
    assert {"stribeck", "position_dependent_load"} <= names
    # the friction curve's misfit is left as structure over velocity, with no name
    assert any(u["variable"] == "velocity" for u in d["unexplained"])


@pytest.mark.long
def test_a_load_that_direction_levels_or_a_speed_curve_explain_is_not_named_alone():
    """Loop specs 2453 (asymmetric Coulomb + Stribeck, 10 Hz, quantized torque) and 2662 (a Lorentzian Stribeck
    law, 10 Hz, quantized): under point-to-point moves each position is passed at one speed and in one direction,
    and a position load took the asymmetric level (2453) and the Lorentzian's misfit (2662), named as a load.  Given
    a free friction curve of each direction the load adds nothing, so it is reported ambiguous with a speed law; no
    finding is named without a planted effect among its alternatives.  2453 is run again with the generated
    reference moved by 4 ulps (another CPU's last digits): there the load is taken and later set aside for the
    asymmetric level (the mechanism differs, the outcome does not)."""
    import json
    bench = bench_module("bench_diagnose_testbench")
    judge, loop_cases, loop_log = bench.judge, bench.loop_cases, bench.loop_log
    from drake_est.diagnose import diagnose

    for k, ulps in ((2453, 0), (2453, 4), (2662, 0)):
        spec = loop_cases(k + 1)[k]
        log, truth = loop_log(spec, reference_ulps=ulps)
        d = json.loads(json.dumps(diagnose(log, robot="generic", seed=0, simulate=False).to_dict(), default=str))
        load = [f for f in d["findings"] if f["effect"] == "position_dependent_load"]
        # on these logs the load is found (with the reference moved by 2 ulps, testbench_loop.generate's
        # reference_ulps, it is not, in 2662): where it is, it is reported ambiguous with a speed law
        if load:
            assert load[0]["status"] == "ambiguous", d["findings"]
            c = load[0]["competition"]
            assert c.get("confounded_with_speed") and c.get("position_vs_speed"), c
            assert "stribeck" in c["ambiguous_with"], c
        elif k == 2453:
            aside = [r for r in d["set_aside"] if r["effect"] == "position_dependent_load"]
            assert aside and aside[0]["better"] == "asymmetric_coulomb", (ulps, d["findings"], d["set_aside"])
        assert judge(spec, d, truth["not_visible"])["wrong"] == [], (k, ulps, [f["effect"] for f in d["findings"]])
