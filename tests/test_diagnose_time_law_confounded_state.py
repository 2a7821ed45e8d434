"""A friction law in time beside a time-periodic disturbance on its joint, which a free function of the joint's state
explains but which stays (alone it predicts better than that function), is reported ambiguous with the laws of the
state the function is made of (sixty-fourth round: core.mark_disturbance_confounded_with_state)."""
import pytest

from drake_est.diagnose import core, diagnose
from drake_est.diagnose.core import ALPHA, MIN_GAIN

from conftest import closed_loop_case


@pytest.fixture(scope="module")
def slow_position_friction():
    # loop spec 23681: a position friction and a 10 Hz disturbance at 10 Hz with Student-t noise and slow moves; an
    # abrupt change takes the position friction's part
    _, _, log, truth = closed_loop_case(23681)
    assert truth["effects"] == ["position_dependent_friction", "time_periodic_disturbance"]
    return diagnose(log, robot="generic", seed=0, simulate=False), truth


def test_the_change_is_ambiguous_with_the_position_friction(slow_position_friction):
    rep, _ = slow_position_friction
    d = rep.to_dict()
    change = [f for f in d["findings"] if f["effect"] == "abrupt_change"]
    assert len(change) == 1
    f = change[0]
    assert f["status"] == "ambiguous"
    assert "position_dependent_friction" in f["ambiguous_between"]
    info = f["competition"]["confounded_with_state"]
    assert "position_friction" in info["blocks"]
    assert not set(info["blocks"]) & set(core.DISTURBANCE_DRIVEN_BLOCKS)
    t = info["finding_given_state"]
    assert not (t["p_value"] < ALPHA and t["rmse_reduction"] >= MIN_GAIN)
    assert "disturbance_given_state" not in info
    # kept, not set aside: alone it predicts better than the state's function alone
    assert info["heldout_rmse_reduction_alone"] > info["state_heldout_rmse_reduction_alone"]
    assert "a law in time fits part of it" in f["competition"]["reason"]
    # the disturbance beside it is on the same joint, and the change's earlier rivals stay
    dist = [x for x in d["findings"] if x["effect"] == "time_periodic_disturbance"]
    assert dist and dist[0]["joint"] == f["joint"]
    assert {"energy_dependent_friction", "stribeck"} <= set(f["ambiguous_between"])


def test_a_change_without_a_disturbance_finding_is_not_marked():
    # loop spec 2012: a planted abrupt change beside a ripple at 10 Hz; the disturbance is only the ripple's rival
    _, _, log, truth = closed_loop_case(2012)
    rep = diagnose(log, robot="generic", seed=0, simulate=False)
    assert "abrupt_change" in rep.effects
    assert "time_periodic_disturbance" not in rep.effects
    f = [x for x in rep.to_dict()["findings"] if x["effect"] == "abrupt_change"][0]
    assert "confounded_with_state" not in f["competition"]
    assert core.mark_disturbance_confounded_with_state(rep.result.prep, rep.result.final_model, rep.result.steps,
                                                       ALPHA, MIN_GAIN) == []
