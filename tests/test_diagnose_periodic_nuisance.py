"""The periodic nuisance of the competition (a speed or time law must beat the periodic structure of the
residual) is held to the held-out data itself: the scan sees the training blocks only, and their alternation
with the held-out blocks makes a sinusoid at the alternation frequency fit the one and miss the other (loop spec
2607: asymmetric Coulomb + Stribeck at 1000 Hz ended as "unexplained" only, Stribeck set aside by a 0.5 Hz pair
that raised the held-out error by a half or more), and for a law in time (an abrupt change, an energy drift) its
sinusoids have at least ``NUISANCE_MIN_PERIODS`` periods in the log: a slower one fits a step or a drift about as well
as the step or drift does, and would set aside the very law the test is for (thirty-first round, loop specs 8484 and
2940).  Every other law keeps the 4-period nuisance (``test_diagnose_multilog.py``: Stribeck against a 6-period
disturbance)."""
from __future__ import annotations

import numpy as np
import pytest

from drake_est.diagnose import competition as comp
from drake_est.diagnose import detectors as det
from drake_est.diagnose import diagnose

from conftest import bench_module, nominal_candidates


def _log(k):
    loop_log = bench_module("bench_diagnose_testbench").loop_log
    return loop_log(k)


def _val_rss(jd, A):
    c, *_ = np.linalg.lstsq(A[jd.train], jd.y[jd.train], rcond=None)
    e = (jd.y - A @ c)[jd.val]
    return float(e @ e)


@pytest.mark.long
def test_periodic_nuisance_lowers_the_held_out_error_and_stribeck_is_named():
    import drake_est.diagnose.detectors as det
    from drake_est.diagnose.competition import periodic_nuisance
    from drake_est.diagnose.core import Model
    from drake_est.diagnose.nominal import prepare

    log, truth = _log(2607)
    assert truth["effects"] == ["asymmetric_coulomb", "stribeck"]
    prep = prepare(log, robot="generic")
    model = Model(prep)
    fit = model.fit()
    jd = prep.joints[1]
    X = model.design(1)
    N = periodic_nuisance(prep, model, fit, 1)
    base = _val_rss(jd, X)
    if N is not None:
        assert _val_rss(jd, np.hstack([X, N])) < base
    # what the unvalidated scan finds first on this log: a sinusoid near the blocks' alternation frequency,
    # which fits the training blocks and raises the held-out error by nearly half
    r = jd.y - fit.pred[1]
    fits = []
    for _ in range(3):
        e = det.time_periodic(jd, r, skip_motion_lines=False)
        if e is None:
            break
        A = np.hstack([X, e.cols[1]])
        fits.append((_val_rss(jd, A), e.spec["frequencies_hz"]))
        c, *_ = np.linalg.lstsq(A[jd.train], jd.y[jd.train], rcond=None)
        r = jd.y - A @ c
    assert any(abs(f[1][0] - 0.5) < 0.02 and f[0] > 1.3 * base for f in fits), (base, fits)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    named = set()
    for f in d["findings"]:
        named |= set(f.get("ambiguous_between", [f["effect"]]))
    assert {"stribeck", "asymmetric_coulomb"} <= named, d["findings"]
    assert named <= {"stribeck", "asymmetric_coulomb", "position_dependent_load"}, named


@pytest.mark.long
def test_a_candidate_ranked_below_one_the_periodic_residual_explains_must_beat_it_too(monkeypatch):
    """Loop spec 2940 (an abrupt change of friction, 250 Hz, Student-t noise), with the nuisance's sinusoids scanned
    from 4 periods up for every law, as before the thirty-first round: the abrupt change scores best but is explained
    by the periodic residual, and a position load (with a position friction as its rival), neither of them planted,
    had then been named without that test.  Every candidate ranked below one the periodic residual explains must beat
    it too (``survives_periodic(any_law=True)``): the log ends with no name and its structure in time reported as
    unexplained."""
    import drake_est.diagnose.competition as comp
    monkeypatch.setattr(comp, "NUISANCE_MIN_PERIODS", 4.0)
    log, truth = _log(2940)
    assert truth["effects"] == ["abrupt_change"]
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert d["findings"] == []
    assert "time" in [u["variable"] for u in d["unexplained"]]
    away = {x["effect"] for x in d["not_found"] if x.get("explained_by_periodic_residual")}
    assert {"abrupt_change", "position_dependent_load", "position_dependent_friction"} <= away, d["not_found"]
    # the previous rule (only the smooth speed/time laws must beat it) names the load
    plain = comp.survives_periodic
    monkeypatch.setattr(comp, "survives_periodic", lambda *a, any_law=False, **kw: plain(*a, **kw))
    d0 = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert "position_dependent_load" in [f["effect"] for f in d0["findings"]]


def test_loop_case_2940_change_is_named_once_the_nuisance_holds_ten_periods():
    """The same log with the nuisance's floor of :data:`~drake_est.diagnose.competition.NUISANCE_MIN_PERIODS`
    periods for the laws in time (thirty-first round): the sinusoids slower than that, which fitted the step, are out
    of the abrupt change's nuisance, and the
    planted change is named (ambiguous with an energy drift, which the held-out blocks do not separate from it);
    no position law is named."""
    log, _ = _log(2940)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    named = set()
    for f in d["findings"]:
        named |= set(f.get("ambiguous_between", [f["effect"]]))
    assert "abrupt_change" in named, d["findings"]
    assert not named & {"position_dependent_load", "position_dependent_friction"}, named


def test_a_sinusoid_of_five_periods_is_found_unless_the_floor_holds_it_back():
    prep, _, _ = nominal_candidates({}, seed=3)
    jd = prep.joints[1]
    t = jd.t[jd.rows]
    T = float(np.ptp(t[jd.train]))
    r = np.sin(2 * np.pi * 5.0 / T * t + 0.3) + 0.01 * np.random.default_rng(0).standard_normal(t.size)
    slow = det.time_periodic(jd, r, skip_motion_lines=False)
    assert slow is not None and abs(slow.spec["frequencies_hz"][0] * T - 5.0) < 0.5
    held = det.time_periodic(jd, r, skip_motion_lines=False, min_periods=comp.NUISANCE_MIN_PERIODS)
    assert held is None or held.spec["frequencies_hz"][0] * T >= 0.99 * comp.NUISANCE_MIN_PERIODS


def test_loop_case_8484_change_is_named_not_a_position_friction():
    """Closed-loop spec 8484 (50 Hz, Student-t noise, a third-size abrupt change): the nuisance held a sinusoid of
    4.2 periods in the 120 s log, which fits the step about as well as the step does, so the change was set aside and
    a position friction (not planted) won the round, with an energy drift beside it.  With the floor the change is
    named and nothing else."""
    from drake_est.diagnose import diagnose
    log, truth = bench_module("bench_diagnose_testbench").loop_log(8484)
    assert set(truth["effects"]) == {"abrupt_change"}
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    named = {f["effect"] for f in d["findings"]}
    assert "abrupt_change" in named
    assert not named & {"position_dependent_friction", "position_dependent_load"}
