"""The model-level rival of a finding that holds its joint's asymmetric Coulomb level (core.level_alternatives): the
search run again with the finding closed; when it ends at the same findings with the level in the finding's place and
the held-out blocks do not separate the two final models, the finding is reported ambiguous with the level."""
import pytest

from conftest import bench_module, nominal_candidates
from drake_est.diagnose import core
from drake_est.diagnose import detectors as det


@pytest.mark.long
@pytest.mark.parametrize("ulps", [0, 3])
def test_loop_case_5775_load_is_ambiguous_with_the_level_it_holds(ulps):
    """Closed-loop spec 5775 (250 Hz: an asymmetric Coulomb level beside a Lorentzian Stribeck law).  The load won
    the first round and Stribeck was fitted beside it; given that Stribeck law the load beats the level by 6.7 % of
    the RMSE.  With the load closed the search ends at the level and a Stribeck law fitted beside it, and the held-out
    blocks do not show the load's model predicting better (paired p = 0.18 on the reference CPU): the load is
    reported ambiguous with the level (it was named outright, a wrong name)."""
    from drake_est.diagnose import diagnose
    log, truth = bench_module("bench_diagnose_testbench").loop_log(5775, reference_ulps=ulps)
    assert sorted(truth["effects"]) == ["asymmetric_coulomb", "stribeck"]
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert [f["effect"] for f in d["findings"]] == ["position_dependent_load", "stribeck"]
    load = d["findings"][0]
    assert load["ambiguous_between"] == ["position_dependent_load", "asymmetric_coulomb"]
    if "alternative_model" not in load["competition"]:
        # on an AVX2 CPU at 3 ulps the load's own round already leaves it ambiguous with the level (paired p = 0.053,
        # the blocks do not separate the two), and no alternative is needed
        assert load["competition"]["paired_p_value"] >= core.PAIRED_ALPHA
        return
    alt = load["competition"]["alternative_model"]
    assert alt["findings"] == ["asymmetric_coulomb", "stribeck"]
    assert load["competition"]["paired_p_value"] >= core.PAIRED_ALPHA
    # the final model predicts better on the whole, but not block by block
    assert alt["heldout_rmse_of_final_model"] < alt["heldout_rmse"]


def test_only_a_finding_that_holds_the_level_and_not_beside_it_gets_an_alternative(monkeypatch):
    """A load holds the level (its kernels sum to a constant over the visited positions); a position friction
    (kernels times sign(qd)) does not.  A model that already names the level gets no alternative, and neither does
    one whose finding does not hold it: the search is not run again for them."""
    prep, sigma, cands = nominal_candidates({"position_dependent_load": 1.0}, seed=3)
    lvl = det.asymmetric(prep.joints[1], None)
    assert core._contains(prep, cands["position_dependent_load"], lvl)
    assert not core._contains(prep, cands["position_dependent_friction"], lvl)
    runs = []
    monkeypatch.setattr(core, "_search", lambda *a, **k: runs.append(a) or (_ for _ in ()).throw(AssertionError))
    for exts in ([cands["position_dependent_friction"]],
                 [cands["position_dependent_load"], cands["asymmetric_coulomb"]]):
        model = core.Model(prep, exts)
        assert core.level_alternatives(prep, model, model.fit(sigma), core.MAX_FINDINGS, core.ALPHA,
                                       core.MIN_GAIN) == {}
    assert runs == []


def test_a_planted_load_is_separated_from_the_level():
    """A planted position load (no asymmetric level): with the load closed the search names the level in its place,
    and the held-out blocks show the load's model predicting better in every group, so the load stays named
    outright."""
    from drake_est.diagnose import competition as comp
    prep, sigma, cands = nominal_candidates({"position_dependent_load": 1.0}, seed=3)
    model = core.Model(prep, [cands["position_dependent_load"]])
    fit = model.fit(sigma)
    alt = core._search(prep, core.MAX_FINDINGS, core.ALPHA, core.MIN_GAIN, {("position_dependent_load", 1)})
    assert [e.effect for e in alt[5].exts] == ["asymmetric_coulomb"]
    assert comp.paired_block_test(prep, alt[4], fit, [1])["p_value"] < core.PAIRED_ALPHA
    assert core.level_alternatives(prep, model, fit, core.MAX_FINDINGS, core.ALPHA, core.MIN_GAIN) == {}
