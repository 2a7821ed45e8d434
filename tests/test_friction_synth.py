"""Acceptance on synthetic IRB 140 logs (drake_est.synth) with known hidden effects:
the matching extended model must beat the nominal model on held-out data, reach the
noise level on it, and recover the true parameters."""
import numpy as np
import pytest

synth = pytest.importorskip("drake_est.synth")
from drake_est.cli.fit_friction import fit_log  # noqa: E402


def _fit_pair(effect, model, nominal, duration, joint=None, seed=0):
    log, truth = synth.synthesize(effect, seed=seed, duration=duration)
    j = joint or truth["joints"][-1]
    nom, _ = fit_log(log, model="nominal", joint=j, nominal=nominal)
    ext, info = fit_log(log, model=model, joint=j, nominal=nominal)
    return log, truth, j, nom, ext, info


def _rel(a, b):
    return abs(a - b) / abs(b)


@pytest.mark.long
def test_position_dependent_friction_joint1():
    log, truth, j, nom, ext, info = _fit_pair("position_dependent_friction", "position", "viscous", 150.0)
    sigma = truth["noise_std"]
    assert ext.validation["rmse"] < nom.validation["rmse"]           # held-out, not training
    assert ext.validation["rmse"] < 1.15 * sigma
    p = ext.model.params()
    assert _rel(p["kv"], truth["friction"][j]["kv"]) < 0.10
    # kc and the expansion share the Coulomb level (Sec. 9.3): compare the level curve kc + bumps(q)
    b = truth["effect_parameters"]["position_dependent_friction"][j]
    qs = np.linspace(np.quantile(log.q[:, j - 1], 0.1), np.quantile(log.q[:, j - 1], 0.9), 50)
    level_true = truth["friction"][j]["kc"] + np.sum(
        b["amplitudes"] * np.exp(-0.5 * ((qs[:, None] - b["centers"]) / b["widths"]) ** 2), axis=1)
    Q = np.zeros((qs.size, 6))
    Q[:, j - 1] = qs
    DQ = np.zeros((qs.size, 6))
    DQ[:, j - 1] = 1e-9   # just above zero: the Coulomb level without the viscous part
    level_est = ext.model.predict(Q, DQ)
    assert np.max(np.abs(level_est - level_true) / np.abs(level_true)) < 0.10


@pytest.mark.long
def test_asymmetric_coulomb_joint1():
    log, truth, j, nom, ext, info = _fit_pair("asymmetric_coulomb", "nominal", "asymmetric", 100.0)
    _, _, _, sym, _, _ = _fit_pair("asymmetric_coulomb", "nominal", "viscous", 100.0)
    sigma = truth["noise_std"]
    assert ext.validation["rmse"] < sym.validation["rmse"]
    assert ext.validation["rmse"] < 1.15 * sigma
    p = ext.model.params()
    e = truth["effect_parameters"]["asymmetric_coulomb"][j]
    assert _rel(p["kc+"], e["kc_pos"]) < 0.10
    assert _rel(p["kc-"], e["kc_neg"]) < 0.10
    assert _rel(p["kv"], truth["friction"][j]["kv"]) < 0.10


@pytest.mark.slow
def test_energy_dependent_friction_joint1():
    log, truth, j, nom, ext, info = _fit_pair("energy_dependent_friction", "energy", "viscous", 900.0)
    sigma = truth["noise_std"]
    assert ext.validation["rmse"] < nom.validation["rmse"]
    assert ext.validation["rmse"] < 1.15 * sigma
    p = ext.model.params()
    e = truth["effect_parameters"]["energy_dependent_friction"][j]
    assert _rel(p["ke"], e["k_e"]) < 0.10
    assert _rel(p["tau_e"], e["tau_e"]) < 0.10
    assert _rel(p["kc"], truth["friction"][j]["kc"]) < 0.10
    assert _rel(p["kv"], truth["friction"][j]["kv"]) < 0.10


@pytest.mark.slow
def test_gear_coupled_joint6():
    log, truth, j, nom, ext, info = _fit_pair("gear_coupling", "coupled", "viscous", 300.0, joint=6)
    assert ext.validation["rmse"] < 0.6 * nom.validation["rmse"]
    assert ext.validation["rmse"] < 1.15 * truth["noise_std"]
    p = ext.model.params()
    e = truth["effect_parameters"]["gear_coupling"][6]
    assert _rel(p["kv_q4"], e["joint4"]["kv"]) < 0.10
    assert _rel(p["kc"], truth["friction"][6]["kc"]) < 0.10
    assert _rel(p["kv"], truth["friction"][6]["kv"]) < 0.10
    assert _rel(p["kc_q4"], e["joint4"]["kc"]) < 0.10
    assert _rel(p["kc_q5"], e["joint5"]["kc"]) < 0.15


@pytest.mark.slow
def test_motor_position_ripple_joint1():
    log, truth, j, nom, ext, info = _fit_pair("motor_position_ripple", "motor", "asymmetric", 300.0)
    sigma = truth["noise_std"]
    assert ext.validation["rmse"] < nom.validation["rmse"]
    assert ext.validation["rmse"] < 1.15 * sigma


@pytest.mark.long
def test_multi_joint_friction_with_gravity_estimated_jointly():
    """Joints 2 and 3 excited together with an unmodeled payload: friction and the gravity
    parameters (mass moments of all links, Sec. 9.2) are estimated at once; the held-out
    residual reaches the noise level, while friction fitted against the nominal rigid-body
    model (which lacks the payload) cannot."""
    from drake_est.identification.friction import JointFriction, fit_multi_joint, gravity_regressor, nominal_terms
    from drake_est.robots import irb140

    log, truth = synth.synthesize("payload", seed=0, duration=120.0)
    log = log.with_derivatives()
    rob = irb140()
    sub = np.arange(0, log.n_samples, 5)
    Q, DQ, DDQ, TAU = log.q[sub], log.dq[sub], log.ddq[sub], log.tau[sub]
    Y, names = gravity_regressor(rob.plant, Q)
    G = np.array([rob.gravity_torques(q) for q in Q])
    theta = np.linalg.lstsq(Y.reshape(-1, Y.shape[2]), G.reshape(-1), rcond=None)[0]
    assert np.max(np.abs(Y.reshape(-1, Y.shape[2]) @ theta - G.reshape(-1))) < 1e-8   # regressor spans G(q)
    ID = rob.inverse_dynamics_batch(Q, DQ, DDQ)
    mask = np.abs(DQ) > 0.05
    js = [j - 1 for j in truth["joints"]]
    fit = fit_multi_joint(Q, DQ, TAU - (ID - G), Y, joints=js, mask=mask, gravity_names=names)
    sigma = truth["noise_std"]
    assert fit.validation["rmse"] < 1.15 * sigma
    for m, j in zip(fit.models, js):
        assert _rel(m.params()["kc"], truth["friction"][j + 1]["kc"]) < 0.10
        assert _rel(m.params()["kv"], truth["friction"][j + 1]["kv"]) < 0.15
    # friction alone against the (payload-free) nominal rigid-body model is far off
    j = js[0]
    m = JointFriction(nominal_terms("viscous"), index=j, lam=0.0).fit(Q, DQ, TAU[:, j] - ID[:, j], mask=mask[:, j])
    r = (m.predict(Q, DQ) - (TAU[:, j] - ID[:, j]))[mask[:, j]]
    assert np.sqrt(np.mean(r ** 2)) > 3 * sigma
