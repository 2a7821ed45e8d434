"""Closed-loop data and the nominal model of a generic axis (issue 16, second round):

* the inertia J identified before any finding is biased on closed-loop data when an unmodeled torque moves the
  axis; :func:`backfit_inertia` re-estimates it with the findings as regressors and the search is repeated;
* a viscous coefficient is kept >= 0 (:func:`solve_kv_nonneg`), so a friction that falls with speed over the whole
  selected range is left to the Stribeck candidate (whose vs grid then reaches the top speed);
* after an energy-dependent friction is accepted, an abrupt change must beat a smooth drift that includes the
  energy law's second order (a law of another shape in the temperature otherwise looks like a step)."""
import numpy as np
import pytest

from drake_est.diagnose.core import run_diagnosis, solve_kv_nonneg
from drake_est.diagnose.testbench_loop import generate


def _lstsq(A, y, keep=None):
    return np.linalg.lstsq(A, y, rcond=None)[0]


def test_solve_kv_nonneg_holds_a_negative_viscous_at_zero():
    rng = np.random.default_rng(0)
    v = rng.uniform(0.05, 1.0, 500) * rng.choice([-1.0, 1.0], 500)
    X = np.column_stack([v, np.sign(v), np.sign(v) * np.exp(-np.abs(v) / 0.3)])
    y = X @ np.array([-2.0, 3.0, 1.0]) + 0.01 * rng.standard_normal(500)
    c, held = solve_kv_nonneg(_lstsq, X, y)
    assert held == {0} and c[0] == 0.0
    # the others are the least-squares solution without the viscous column (the constrained optimum)
    np.testing.assert_allclose(c[1:], np.linalg.lstsq(X[:, 1:], y, rcond=None)[0], rtol=1e-12)
    # a positive viscous coefficient is left as it is
    y2 = X @ np.array([2.0, 3.0, 1.0])
    c2, held2 = solve_kv_nonneg(_lstsq, X, y2)
    assert not held2
    np.testing.assert_allclose(c2, [2.0, 3.0, 1.0], atol=1e-9)


def test_inertia_backfit_removes_closed_loop_bias():
    """A 2 Hz torque disturbance under a PID loop: the torque command answers it, so the open-loop inertia fit
    of ``prepare`` is biased (several times the true J) and its error, times a multisine acceleration that
    correlates with position, was named a position-dependent load.  With the backfit J is within 10 % and only
    the disturbance is named."""
    log, truth = generate({"time_periodic_disturbance": 1.0, "_f_hz": 2.0}, seed=3089, duration=120.0,
                          sample_rate=100.0, noise="gaussian", noise_std=0.057)
    from drake_est.diagnose import diagnose

    rep = diagnose(log, robot="generic", seed=0, simulate=False)
    res = rep.result
    c = res.prep.joints[1].counts
    assert c["inertia_before_backfit"] > 2.0 * truth["J"]          # the bias is there before the backfit
    assert c["inertia"] == pytest.approx(truth["J"], rel=0.10)
    assert [e.effect for e in res.final_model.exts] == ["time_periodic_disturbance"]
    # the report gives both inertias with the nominal parameters, not among the excluded-sample counts
    d = rep.to_dict()
    p = d["nominal"]["parameters"]["1"]
    assert p["J"] == pytest.approx(c["inertia"], rel=1e-4)
    assert p["J_before_backfit"] == pytest.approx(c["inertia_before_backfit"], rel=1e-4)
    assert "inertia_before_backfit" not in d["data"]["excluded"]["1"]
    # report.md says it in words, not as a raw parameter
    from drake_est.diagnose.report import markdown
    md = markdown(d)
    assert "J_before_backfit" not in md
    assert f"J was identified as {p['J_before_backfit']:.4g} before the findings" in md


def test_report_sentence_of_a_withheld_inertia_move():
    from drake_est.diagnose.report import _inertia_backfit_lines
    p = {"kv": 1.0, "J": 0.467, "J_backfit_withheld": {"J_moved": 3.97, "J_speed_curve": -0.29,
                                                         "standard_error": 0.63, "speed_curve_columns": 12}}
    (line,) = _inertia_backfit_lines(p)
    assert line.startswith("J kept at 0.467: re-estimating it beside the findings gave 3.97")
    assert "-0.29 +- 0.63" in line
    assert _inertia_backfit_lines({"kv": 1.0, "J": 0.5}) == []


def test_stribeck_seen_only_on_its_falling_flank():
    """98 % of the moving samples below 2 vs: the data show friction falling with speed over the whole range.
    Unconstrained, that was a negative viscous coefficient and the rest went to an abrupt change; with kv >= 0
    it is a Stribeck hump with the planted vs and shape."""
    log, truth = generate({"stribeck": 1.0}, seed=3088, duration=120.0, sample_rate=100.0, noise="quantized",
                          noise_std=0.12)
    assert truth["stribeck"]["share_moving_below_2vs"] > 0.95
    res = run_diagnosis(log, robot="generic")
    assert [e.effect for e in res.final_model.exts] == ["stribeck"]
    e = res.final_model.exts[0]
    assert e.spec["vs"] == pytest.approx(truth["stribeck"]["vs"], rel=0.3)
    nominal = res.final_model.coef_slices(res.final_fit, 1)["nominal"]
    assert nominal["kv"] >= 0.0


def test_energy_law_of_another_shape_is_not_an_abrupt_change():
    """The energy state E follows a duty cycle (full work, then a third of it, in blocks of 40-150 s); the true
    law is second order in E.  The linear law (9.23) leaves a misfit that follows E, not a smooth function of
    time: a step wins against the time-quadratic drift alone, and declines once the energy law's second order
    is the smooth alternative."""
    from scipy.signal import lfilter

    from drake_est.diagnose.detectors import change_point
    from drake_est.diagnose.nominal import JointData

    rng = np.random.default_rng(1)
    n, h = 6000, 0.1
    t = np.arange(n) * h
    s = np.sin(2 * np.pi * t / 7.0)
    v = 0.5 * s + 0.6 * np.sign(s)
    level, k, on = np.ones(n), 0, True
    while k < n:
        m = int(rng.uniform(400, 1500))
        level[k:k + m] = 1.0 if on else 0.3
        on, k = not on, k + m
    a = h / 60.0
    E = lfilter([a], [1.0, -(1.0 - a)], level * np.abs(v))        # unit-gain first-order state, tau_e = 60 s
    C = np.column_stack([np.sign(v) * E, v * E])
    y = 0.4 * v * E ** 2 + 0.3 * np.sign(v) * E ** 2 + 0.02 * rng.standard_normal(n)
    X = np.column_stack([v, np.sign(v), C])                         # the model with the linear energy law
    r = y - X @ np.linalg.lstsq(X, y, rcond=None)[0]
    rows = np.arange(n)
    jd = JointData(joint=1, col=0, t=t, q=np.cumsum(v) * h, v=v, a=np.gradient(v, t), tau=y, rb=np.zeros(n),
                   rows=rows, train=(rows // 300) % 2 == 0, val=(rows // 300) % 2 == 1)
    assert change_point(jd, r, smooth_alternative=True) is not None
    assert change_point(jd, r, smooth_alternative=True, energy_cols=C) is None
