"""Every finding against the others (core.finding_to_set_aside) and the Stribeck basis expansion in |qd|
(detectors.stribeck with a shape that one exponential cannot follow)."""
import numpy as np
import pytest

from drake_est.diagnose import core
from drake_est.diagnose import detectors as det
from drake_est.diagnose.nominal import JointData, block_split
from drake_est.diagnose.testbench import generate

from conftest import bench_module, nominal_candidates


def test_a_load_standing_in_for_an_asymmetric_coulomb_level_is_set_aside():
    """Given the nominal Coulomb level, an asymmetric Coulomb friction is a constant torque offset, and a
    position load holds a constant: a load accepted for it (before a ripple) is no longer the best explanation once
    the round is run without it (the asymmetric level scores higher with 1 parameter instead of 10); with the
    planted findings nothing is set aside.  (The last finding is not checked: it won the round before it.)"""
    prep, sigma, cands = nominal_candidates({"asymmetric_coulomb": 1.0, "motor_position_ripple": 1.0}, seed=11)
    wrong = core.Model(prep, [cands["position_dependent_load"], cands["motor_position_ripple"]])
    bad = core.finding_to_set_aside(prep, wrong, sigma, core.ALPHA, core.MIN_GAIN)
    assert bad is not None
    effect, joint, why = bad
    assert (effect, joint) == ("position_dependent_load", 1)
    assert why["better"] == "asymmetric_coulomb" and why["better_score"] > why["score"] + core.AMBIGUITY_MARGIN
    right = core.Model(prep, [cands["asymmetric_coulomb"], cands["motor_position_ripple"]])
    assert core.finding_to_set_aside(prep, right, sigma, core.ALPHA, core.MIN_GAIN) is None


def test_a_finding_that_a_later_one_explains_is_set_aside():
    """A ripple log: a position friction accepted before the ripple is not significant once the ripple is in the
    model, and is set aside (the backward half of a stepwise search)."""
    prep, sigma, cands = nominal_candidates({"motor_position_ripple": 1.0}, seed=5)
    m = core.Model(prep, [cands["position_dependent_friction"], cands["motor_position_ripple"]])
    bad = core.finding_to_set_aside(prep, m, sigma, core.ALPHA, core.MIN_GAIN)
    assert bad is not None and bad[0] == "position_dependent_friction"
    assert bad[2]["reason"] == "not significant given the other findings"


def _axis(law, n=20000, seed=0):
    """A generic axis at many constant speeds with a friction excess towards standstill of the given law."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.01
    levels = np.geomspace(0.01, 1.0, 16)
    v = np.repeat(rng.permutation(np.concatenate([levels, -levels])), n // 32 + 1)[:n]
    tau = 0.5 * v + 2.0 * np.sign(v) + np.sign(v) * law(np.abs(v)) + 0.02 * rng.standard_normal(n)
    rows = np.arange(n)
    jd = JointData(joint=1, col=0, t=t, q=np.cumsum(v) * 0.01, v=v, a=np.zeros(n), tau=tau, rb=np.zeros(n),
                   rows=rows, counts={"thresholds": {"v_min": 0.005, "a_max": 1.0}})
    jd.train, jd.val = block_split(t, rows)
    return jd


def _fit_inner_for(jd):
    X = np.column_stack([jd.v, np.sign(jd.v)])
    block = core.block_index(jd.t, jd.rows)
    a, b = jd.train & (block % 4 == 0), jd.train & (block % 4 == 2)

    def fit_inner(C, nonneg=False):
        A = np.hstack([X, C])
        c = core._lstsq_kv(A[a], jd.y[a], [0] + (list(range(2, A.shape[1])) if nonneg else []))
        e = jd.y[b] - A[b] @ c
        return float(e @ e)
    return X, fit_inner


def test_stribeck_of_another_shape_gets_a_basis_expansion():
    """A heavy-tailed excess ks / (1 + |v|/vs) (falling and convex, but not exp(-|v/vs|^delta)): the basis of
    exponentials in |qd| with nonnegative coefficients wins on the inner split; the friction it gives is the
    planted one within 5 % of ks from the slowest to the fastest speed, its columns are what columns_at evaluates
    (simulation), and the report's ks and vs (the speed where the excess is ks / e, vs (e - 1) here) follow."""
    from drake_est.identification.friction.extensions import columns_at

    ks, vs = 1.5, 0.05
    jd = _axis(lambda s: ks / (1.0 + s / vs))
    X, fit_inner = _fit_inner_for(jd)
    e = det.stribeck(jd, jd.y, fit_inner)
    assert e is not None and e.spec.get("basis_speeds") and e.n_params >= 2
    assert e.evidence["inner_error_basis"] < e.evidence["inner_error_parametric"]
    np.testing.assert_allclose(columns_at(e.spec, jd.q, jd.v, jd.t), e.cols[1], rtol=1e-12)
    A = np.hstack([X, e.cols[1]])
    coef = core._lstsq_kv(A[jd.train], jd.y[jd.train], list(range(A.shape[1])))
    assert np.all(coef[2:] >= 0.0)
    kv_hat, kc_hat, c = coef[0], coef[1], coef[2:]
    s = np.linspace(0.01, 1.0, 200)
    friction = kv_hat * s + kc_hat + det.stribeck_curve(e.spec, c, s)
    assert np.max(np.abs(friction - (0.5 * s + 2.0 + ks / (1 + s / vs)))) < 0.05 * ks
    # the report's parameters from the same coefficients: ks at standstill, vs where the excess is ks / e.  A heavy
    # tail trades with the Coulomb level (kc + ks is what the data fix: the friction at the slowest speed; below it
    # the fastest exponential extrapolates), so ks and vs are looser than the curve
    ks_hat, vs_hat = det.stribeck_ks_vs(e.spec, c)
    assert ks_hat == pytest.approx(ks, rel=0.3)
    assert vs_hat == pytest.approx(vs * (np.e - 1.0), rel=0.3)


def test_stribeck_of_the_exponential_shape_keeps_the_parametric_law():
    jd = _axis(lambda s: 1.5 * np.exp(-(s / 0.08) ** 2))
    _, fit_inner = _fit_inner_for(jd)
    e = det.stribeck(jd, jd.y, fit_inner)
    assert e is not None and "basis_speeds" not in e.spec
    assert e.spec["vs"] == pytest.approx(0.08, rel=0.1) and e.spec["delta"] == pytest.approx(2.0, abs=0.3)


@pytest.mark.long
def test_closed_loop_load_standing_in_for_asymmetry_and_stribeck_is_set_aside():
    """Closed-loop generator, spec 121 of the benchmark (asymmetric Coulomb + Stribeck under point-to-point
    moves, never used while the rule was written): the greedy search named a position load first; the report
    now names the two planted effects and says what it set aside and why."""
    from drake_est.diagnose import diagnose
    log, _ = bench_module("bench_diagnose_testbench").loop_log(121)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert sorted(f["effect"] for f in d["findings"]) == ["asymmetric_coulomb", "stribeck"]
    assert [(r["effect"], r["joint"]) for r in d["set_aside"]] == [("position_dependent_load", 1)]
    assert d["set_aside"][0]["better"] == "asymmetric_coulomb"
    f = next(f for f in d["findings"] if f["effect"] == "asymmetric_coulomb")
    # the paired held-out blocks do not separate the two (p ~ 0.06 on this log, at the level: with the reference
    # moved by 2 ulps, testbench_loop.generate's reference_ulps, they do): when not separated, the simpler one is
    # kept and reported as ambiguous with the load; when separated, it is named outright
    if d["set_aside"][0].get("not_separated"):
        assert d["set_aside"][0]["paired_p_value"] > core.PAIRED_ALPHA
        assert f["ambiguous_between"] == ["asymmetric_coulomb", "position_dependent_load"]
    else:
        assert not f.get("ambiguous_between"), f


def test_paired_block_test_separates_a_real_gain_from_chance():
    """competition.paired_block_test: a model that removes a component of the held-out residual is better beyond
    chance; two models that differ by noise-sized predictions are not (p well above the set-aside level)."""
    from types import SimpleNamespace

    from drake_est.diagnose.competition import paired_block_test

    rng = np.random.default_rng(0)
    n = 12000
    t = np.arange(n) * 0.01
    rows = np.arange(n)
    jd = SimpleNamespace(t=t, rows=rows, y=np.sin(0.7 * t) + 0.1 * rng.standard_normal(n))
    jd.train, jd.val = block_split(t, rows)
    prep = SimpleNamespace(joints={1: jd})
    bad = SimpleNamespace(pred={1: np.zeros(n)})
    good = SimpleNamespace(pred={1: np.sin(0.7 * t)})
    jitter_a = SimpleNamespace(pred={1: np.sin(0.7 * t) + 0.003 * rng.standard_normal(n)})
    jitter_b = SimpleNamespace(pred={1: np.sin(0.7 * t) + 0.003 * rng.standard_normal(n)})
    sep = paired_block_test(prep, bad, good, [1])
    assert sep["p_value"] < 1e-6 and sep["groups"] == 20
    same = paired_block_test(prep, jitter_a, jitter_b, [1])
    assert same["p_value"] > core.PAIRED_ALPHA
    assert paired_block_test(prep, good, bad, [1])["p_value"] > 0.99     # one-sided
    # a warm-up: the gain is large early and small, but of the same sign, later (a t-test's variance would be
    # dominated by the first group; the signed-rank test counts the consistent sign)
    drift = 2.0 * np.exp(-t / 6.0) + 0.05
    jd.y = drift + 0.1 * rng.standard_normal(n)
    warm = paired_block_test(prep, SimpleNamespace(pred={1: np.zeros(n)}), SimpleNamespace(pred={1: drift}), [1])
    assert warm["p_value"] < 1e-4 and warm["groups_better"] >= 18


@pytest.mark.long
def test_rival_that_does_not_separate_on_held_out_blocks_makes_the_finding_ambiguous():
    """Closed-loop out-of-sample spec 143 (asymmetric Coulomb + a Gaussian-shaped Stribeck law under
    point-to-point moves).  With the fourth round's Stribeck fit a position load scored 135 above the asymmetric
    level given the Stribeck term, but the paired held-out blocks did not separate them (p ~ 0.7): the finding was
    reported as ambiguous between the two, not replaced by the load (the third round's wrong name).  Since the
    fifth round (ks >= 0, a Stribeck grid beyond the data when the friction falls throughout) the Stribeck term fits
    well enough that the load no longer scores above the asymmetric level; the asymmetric level is named, and if a
    rival is reported beside it, it is the load it was not separated from.  Checked at reference_ulps 0 and 3: at 3
    the load is taken first and then set aside (the mechanism differs, the outcome does not), or, on the twentieth
    round's CPU, kept and reported as ambiguous with the asymmetric level."""
    from drake_est.diagnose import diagnose
    loop_log = bench_module("bench_diagnose_testbench").loop_log
    for ulps in (0, 3):
        _check_spec_143(loop_log(143, reference_ulps=ulps)[0], diagnose)


def _check_spec_143(log, diagnose):
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    effects = sorted(f["effect"] for f in d["findings"])
    if effects == ["position_dependent_load", "stribeck"]:
        # the twentieth round's CPU (AMD EPYC) at 3 ulps: the load is taken first and kept, but reported as ambiguous
        # with the asymmetric level it is not separated from (no cause named that the data prefer to the planted one;
        # the benchmark counts it correct); another CPU's last digits set it aside instead (below)
        f = next(f for f in d["findings"] if f["effect"] == "position_dependent_load")
        assert f["ambiguous_between"] == ["position_dependent_load", "asymmetric_coulomb"], f
        assert not d["set_aside"], d["set_aside"]
        return
    assert effects == ["asymmetric_coulomb", "stribeck"], d["findings"]
    f = next(f for f in d["findings"] if f["effect"] == "asymmetric_coulomb")
    if f.get("ambiguous_between"):
        assert f["ambiguous_between"] == ["asymmetric_coulomb", "position_dependent_load"]
        # not separated on the held-out blocks, or (ninth round) within MIN_GAIN of the asymmetry's held-out RMSE
        c = f["competition"]
        assert (c.get("paired_p_value", 0.0) > core.PAIRED_ALPHA
                or c.get("separation_below_min_gain", {}).get("position_dependent_load", 1.0) < core.MIN_GAIN)
    else:
        assert f["competition"]["runner_up"] == "position_dependent_load" and f["competition"]["margin"] > 0
    # where the load is taken first (the generated reference 3 ulps off, another CPU's last digits) it is set aside
    # for the asymmetric level it did not separate from, or (above) kept as ambiguous with it
    for r in d["set_aside"]:
        assert (r["effect"], r["joint"], r["better"]) == ("position_dependent_load", 1, "asymmetric_coulomb"), r
        assert not r.get("not_separated") or r["paired_p_value"] > core.PAIRED_ALPHA


class _Ext:
    def __init__(self, effect, joint=1, shared=False):
        self.effect, self.joint, self.shared = effect, joint, shared


class _Step:
    def __init__(self, effect, competition, joint=1):
        self.ext, self.competition = _Ext(effect, joint), dict(competition)


def test_an_ambiguity_whose_rival_is_also_named_is_resolved():
    """"A or B" where B is a finding of the same joint too: the data need both, so B leaves ``ambiguous_with``
    (listed under ``resolved_with``).  A rival named on another joint, a law in time confounded with a free friction
    curve, and a finding of a model whose final check did not run stay ambiguous."""
    amb = {"ambiguous": True, "runner_up": "abrupt_change", "ambiguous_with": ["abrupt_change"], "reason": "r"}
    steps = [_Step("position_dependent_friction", amb), _Step("abrupt_change", {"ambiguous": False})]
    core._resolve_named_rivals(steps, checked=True)
    c = steps[0].competition
    assert not c["ambiguous"] and c["resolved_with"] == ["abrupt_change"] and "ambiguous_with" not in c
    assert "also named" in c["reason"]
    # two rivals, one named: the other stays
    two = dict(amb, ambiguous_with=["abrupt_change", "position_dependent_load"])
    steps = [_Step("position_dependent_friction", two), _Step("abrupt_change", {"ambiguous": False})]
    core._resolve_named_rivals(steps, checked=True)
    assert steps[0].competition["ambiguous"] and steps[0].competition["ambiguous_with"] == ["position_dependent_load"]
    # the rival on another joint
    steps = [_Step("position_dependent_friction", amb), _Step("abrupt_change", {"ambiguous": False}, joint=2)]
    core._resolve_named_rivals(steps, checked=True)
    assert steps[0].competition["ambiguous"]
    # confounded with a speed law
    conf = dict(amb, ambiguous_with=["stribeck"], confounded_with_speed=True)
    steps = [_Step("abrupt_change", conf), _Step("stribeck", {"ambiguous": False})]
    core._resolve_named_rivals(steps, checked=True)
    assert steps[0].competition["ambiguous"]
    # the final check did not run: only the last finding (accepted given the earlier ones) is resolved
    steps = [_Step("position_dependent_friction", amb), _Step("abrupt_change", {"ambiguous": False})]
    core._resolve_named_rivals(steps, checked=False)
    assert steps[0].competition["ambiguous"]
    steps = [_Step("abrupt_change", {"ambiguous": False}), _Step("position_dependent_friction", amb)]
    core._resolve_named_rivals(steps, checked=False)
    assert not steps[1].competition["ambiguous"]


def test_position_friction_and_a_change_both_named_outright():
    """Testbench spec 10 of the benchmark (a position friction and an abrupt change, 50 Hz, Student-t noise): in
    its round the position friction is not separated on the held-out blocks from a change (paired p 0.32); the
    change is named in the next round, and the report names both outright."""
    from drake_est.diagnose import diagnose
    log, _ = generate({"position_dependent_friction": 1.0, "abrupt_change": 1.0}, seed=1010, duration=120.0,
                      sample_rate=50.0, speeds=6, noise="student_t", noise_std=0.05586899305534607)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert sorted(f["effect"] for f in d["findings"]) == ["abrupt_change", "position_dependent_friction"]
    assert not any(f.get("ambiguous_between") for f in d["findings"])
    pf = next(f for f in d["findings"] if f["effect"] == "position_dependent_friction")
    assert pf["competition"]["resolved_with"] == ["abrupt_change"]


def test_asymmetric_level_or_load_gets_a_concrete_next_experiment():
    """A quantized asymmetric-Coulomb log of the testbench (spec 26 of the benchmark) whose finding is ambiguous
    between the asymmetric level and a position load (and, since the twelfth round, a speed law: a free friction
    curve explains the load as well): the next experiment names the joint, speeds inside the log's range and the
    position range the log covered, with rests across it."""
    from drake_est.diagnose import diagnose
    log, _ = generate({"asymmetric_coulomb": 1.0}, seed=1026, duration=120.0, sample_rate=100.0, speeds=6,
                      noise="quantized", noise_std=0.023708521244188586)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    amb = [f for f in d["findings"] if f.get("ambiguous_between")]
    assert amb and {"asymmetric_coulomb", "position_dependent_load"} <= set(amb[0]["ambiguous_between"])
    exp = next(e for e in d["next_experiment"] if e["reason"].startswith("ambiguous"))
    assert exp["joint"] == 1 and "rests" in exp["experiment"]
    lo, hi = min(exp["speeds"]), max(exp["speeds"])
    v = np.abs(np.gradient(log.q[:, 0], log.t))
    assert 0 < lo < hi <= v.max()
    qa, qb = exp["position_range_covered"]
    assert np.isclose(qa, log.q[:, 0].min(), atol=1e-6) and np.isclose(qb, log.q[:, 0].max(), atol=1e-6)
