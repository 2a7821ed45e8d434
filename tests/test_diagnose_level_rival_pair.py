"""An asymmetric level that a position load with a second law predicts worse than is reported ambiguous with the
load (fifty-ninth round: core.mark_level_within_rival_pair)."""
import pytest

from drake_est.diagnose import core, diagnose
from drake_est.diagnose.core import Model

from conftest import closed_loop_case


@pytest.fixture(scope="module")
def load_beside_stribeck():
    # loop spec 21436: a spring-like load beside a Gaussian Stribeck law at 10 Hz; the joint moves forward at negative
    # positions and back at positive ones, so the direction is a function of the position and the level (a constant
    # torque while moving) takes the load's mean; neither planted law wins a round alone
    _, _, log, truth = closed_loop_case(21436)
    assert sorted(truth["effects"]) == ["position_dependent_load", "stribeck"]
    return diagnose(log, robot="generic", seed=0, simulate=False), truth


def test_the_level_is_ambiguous_with_the_load(load_beside_stribeck):
    rep, _ = load_beside_stribeck
    d = rep.to_dict()
    lvl = [f for f in d["findings"] if f["effect"] == "asymmetric_coulomb"]
    assert len(lvl) == 1
    f = lvl[0]
    assert "position_dependent_load" in f["ambiguous_between"]
    pair = f["competition"]["rival_pair"]
    # the load's pair takes the Stribeck law, and predicts the held-out blocks better than the level's pair
    assert pair["rival_pair"] == ["position_dependent_load", "stribeck"]
    assert pair["heldout_rmse_rival_pair"] < pair["heldout_rmse_level_pair"]
    assert pair["paired_p_value"] < core.PAIRED_ALPHA
    assert pair["groups_rival_pair_better"] > pair["paired_groups"] / 2
    assert "neither law of that pair wins a round alone" in f["competition"]["reason"]


def test_the_check_needs_structure_in_the_final_residual(load_beside_stribeck):
    rep, _ = load_beside_stribeck
    prep, model = rep.result.prep, rep.result.final_model
    steps = [core.Step(st.ext, st.test, st.fit, st.validation, st.validation_joint, {}) for st in rep.result.steps]
    sigma = rep.result.sigma
    assert core.mark_level_within_rival_pair(prep, model, steps, [], sigma) == []
    assert all(not st.competition for st in steps)
    # with an entry on another joint nothing is checked either; on the level's joint the step is marked
    assert core.mark_level_within_rival_pair(prep, model, steps, [{"joint": 2, "variable": "time"}], sigma) == []
    got = core.mark_level_within_rival_pair(prep, model, steps, [{"joint": 1, "variable": "time"}], sigma)
    assert [st.ext.effect for st in got] == ["asymmetric_coulomb"]
    assert got[0].competition["ambiguous_with"] == ["position_dependent_load"]


def test_a_planted_level_that_the_pairs_decide_is_not_marked():
    # loop spec 1507 (a level beside Stribeck at 100 Hz): named outright, with velocity and time-shift entries in the
    # final residual, so the check runs; the load contains the level there, but its best pair does not predict the
    # held-out blocks better than the level's
    _, _, log, truth = closed_loop_case(1507)
    assert sorted(truth["effects"]) == ["asymmetric_coulomb", "stribeck"]
    rep = diagnose(log, robot="generic", seed=0, simulate=False)
    d = rep.to_dict()
    assert sorted(f["effect"] for f in d["findings"]) == ["asymmetric_coulomb", "stribeck"]
    assert all("rival_pair" not in f["competition"] for f in d["findings"])
    prep, model = rep.result.prep, rep.result.final_model
    lvl = [e for e in model.exts if e.effect == "asymmetric_coulomb"][0]
    base = Model(prep, [e for e in model.exts if e is not lvl])
    cands = core._joint_candidates(prep, base, base.fit(rep.result.sigma), 1,
                                   {(e.effect, e.joint) for e in model.exts})
    assert any(core._contains(prep, c, lvl) for c in cands), "the check must have had a rival to compare"
    steps = [core.Step(st.ext, st.test, st.fit, st.validation, st.validation_joint, {}) for st in rep.result.steps]
    assert core.mark_level_within_rival_pair(prep, model, steps, [{"joint": 1, "variable": "velocity"}],
                                             rep.result.sigma) == []
