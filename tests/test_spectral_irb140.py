"""LPV spectral detection of hidden motor-position ripple in synthetic IRB 140 logs (drake_est.synth)."""
import numpy as np
import pytest

from drake_est.spectral import find_periodic_components


@pytest.mark.parametrize("seed", [0, 2])          # seed 0: 2nd motor harmonic, seed 2: 3rd
def test_ripple_frequency_and_trend_without_gear_ratio(seed):
    from drake_est.synth import synthesize

    log, truth = synthesize(effect="motor_position_ripple", seed=seed, duration=60.0)
    log = log.with_derivatives()
    j = truth["joints"][0]
    c = log.col(j)
    q, v, tau = log.q[:, c], log.dq[:, c], log.tau[:, c]
    base = np.column_stack([np.sign(v), v, log.ddq[:, c]])     # Coulomb, viscous, inertia
    pc = find_periodic_components(q, tau, schedule=v, base=base, n_components=2)
    ep = truth["effect_parameters"]["motor_position_ripple"][j]
    f0 = ep["frequency_per_arm_rad"]
    assert abs(pc.freqs[0] - f0) / f0 < 0.01                   # within 1 %, no gear ratio given
    assert pc.velocity_trend[0] < 0                             # amplitude falls with speed
    assert pc.explained_fraction[0] > 5 * pc.explained_fraction[1]
    # with the gear ratio the harmonic number follows
    assert round(pc.per_motor_revolution(ep["gear_ratio"])[0]) == ep["harmonic_per_motor_rev"]
