import numpy as np
import pytest

from drake_est.cli import main
from drake_est.data import load_log
from drake_est.errors import DrakeEstError
from drake_est.synth import EFFECTS, synthesize

DUR = 12.0


@pytest.fixture(scope="module")
def none_log():
    return synthesize("none", seed=7, duration=DUR)


def test_reproducible_by_seed(none_log):
    log, truth = none_log
    log2, truth2 = synthesize("none", seed=7, duration=DUR)
    np.testing.assert_array_equal(log.q, log2.q)
    np.testing.assert_array_equal(log.tau, log2.tau)
    log3, _ = synthesize("none", seed=8, duration=DUR)
    assert not np.allclose(log.tau[:100], log3.tau[:100])


def test_no_effect_when_not_requested(none_log):
    log, truth = none_log
    assert truth["effects"] == [] and truth["effect_parameters"] == {}
    tm = truth["truth_model"]
    assert tm.bumps is None and tm.ripple is None and tm.energy is None and tm.coupling is None
    assert tm.change is None and tm.kc_neg is None
    # friction torque of the moving joint equals the nominal Coulomb + viscous law
    v = truth["dq_true"][:, 0]
    f = truth["friction"][1]
    np.testing.assert_allclose(truth["friction_torque"][:, 0], f["kv"] * v + f["kc"] * np.tanh(v / tm.v_eps), atol=1e-9)


def test_log_is_physical(none_log):
    log, truth = none_log
    assert log.joints == [1, 2, 3, 4, 5, 6] and log.dq is None
    assert np.all(np.diff(log.t) > 0)
    assert np.ptp(log.q[:, 0]) > 1.0  # joint 1 sweeps
    assert np.ptp(log.q[:, 2]) < 1e-2  # joint 3 holds still
    # quantized encoders: positions on the encoder grid
    step = 2 * np.pi / (4096 * 117.0)
    np.testing.assert_allclose(log.q[:, 0] / step, np.round(log.q[:, 0] / step), atol=1e-6)


@pytest.mark.parametrize("effect", EFFECTS)
def test_each_effect_present_in_truth(effect):
    log, truth = synthesize(effect, seed=3, duration=DUR if effect != "energy_dependent_friction" else 40.0,
                            sample_rate=50.0)
    assert truth["effects"] == [effect]
    assert effect in truth["effect_parameters"]
    tm = truth["truth_model"]
    j = truth["joints"][0] - 1
    field = {"position_dependent_friction": tm.bumps, "motor_position_ripple": tm.ripple, "energy_dependent_friction": tm.energy,
             "asymmetric_coulomb": tm.kc_neg, "gear_coupling": tm.coupling, "abrupt_change": tm.change}.get(effect)
    if effect == "payload":
        assert truth["effect_parameters"]["payload"]["mass"] > 1.0
    else:
        assert field is not None
    # the effect changes the torque compared with the same seed without it... except payload acts via dynamics
    if effect not in ("payload", "gear_coupling"):
        v = truth["dq_true"][:, j]
        f = truth["friction"][j + 1]
        nominal = f["kv"] * v + f["kc"] * np.tanh(v / tm.v_eps)
        assert np.std(truth["friction_torque"][:, j] - nominal) > 0.05


def test_combined_effects_and_errors():
    log, truth = synthesize(["position_dependent_friction", "asymmetric_coulomb"], seed=1, duration=DUR)
    assert set(truth["effect_parameters"]) == {"position_dependent_friction", "asymmetric_coulomb"}
    with pytest.raises(DrakeEstError, match="unknown effect 'friction'"):
        synthesize("friction")
    with pytest.raises(DrakeEstError, match="joint 9 does not exist"):
        synthesize("none", joints=[9])


def test_cli_synth_writes_loadable_log(tmp_path, capsys):
    out = tmp_path / "log.csv"
    assert main(["synth", "--effect", "asymmetric_coulomb", "--seed", "2", "--duration", "8", "--out", str(out)]) == 0
    log = load_log(out)
    assert log.n_samples > 500 and (tmp_path / "log.csv.truth.json").exists()
    assert main(["synth", "--effect", "nonsense", "--out", str(out)]) == 2
    assert "unknown effect 'nonsense'" in capsys.readouterr().err


def test_one_effect_list():
    """synth, the diagnosis and drake_est.effects share one list of effect names (issue #18)."""
    import drake_est.effects as eff
    from drake_est.diagnose import VOCABULARY
    from drake_est.synth import EFFECTS as synth_effects
    assert synth_effects is eff.EFFECTS and VOCABULARY is eff.EFFECTS
    assert eff.check_effect("payload") == "payload"
    from drake_est.errors import DataError
    with pytest.raises(DataError, match="unknown effect 'bogus'"):
        eff.check_effect("bogus")
