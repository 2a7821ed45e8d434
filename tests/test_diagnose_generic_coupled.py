"""Several coupled joints moving together, diagnosed with ``--robot generic`` (issue 16 item 6).

The inertia and gravity one joint of a serial arm feels depend on the other joints' positions, velocities and
accelerations.  A generic axis model of joint j therefore gets the coupled rigid-body columns of
:func:`drake_est.diagnose.nominal.coupled_rigid_body_groups` in its nominal model, each group admitted by a
held-out F-test and a conditioning check (:func:`~drake_est.diagnose.nominal.select_coupled_rigid_body`).
Checked here: the columns span the exact dynamics of a planar two-link arm; the selection recovers them from
noisy data and admits nothing for independent axes; a joint moving alone is unchanged; IRB 140 synth logs of
joints 2+3 (and, slow, the wrist) with ``--robot generic`` name only what was planted."""
from __future__ import annotations

import functools
import os

import numpy as np
import pytest

os.environ.setdefault("DRAKE_EST_NO_PROGRESS", "1")

from drake_est.data import Log  # noqa: E402
from drake_est.diagnose import diagnose  # noqa: E402
from drake_est.diagnose.nominal import (_load_nuisance, _own_load_basis, block_split,  # noqa: E402
                                        coupled_rigid_body_groups, prepare, select_coupled_rigid_body)


# ----------------------------------------------------------------------------- a planar two-link arm (numpy)

M1, M2, L1, LC1, LC2, I1, I2, G = 12.0, 6.0, 0.7, 0.3, 0.35, 0.4, 0.2, 9.81


def two_link_torque(q, v, a):
    """Inverse dynamics of a planar 2R arm in a vertical plane (joints "2" and "3", parallel horizontal axes,
    q3 relative to link 2): {2: tau2, 3: tau3} (textbook form, written independently of the columns tested)."""
    c3, s3 = np.cos(q[3]), np.sin(q[3])
    m11 = I1 + I2 + M1 * LC1 ** 2 + M2 * (L1 ** 2 + LC2 ** 2 + 2 * L1 * LC2 * c3)
    m12 = I2 + M2 * (LC2 ** 2 + L1 * LC2 * c3)
    m22 = I2 + M2 * LC2 ** 2
    h = -M2 * L1 * LC2 * s3
    g2 = (M1 * LC1 + M2 * L1) * G * np.cos(q[2]) + M2 * LC2 * G * np.cos(q[2] + q[3])
    g3 = M2 * LC2 * G * np.cos(q[2] + q[3])
    tau2 = m11 * a[2] + m12 * a[3] + h * (2 * v[2] * v[3] + v[3] ** 2) + g2
    tau3 = m12 * a[2] + m22 * a[3] - h * v[2] ** 2 + g3
    return {2: tau2, 3: tau3}


def sines(t, rng, amp, n=4, base=0.08):
    """Sum of sinusoids with exact derivatives: (q, v, a)."""
    q, v, a = np.zeros_like(t), np.zeros_like(t), np.zeros_like(t)
    for k in range(1, n + 1):
        w = 2 * np.pi * base * k * rng.uniform(0.8, 1.2)
        c = amp / n * rng.uniform(0.6, 1.0)
        ph = rng.uniform(0, 2 * np.pi)
        q += c * np.sin(w * t + ph)
        v += c * w * np.cos(w * t + ph)
        a -= c * w * w * np.sin(w * t + ph)
    return q, v, a


def arm_data(seed=0, duration=200.0, rate=50.0, noise=0.3, coupled=True):
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / rate)
    q, v, a = {}, {}, {}
    for j, amp, off in ((2, 1.2, 0.3), (3, 1.5, -0.4)):
        q[j], v[j], a[j] = sines(t, rng, amp)
        q[j] += off
    if coupled:
        tau = two_link_torque(q, v, a)
    else:   # two independent axes, each with its own inertia and gravity-like load
        tau = {2: 3.0 * a[2] + 20.0 * np.cos(q[2]), 3: 0.8 * a[3] + 5.0 * np.sin(q[3])}
    fric = {j: 4.0 * np.sign(v[j]) + 2.0 * v[j] for j in (2, 3)}
    meas = {j: tau[j] + fric[j] + noise * rng.standard_normal(t.size) for j in (2, 3)}
    return t, q, v, a, tau, meas


def _rows(t, v, j):
    """(moving training rows, steady training rows) as prepare uses them (exact accelerations: all moving)."""
    moving = np.flatnonzero(np.abs(v[j]) > 0.05 * np.quantile(np.abs(v[j]), 0.95))
    tr, _ = block_split(t, moving)
    return moving[tr], moving[tr]


def test_no_columns_for_a_joint_moving_alone():
    t, q, v, a, _, _ = arm_data(duration=20.0)
    assert coupled_rigid_body_groups(2, q, v, a, []) == {}


@pytest.mark.parametrize("j", [2, 3])
def test_columns_span_the_two_link_dynamics(j):
    """Own inertia, own load [1, sin q_j, cos q_j] and the coupled groups reproduce the exact torque."""
    t, q, v, a, tau, _ = arm_data(duration=60.0)
    other = 5 - j
    groups = coupled_rigid_body_groups(j, q, v, a, [other])
    X = np.hstack([a[j][:, None], _own_load_basis(q[j])] + [C for _, C in groups.values()])
    coef, *_ = np.linalg.lstsq(X, tau[j], rcond=None)
    assert np.sqrt(np.mean((tau[j] - X @ coef) ** 2)) < 1e-8 * np.sqrt(np.mean(tau[j] ** 2))
    # without the coupled columns the same fit misses by far more than a typical torque noise
    X0 = X[:, :4]
    c0, *_ = np.linalg.lstsq(X0, tau[j], rcond=None)
    assert np.sqrt(np.mean((tau[j] - X0 @ c0) ** 2)) > 1.0


@pytest.mark.parametrize("j", [2, 3])
def test_selection_recovers_the_coupled_torque(j):
    """From noisy torques (noise 0.3 N m) the selected coupled terms plus J qdd_j reproduce the true torque
    up to a function of q_j alone (the load left for position_dependent_load) well below the noise."""
    t, q, v, a, tau, meas = arm_data(seed=1)
    idx_m, idx_s = _rows(t, v, j)
    tau_c, info = select_coupled_rigid_body(j, q, v, a, meas[j], idx_m, idx_s, t, [5 - j])
    assert any(g.startswith("gravity") for g in info["groups"]), info["groups"]
    rb = info["inertia"] * a[j] + tau_c
    e = rb - tau[j]
    L = _own_load_basis(q[j])
    c, *_ = np.linalg.lstsq(L, e, rcond=None)
    assert np.sqrt(np.mean((e - L @ c) ** 2)) < 0.15


def test_selection_admits_nothing_for_independent_axes():
    """Two axes that do not interact: no coupled group passes the held-out test, J is each axis' own."""
    t, q, v, a, _, meas = arm_data(seed=2, coupled=False)
    for j, J in ((2, 3.0), (3, 0.8)):
        idx_m, idx_s = _rows(t, v, j)
        tau_c, info = select_coupled_rigid_body(j, q, v, a, meas[j], idx_m, idx_s, t, [5 - j])
        assert info["groups"] == [] and not tau_c.any(), info["groups"]
        assert abs(info["inertia"] - J) < 0.05 * J


def test_single_joint_prepare_is_unchanged():
    """One logged joint: no coupled columns, J from the regression [qdd, qd, sign(qd), 1, sin q, cos q]."""
    t, q, v, a, _, meas = arm_data(seed=3, coupled=False, duration=120.0)
    log = Log(t=t, q=q[2][:, None], tau=meas[2][:, None], joints=[2])
    prep = prepare(log, robot="generic")
    assert "coupled_rigid_body" not in prep.meta
    jd = prep.joints[2]
    moving = np.flatnonzero(np.abs(jd.v) > jd.counts["thresholds"]["v_min"])
    idx = moving[block_split(t, moving)[0]]
    X = np.column_stack([jd.a[idx], jd.v[idx], np.sign(jd.v[idx])] + _load_nuisance(jd.q[idx]))
    coef, *_ = np.linalg.lstsq(X, jd.tau[idx], rcond=None)
    e = jd.tau[idx] - X @ coef
    ok = np.abs(e - np.median(e)) <= 6.0 * 1.4826 * np.median(np.abs(e - np.median(e)))
    coef, *_ = np.linalg.lstsq(X[ok], jd.tau[idx][ok], rcond=None)
    assert jd.counts["inertia"] == pytest.approx(coef[0], rel=1e-12)


def test_two_link_log_with_generic_robot_names_only_the_loads():
    """The two-link arm as a log (derivatives from positions, like any log): nothing but the gravity loads."""
    t, q, v, a, tau, meas = arm_data(seed=4, duration=100.0)
    log = Log(t=t, q=np.column_stack([q[2], q[3]]), tau=np.column_stack([meas[2], meas[3]]), joints=[2, 3])
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    names = {f["effect"] for f in d["findings"]}
    assert names <= {"position_dependent_load"}, d["findings"]
    for j in ("2", "3"):
        assert d["final"]["per_joint"][j]["rmse"] < 1.1 * 0.3


# ----------------------------------------------------------------------------- IRB 140 synth logs


@functools.lru_cache(maxsize=None)
def _synth(effect, joints, seed, duration=80.0, experiment=None, noise_std=0.3):
    from drake_est.synth import synthesize
    log, truth = synthesize(effect, seed=seed, joints=list(joints), duration=duration, sample_rate=50.0,
                            noise_std=noise_std, experiment=experiment)
    return Log(t=log.t, q=log.q, tau=log.tau, joints=log.joints), truth


def _findings(log):
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    return [(f["effect"], f["joint"]) for f in d["findings"]], d


@pytest.mark.long
def test_irb140_joints_2_3_without_effect_name_nothing_but_the_load():
    log, truth = _synth("none", (2, 3), 11)
    f, d = _findings(log)
    assert {e for e, _ in f} <= {"position_dependent_load"}, f
    for j in ("2", "3"):
        assert d["final"]["per_joint"][j]["rmse"] < 1.15 * truth["noise_std"]


@pytest.mark.long
def test_irb140_joints_2_3_ripple_is_named():
    log, truth = _synth("motor_position_ripple", (2, 3), 12)
    f, _ = _findings(log)
    assert ("motor_position_ripple", 3) in f, f
    assert {e for e, _ in f} <= {"motor_position_ripple", "position_dependent_load"}, f


@pytest.mark.slow
def test_irb140_joints_2_3_position_friction_is_named():
    log, _ = _synth("position_dependent_friction", (2, 3), 5, duration=120.0)
    f, _ = _findings(log)
    assert ("position_dependent_friction", 2) in f and ("position_dependent_friction", 3) in f, f
    assert {e for e, _ in f} <= {"position_dependent_friction", "position_dependent_load"}, f


@pytest.mark.slow
def test_irb140_wrist_gear_coupling_is_named_alone():
    log, _ = _synth("gear_coupling", (4, 5, 6), 7, duration=120.0, noise_std=0.2)
    f, _ = _findings(log)
    assert ("gear_coupling", 5) in f and ("gear_coupling", 6) in f, f
    assert {e for e, _ in f} == {"gear_coupling"}, f


@pytest.mark.slow
def test_irb140_joints_2_3_abrupt_change_is_named_and_fitted():
    """Friction that jumps mid-log must not be absorbed by the coupled columns (time-segment nuisance)."""
    log, truth = _synth("abrupt_change", (2, 3), 16, duration=120.0)
    f, d = _findings(log)
    assert ("abrupt_change", 2) in f and ("abrupt_change", 3) in f, f
    assert {e for e, _ in f} <= {"abrupt_change", "position_dependent_load"}, f
    for j in ("2", "3"):
        assert d["final"]["per_joint"][j]["rmse"] < 1.25 * truth["noise_std"]
