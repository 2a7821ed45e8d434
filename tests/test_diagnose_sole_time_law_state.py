"""A law in time alone on its joint, while the final residual holds structure in the state, against a free function of
the state (fifty-second round: core.sole_time_law_explained_by_state): set aside when the function explains the law
and, given the law, still explains much of the residual; kept when the two explain each other (a planted change
that the moves make look like a function of the state).  tests/test_diagnose_time_law_state.py follows 13761 through
the whole diagnosis."""
from drake_est.diagnose import core
from drake_est.diagnose.core import Model
from drake_est.diagnose.nominal import prepare

from conftest import closed_loop_case


def _sole_change(k):
    """(prep, model holding only the first round's abrupt-change candidate) of closed-loop spec ``k``."""
    _, _, log, _ = closed_loop_case(k)
    prep = prepare(log, robot="generic")
    m0 = Model(prep)
    cands = {e.effect: e for e in core._candidates(prep, m0, m0.fit(), set())}
    return prep, Model(prep, [cands["abrupt_change"]])


STATE_LEFT = [{"joint": 1, "variable": "position"}]


def test_change_for_a_misfit_of_the_state_is_set_aside():
    # loop spec 13761: an asymmetric level beside Stribeck at 10 Hz with Student-t noise; on an AVX2 CPU the search
    # ended with an abrupt change alone (the change given the state's function 1.1 %, the function given the change
    # 47 %)
    prep, m = _sole_change(13761)
    got = core.sole_time_law_explained_by_state(prep, m, STATE_LEFT, core.ALPHA, core.MIN_GAIN)
    assert got is not None
    effect, joint, why = got
    assert (effect, joint) == ("abrupt_change", 1)
    assert why["sole_law_in_time"] and why["explained_by_state"]
    assert why["state_given_law"]["rmse_reduction"] >= core.MIN_GAIN
    assert why["state_given_law"]["p_value"] < core.ALPHA
    assert "structure in position" in why["reason"]
    # the check runs only where the final residual reports structure in the state, and only on a law alone
    assert core.sole_time_law_explained_by_state(prep, m, [], core.ALPHA, core.MIN_GAIN) is None
    assert core.sole_time_law_explained_by_state(prep, m, [{"joint": 1, "variable": "time"}], core.ALPHA,
                                                 core.MIN_GAIN) is None


def test_planted_change_that_explains_the_state_function_back_is_kept():
    # loop spec 8484: a third-size abrupt change at 50 Hz with Student-t noise; the function of the state explains the
    # change, and the change explains the function: the change stays
    prep, m = _sole_change(8484)
    assert core.sole_time_law_explained_by_state(prep, m, STATE_LEFT, core.ALPHA, core.MIN_GAIN) is None

