"""A disturbance periodic in time off the motion's lines must beat a free function of the joint's state given the
final model's other findings (core.disturbance_explained_by_state): where the moves are slow, a misfit of the
model's laws of the state is slow in time too, and a sinusoid of a few periods per log fits it."""
import numpy as np
import pytest

from drake_est.diagnose import competition as comp
from drake_est.diagnose import core
from drake_est.diagnose.core import Model, run_diagnosis
from drake_est.diagnose.nominal import prepare

from conftest import closed_loop_case, search_names


@pytest.mark.parametrize("ulps", [0, pytest.param(3, marks=pytest.mark.long)])
def test_a_slow_misfit_of_the_state_is_not_named_a_disturbance(monkeypatch, ulps):
    # loop spec 10942: a position load beside a Lorentzian Stribeck law at 250 Hz, nearly every moving sample below
    # twice the Stribeck speed; before the thirty-sixth round a disturbance at 0.087 Hz (17 % lower held-out RMSE, not
    # planted, not at a line of the motion) was named for the misfit.  The disturbance comes up after the inertia
    # backfit's move of J (1.35 -> 8.3, the generator's 1.27), which the fifty-fourth round's check withholds
    # (test_a_withheld_inertia_move_leaves_no_disturbance_to_set_aside): the check of the state is followed with the
    # move made
    monkeypatch.setattr(core, "inertia_move_contradicted", lambda *a, **k: None)
    mod, spec, _, _ = closed_loop_case(10942)
    planted = {e for e in spec["effects"] if not e.startswith("_")}
    log, _ = mod.loop_log(spec, reference_ulps=ulps)
    d = run_diagnosis(log, robot="generic")
    assert "time_periodic_disturbance" not in search_names(d)
    away = [x for x in d.prep.meta["set_aside"] if x.get("explained_by_state")]
    assert [(x["effect"], x["joint"]) for x in away] == [("time_periodic_disturbance", 1)]
    t = away[0]["state_law_test"]
    assert not (t["p_value"] < core.ALPHA and t["rmse_reduction"] >= core.MIN_GAIN)
    assert "function of the state of joint 1" in away[0]["reason"]
    # what is named is planted (the level is ambiguous with the planted load)
    named = set(search_names(d))
    assert named & planted and named <= planted | {"asymmetric_coulomb"}


@pytest.mark.long
def test_a_withheld_inertia_move_leaves_no_disturbance_to_set_aside():
    # the same log with the fifty-fourth round's check: J stays at prepare's, and no disturbance comes up at all
    mod, spec, log, truth = closed_loop_case(10942)
    planted = {e for e in spec["effects"] if not e.startswith("_")}
    d = run_diagnosis(log, robot="generic")
    jd = d.prep.joints[1]
    assert "inertia_backfit_withheld" in jd.counts and "inertia_before_backfit" not in jd.counts
    assert jd.counts["inertia"] == pytest.approx(truth["J"], rel=0.1)
    assert not [x for x in d.prep.meta["set_aside"] if x.get("explained_by_state")]
    named = set(search_names(d))
    assert named & planted and named <= planted | {"asymmetric_coulomb"}


def test_a_disturbance_from_outside_the_axis_is_kept_given_the_state():
    # loop spec 67: a disturbance at 0.5 Hz alone, 1000 Hz, Student-t noise
    mod, spec, log, truth = closed_loop_case(67)
    d = run_diagnosis(log, robot="generic")
    assert [st.ext.effect for st in d.steps] == ["time_periodic_disturbance"]
    assert "at_motion_line_hz" not in d.steps[0].ext.evidence
    assert not [x for x in d.prep.meta["set_aside"] if x.get("explained_by_state")]
    assert core.disturbance_explained_by_state(d.prep, d.final_model, core.ALPHA, core.MIN_GAIN) is None


def test_a_disturbance_at_a_line_of_the_motion_is_left_to_its_round():
    # the final check skips a candidate whose round already held it against the state (evidence at_motion_line_hz)
    mod, spec, log, truth = closed_loop_case(10942)
    prep = prepare(log, robot="generic", seed=0)
    alt = core._search(prep, core.MAX_FINDINGS, core.ALPHA, core.MIN_GAIN)   # the search before any set-aside
    exts = [st.ext for st in alt[3]]
    tp = [e for e in exts if e.effect == "time_periodic_disturbance"]
    assert tp and "at_motion_line_hz" not in tp[0].evidence
    assert core.disturbance_explained_by_state(prep, Model(prep, exts), core.ALPHA, core.MIN_GAIN)[0] \
        == "time_periodic_disturbance"
    tp[0].evidence["at_motion_line_hz"] = float(tp[0].evidence["frequency_hz"])
    assert core.disturbance_explained_by_state(prep, Model(prep, exts), core.ALPHA, core.MIN_GAIN) is None


@pytest.mark.long
def test_the_blocks_a_disturbance_drives_are_left_out():
    # loop spec 5597: a position friction beside a planted 15 Hz disturbance (1000 Hz, Student-t noise).  In closed
    # loop the disturbance moves the axis, and the acceleration carries its frequency: given the state's blocks with
    # the acceleration ones the disturbance keeps only about 2 % (it lowers the held-out RMSE by half alone), without
    # them it stays significant and is named
    mod, spec, log, truth = closed_loop_case(5597)
    d = run_diagnosis(log, robot="generic")
    assert sorted(st.ext.effect for st in d.steps) == ["position_dependent_friction", "time_periodic_disturbance"]
    e = next(st.ext for st in d.steps if st.ext.effect == "time_periodic_disturbance")
    assert abs(e.evidence["frequency_hz"] - 15.0) < 0.01
    m0 = Model(d.prep, [x for x in d.final_model.exts if x is not e])
    solve = core._model_solver(m0, 1)
    C = e.cols[1]
    with_acc = comp._partial_test(d.prep, m0, 1, comp.state_nuisance(d.prep, m0, 1, solve=solve), C, core.ALPHA,
                                  core.MIN_GAIN, solve)
    without = comp._partial_test(d.prep, m0, 1, comp.state_nuisance(
        d.prep, m0, 1, solve=solve, without=core.DISTURBANCE_DRIVEN_BLOCKS), C, core.ALPHA, core.MIN_GAIN, solve)
    assert with_acc["rmse_reduction"] < 0.05 < without["rmse_reduction"]
    assert without["significant"]
    assert core.disturbance_explained_by_state(d.prep, d.final_model, core.ALPHA, core.MIN_GAIN) is None


@pytest.mark.long
def test_the_report_says_why_the_disturbance_was_set_aside(monkeypatch, tmp_path):
    from drake_est.diagnose import diagnose
    # with the inertia backfit's move made, as in test_a_slow_misfit_of_the_state_is_not_named_a_disturbance
    monkeypatch.setattr(core, "inertia_move_contradicted", lambda *a, **k: None)
    mod, spec, log, truth = closed_loop_case(10942)
    rep = diagnose(log, robot="generic", simulate=False)
    rep.write(tmp_path)
    md = (tmp_path / "report.md").read_text()
    assert "## Findings set aside" in md
    line = next(x for x in md.splitlines() if x.startswith("- time_periodic_disturbance (joint 1): explained by a function"))
    assert "the search was run again without it" in line
    import json
    d = json.loads((tmp_path / "report.json").read_text())
    assert any(r.get("explained_by_state") for r in d["set_aside"])


def test_state_nuisance_names_an_unknown_block():
    mod, spec, log, truth = closed_loop_case(67)
    prep = prepare(log, robot="generic", seed=0)
    m = Model(prep)
    assert set(comp.state_blocks(prep, 1)) <= set(comp.STATE_BLOCK_NAMES)
    assert set(core.DISTURBANCE_DRIVEN_BLOCKS) <= set(comp.STATE_BLOCK_NAMES)
    with pytest.raises(ValueError, match="no state block named intertia"):
        comp.state_nuisance(prep, m, 1, without=("intertia",))
