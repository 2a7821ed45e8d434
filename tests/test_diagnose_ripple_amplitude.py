"""The eighty-seventh round: a finding beside a constant-amplitude motor-position ripple of its joint is held against the
ripple with the detector's speed-dependent amplitude (``core.RIPPLE_AMPLITUDE_RULE``;
``benchmarks/results/diagnose_ripple_amplitude_round87_rule.txt``)."""
import numpy as np
import pytest

from drake_est.diagnose import core, detectors as det, diagnose


@pytest.fixture(scope="module")
def design_case():
    from conftest import closed_loop_case
    return closed_loop_case(31044)


def test_spec_31044_names_the_ripple_alone_with_the_rule_on(monkeypatch, design_case):
    """The design log: off, the ripple and an energy drift; on, the drift is set aside, explained one way by the
    ripple with a speed-dependent amplitude."""
    mod, spec, log, truth = design_case
    monkeypatch.setattr(core, "RIPPLE_AMPLITUDE_RULE", False)
    off = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert sorted(f["effect"] for f in off["findings"]) == ["energy_dependent_friction", "motor_position_ripple"]
    assert mod.judge(spec, off)["wrong"] == ["energy_dependent_friction"]
    monkeypatch.setattr(core, "RIPPLE_AMPLITUDE_RULE", True)
    rep = diagnose(log, robot="generic", seed=0, simulate=False)
    on = rep.to_dict()
    assert [f["effect"] for f in on["findings"]] == truth["planted"] == ["motor_position_ripple"]
    j = mod.judge(spec, on)
    assert j["correct"] and not j["wrong"] and not j["missed"]
    aside = [x for x in on["set_aside"] if x.get("explained_by_ripple_amplitude")]
    assert [x["effect"] for x in aside] == ["energy_dependent_friction"]
    x = aside[0]
    assert x["finding_given_ripple_amplitude"]["p_value"] > core.ALPHA
    assert x["ripple_amplitude_given_finding"]["p_value"] < core.ALPHA
    assert x["heldout_rmse_reduction_alone"] > core.MIN_GAIN
    assert on["findings"][0]["evidence"]["amplitude_basis_functions"] == 1


def test_the_speed_dependent_columns_span_the_constant_ripple(monkeypatch, design_case):
    """:func:`core.ripple_amplitude_nuisance`: RIPPLE_BASIS columns per cosine and sine of each component, whose span
    holds the constant-amplitude ripple (the basis is normalized), so the test given them asks only what the speed
    adds; None for a ripple whose amplitude already follows the speed."""
    from drake_est.identification.friction.extensions import RippleRegressors, ripple_regressors
    _, _, log, _ = design_case
    monkeypatch.setattr(core, "RIPPLE_AMPLITUDE_RULE", True)
    res = diagnose(log, robot="generic", seed=0, simulate=False).result
    rip = next(e for e in res.final_model.exts if e.effect == "motor_position_ripple")
    N = core.ripple_amplitude_nuisance(res.prep, rip)
    C = rip.cols[rip.joint]
    nf = ripple_regressors(rip.spec).freqs.size
    assert C.shape[1] == 2 * nf and N.shape == (C.shape[0], 2 * nf * det.RIPPLE_BASIS)
    coef = np.linalg.lstsq(N, C, rcond=None)[0]
    assert np.abs(N @ coef - C).max() < 1e-8 * np.abs(C).max()
    rr = ripple_regressors(rip.spec)
    speed = RippleRegressors(rr.freqs, {**rr.basis_spec, "n_basis": det.RIPPLE_BASIS})
    moved = type(rip)(rip.effect, rip.joint, rip.cols, rip.names, {**rip.spec, "_pc": speed}, rip.evidence)
    assert core.ripple_amplitude_nuisance(res.prep, moved) is None


def test_off_the_check_is_silent(monkeypatch, design_case):
    """With the switch off the check returns None without fitting anything."""
    monkeypatch.setattr(core, "RIPPLE_AMPLITUDE_RULE", False)
    assert core.finding_explained_by_ripple_amplitude(None, None, core.ALPHA, core.MIN_GAIN) is None


def test_kept_and_its_table_is_its_jsons():
    """Kept: the switch is on; the docs' table holds each probe JSON's row as --against-off-rows prints it; lanes a and
    b are the 1,472 closed-loop logs whose kept rows named a ripple and one of the laws (alternate keys), lane c the 8
    open-loop ones, lane d the 4 of the fresh block 31100-31199; the rule fired in the design log only, which lost its
    wrong name (its rule-on row is now its kept row), and nothing was lost."""
    from conftest import assert_rule_mended_only, bench_module, probe_lanes
    assert core.RIPPLE_AMPLITUDE_RULE is True
    probe = bench_module("probe_ripple_amplitude")
    assert probe.LAWS == core.RIPPLE_AMPLITUDE_EFFECTS
    doc, files, examined, s = probe_lanes(probe, "diagnose_ripple_amplitude_round87_lane_*.json", lanes="abcd")
    assert [len(d["keys_examined"]) for _, d in files] == [736, 736, 8, 4]
    assert len(examined["loop"]) == 1476 and len(examined["testbench"]) == 8 and 31044 in examined["loop"]
    assert_rule_mended_only("diagnose_ripple_amplitude_round87_lane_*.json", files, s, 31044)
    assert f"{sum(len(d['keys_examined']) for _, d in files):,}" in doc
