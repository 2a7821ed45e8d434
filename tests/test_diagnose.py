"""Model-discrepancy diagnosis: the tests hide an effect in a simulated IRB 140 log and require the
diagnosis to find it (top finding = hidden effect on its joint), to report nothing on logs without
an effect, and to bring the held-out RMSE of the extended model within 20 % of the noise level.

Logs are short (60-300 s) and generated once per test session; the big confusion matrix over
>= 60 randomized logs is ``benchmarks/bench_diagnose.py`` (and the ``benchmark``-marked test in
``test_diagnose_cli.py``)."""
from __future__ import annotations

import functools
import json

import numpy as np
import pytest

from drake_est.data import Log
from drake_est.diagnose import VOCABULARY, diagnose, friction_system
from drake_est.errors import DataError
from drake_est.synth import synthesize

SPECS = {
    "none": dict(effect="none", seed=11, duration=90.0),
    "position_dependent_friction": dict(effect="position_dependent_friction", seed=12, duration=100.0),
    "motor_position_ripple": dict(effect="motor_position_ripple", seed=13, duration=100.0),
    "asymmetric_coulomb": dict(effect="asymmetric_coulomb", seed=14, duration=80.0),
    "abrupt_change": dict(effect="abrupt_change", seed=15, duration=100.0),
    "gear_coupling": dict(effect="gear_coupling", seed=16, duration=60.0, sample_rate=50.0),
    "payload": dict(effect="payload", seed=17, duration=60.0, sample_rate=50.0),
    "energy_dependent_friction": dict(effect="energy_dependent_friction", seed=18, duration=300.0, sample_rate=20.0),
    "position+energy": dict(effect=["position_dependent_friction", "energy_dependent_friction"], seed=19,
                            duration=300.0, sample_rate=20.0),
}


@functools.lru_cache(maxsize=None)
def make(name):
    log, truth = synthesize(**SPECS[name])
    # only the columns of the foundation format that a user log has: t, q<j>, tau<j>
    return Log(t=log.t, q=log.q, tau=log.tau, joints=log.joints), truth


@functools.lru_cache(maxsize=None)
def report(name, robot="irb140"):
    log, truth = make(name)
    return diagnose(log, robot=robot, seed=0, simulate=False), truth


def _final_rmse(rep, joints):
    d = rep.to_dict()
    return max(d["final"]["per_joint"][str(j)]["rmse"] for j in joints if str(j) in d["final"]["per_joint"])


def test_vocabulary_is_fixed():
    assert VOCABULARY == ("position_dependent_friction", "motor_position_ripple", "energy_dependent_friction",
                          "asymmetric_coulomb", "gear_coupling", "payload", "abrupt_change")


def test_none_log_gives_no_finding():
    rep, truth = report("none")
    assert rep.findings == []
    d = rep.to_dict()
    assert d["final"]["effects"] == []
    # the nominal model explains the held-out data to the noise level
    assert d["nominal"]["validation"]["rmse"] < 1.2 * truth["noise_std"]
    # held joints are reported as skipped, not diagnosed
    assert set(d["data"]["skipped_joints"]) == {"2", "3", "4", "5", "6"}


@pytest.mark.parametrize("name", ["position_dependent_friction",
                                  pytest.param("motor_position_ripple", marks=pytest.mark.long),
                                  pytest.param("asymmetric_coulomb", marks=pytest.mark.long),
                                  pytest.param("abrupt_change", marks=pytest.mark.long),
                                  # ~30 s (a long log); an energy effect alone is named in the default
                                  # multi-log test (test_energy_state_restarts_per_log_in_the_diagnosis)
                                  pytest.param("energy_dependent_friction", marks=pytest.mark.slow)])
def test_single_joint_effect_is_found(name):
    rep, truth = report(name)
    f = rep.findings
    assert f, f"nothing found for hidden {name}"
    assert f[0]["effect"] == name, [x["effect"] for x in f]
    assert f[0]["joint"] in truth["joints"]
    assert f[0]["evidence"]["p_value"] < 1e-4
    assert f[0]["gain"]["rmse_ratio"] > 1.0
    assert [x["effect"] for x in f] == [name], "spurious extra findings"
    assert _final_rmse(rep, truth["joints"]) <= 1.2 * truth["noise_std"]


@pytest.mark.long     # shares the ripple log of the long single-effect case
def test_ripple_frequency_without_gear_ratio():
    """The generic robot knows no gear ratio; the LPV spectral detector still finds the ripple
    frequency (cycles per arm radian = harmonic * gear / (2 pi))."""
    rep, truth = report("motor_position_ripple", robot="generic")
    f = rep.findings[0]
    assert f["effect"] == "motor_position_ripple"
    true_f = truth["effect_parameters"]["motor_position_ripple"][1]["frequency_per_arm_rad"]
    assert abs(f["evidence"]["frequency_per_arm_rad"] - true_f) < 0.01 * true_f
    # amplitude falls with speed, as injected
    assert f["evidence"]["amplitude_slope_vs_speed"] < 0


@pytest.mark.long     # shares the abrupt-change log of the long single-effect case
def test_abrupt_change_time_and_levels():
    rep, truth = report("abrupt_change")
    p = rep.findings[0]["parameters"]
    tp = truth["effect_parameters"]["abrupt_change"][1]
    assert abs(p["t_change_s"] - tp["t_change"]) < 0.06 * rep.to_dict()["data"]["duration_s"]
    assert p["kc_after"] == pytest.approx(tp["kc_after"], rel=0.15)


@pytest.mark.long
def test_energy_time_constant():
    rep, truth = report("energy_dependent_friction")
    p = rep.findings[0]["parameters"]
    tp = truth["effect_parameters"]["energy_dependent_friction"][1]
    assert 0.5 * tp["tau_e"] < p["time_constant_s"] < 2.0 * tp["tau_e"]
    assert p["gain_k_e"] < 0   # friction falls as the joint warms up, as injected


@pytest.mark.long
def test_gear_coupling_found_on_wrist():
    rep, truth = report("gear_coupling")
    f = rep.findings
    assert f and f[0]["effect"] == "gear_coupling" and f[0]["joint"] in (5, 6)
    assert {x["effect"] for x in f} == {"gear_coupling"}
    assert {x["joint"] for x in f} == {5, 6}       # joint 4 has no coupled friction
    assert _final_rmse(rep, [4, 5, 6]) <= 1.2 * truth["noise_std"]


def test_payload_found_and_mass():
    rep, truth = report("payload")
    f = rep.findings
    assert f and f[0]["effect"] == "payload" and f[0]["joint"] in truth["joints"]
    assert [x["effect"] for x in f] == ["payload"]
    m = truth["effect_parameters"]["payload"]["mass"]
    assert f[0]["parameters"]["mass_kg"] == pytest.approx(m, rel=0.15)
    assert _final_rmse(rep, truth["joints"]) <= 1.2 * truth["noise_std"]


@pytest.mark.slow   # ~30 s; measured in benchmarks/bench_diagnose.py (class pos+energy) and the testbench benchmark
def test_combined_position_and_energy_both_found():
    rep, truth = report("position+energy")
    eff = [x["effect"] for x in rep.findings]
    assert set(eff) == {"position_dependent_friction", "energy_dependent_friction"}, eff
    assert _final_rmse(rep, truth["joints"]) <= 1.2 * truth["noise_std"]


def test_outliers_are_flagged_and_do_not_create_findings():
    log, truth = make("none")
    rng = np.random.default_rng(3)
    tau = log.tau.copy()
    k = rng.choice(log.n_samples, 40, replace=False)
    tau[k, 0] += rng.choice([-1, 1], 40) * 20 * truth["noise_std"]
    bad = Log(t=log.t, q=log.q, tau=tau, joints=log.joints)
    rep = diagnose(bad, robot="irb140", simulate=False)
    assert rep.findings == []
    assert rep.to_dict()["data"]["excluded"]["1"]["outliers"] >= 25   # most spikes fall on selected samples


def test_other_sample_rate_and_generic_robot():
    """A 10 Hz decimation of the position-dependence log, diagnosed as a generic axis."""
    log, truth = make("position_dependent_friction")
    idx = np.arange(0, log.n_samples, 10)
    low = Log(t=log.t[idx], q=log.q[idx], tau=log.tau[idx], joints=log.joints)
    rep = diagnose(low, robot="generic", joints=[1], simulate=False)
    assert rep.findings and rep.findings[0]["effect"] == "position_dependent_friction"


@pytest.mark.long
def test_report_shape_and_simulation(tmp_path):
    log, truth = make("asymmetric_coulomb")
    rep = diagnose(log, robot="irb140", seed=0)
    rep.write(tmp_path)
    d = json.loads((tmp_path / "report.json").read_text())
    assert set(["data", "nominal", "findings", "final"]) <= set(d)
    assert set(["file", "samples", "joints", "duration_s"]) <= set(d["data"])
    assert set(["rmse", "mae", "fit", "fpe"]) <= set(d["nominal"]["validation"])
    f = d["findings"][0]
    assert set(["effect", "joint", "score", "evidence", "parameters", "validation", "gain"]) <= set(f)
    assert f["evidence"]["test"] == "F-test on held-out residual" and "p_value" in f["evidence"]
    assert "rmse_ratio" in f["gain"]
    assert d["final"]["effects"] == ["asymmetric_coulomb"] and "rmse" in d["final"]["validation"]
    for png in ("residual_time.png", "residual_position.png", "residual_motor_position.png",
                "residual_velocity.png", "simulation.png"):
        assert (tmp_path / png).stat().st_size > 1000
        assert png in (tmp_path / "report.md").read_text()
    # re-simulation with the measured torque: the extended model tracks the measured velocity better
    s = d["simulation"]
    assert s["velocity_rmse_extended"]["1"] < s["velocity_rmse_nominal"]["1"]
    # the extended friction model is a Drake system with named ports
    sys_ = friction_system(rep)
    ctx = sys_.CreateDefaultContext()
    q = np.zeros(6)
    v = np.zeros(6)
    v[0] = -0.5
    sys_.get_input_port(0).FixValue(ctx, q)
    sys_.get_input_port(1).FixValue(ctx, v)
    F = sys_.get_output_port(0).Eval(ctx)
    p = f["parameters"]
    # extension terms fade out below the selection speed v_min (|tanh(v / v_min)|; ~1 at 0.5 rad/s)
    assert F[0] == pytest.approx(-p["kc_neg"] - 0.5 * p["kv"], rel=2e-3)
    assert F[0] != pytest.approx(-p["kc_pos"] - 0.5 * p["kv"], rel=2e-2)
    assert sys_.get_output_port(0).get_name() == "friction_torques"


def test_bad_input_raises_one_line_errors():
    log, _ = make("none")
    with pytest.raises(DataError, match="joint 9"):
        diagnose(log, robot="irb140", joints=[9], simulate=False)
    with pytest.raises(DataError, match="--robot"):
        diagnose(log, robot="no_such_robot.urdf", simulate=False)
    with pytest.raises(DataError, match="no joint of the log can be diagnosed"):
        diagnose(log, robot="irb140", joints=[4], simulate=False)
    notau = Log(t=log.t, q=log.q, joints=log.joints)
    with pytest.raises(DataError, match="torque"):
        diagnose(notau, simulate=False)


def _axis_generator():
    from conftest import bench_module
    return bench_module("bench_diagnose").axis_log


@pytest.mark.parametrize("effect, duration, rate", [("none", 120.0, 1000.0), ("asymmetric_coulomb", 300.0, 10.0),
                                                    ("position_dependent_friction", 120.0, 200.0)])
def test_logs_from_an_independent_generator(effect, duration, rate):
    """A numpy single-axis simulation (not drake_est.synth; differently shaped effects), generic robot."""
    log, truth = _axis_generator()(effect, seed=7, duration=duration, sample_rate=rate, noise_std=0.4)
    rep = diagnose(log, robot="generic", simulate=False)
    assert [f["effect"] for f in rep.findings] == truth["effects"]
    assert rep.to_dict()["final"]["per_joint"]["1"]["rmse"] <= 1.2 * 0.4


@pytest.mark.parametrize("name", ["motor_position_ripple", pytest.param("gear_coupling", marks=pytest.mark.long),
                                  "abrupt_change",
                                  # the long logs of test_energy_time_constant and test_gear_coupling_found_on_wrist
                                  pytest.param("energy_dependent_friction", marks=pytest.mark.long)])
def test_diagnosed_model_is_the_friction_model_and_round_trips_json(name, tmp_path):
    """issue #18: friction_system(report) is the same FrictionModel class as fit-friction's; it saves
    to params.json and loads back with identical torques; it equals the simulation's FrictionLaw
    (given the same energy) on random states, at times before and after any change."""
    from drake_est.diagnose import friction_params
    from drake_est.diagnose.simulate import FrictionLaw
    from drake_est.systems.friction import FrictionModel
    rep, truth = report(name)
    res = rep.result
    assert any(s.ext.effect == name for s in res.steps), "the effect must be found for this check to bite"
    fm = friction_system(rep)
    assert type(fm) is FrictionModel
    path = tmp_path / "params.json"
    path.write_text(json.dumps(friction_params(rep)))
    fm2 = FrictionModel.from_json(path)
    law = FrictionLaw(res, res.final_model, res.final_fit)
    prep = res.prep
    rng = np.random.default_rng(0)
    n = prep.robot.n
    t_end = float(prep.log.t[-1])
    for _ in range(20):
        q = rng.uniform(-1.5, 1.5, n)
        v = rng.uniform(-1.0, 1.0, n)
        t = float(rng.uniform(0, t_end))
        qm = np.array([q[prep.robot_cols[j]] for j in prep.log.joints])
        vm = np.array([v[prep.robot_cols[j]] for j in prep.log.joints])
        E_log = law.energy_at(t)
        E = np.zeros(n)
        for c, j in enumerate(prep.log.joints):
            E[prep.robot_cols[j]] = E_log[c]
        F = fm.friction(q, v, E, t)
        np.testing.assert_array_equal(fm2.friction(q, v, E, t), F)
        F_law = law.friction(t, qm, vm)
        np.testing.assert_allclose([F[prep.robot_cols[j]] for j in prep.log.joints], F_law, rtol=1e-12, atol=1e-12)
    # the LeafSystem output is the same function
    ctx = fm.CreateDefaultContext()
    fm.get_joint_positions_input_port().FixValue(ctx, q)
    fm.get_joint_velocities_input_port().FixValue(ctx, v)
    ctx.SetTime(t)
    E0 = np.zeros(n)
    np.testing.assert_allclose(fm.get_friction_torques_output_port().Eval(ctx), fm.friction(q, v, E0, t), rtol=1e-14)
    assert json.loads(path.read_text())["format"] == "drake_est.friction_model/2"
