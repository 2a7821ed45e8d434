"""LtvIdentifier LeafSystem: online parameter Kalman filter, equal to the offline ltv_filter."""
import numpy as np
import pytest

from drake_est.errors import DataError
from drake_est.identification import ltv


def test_ltv_identifier_system_matches_offline_filter():
    from pydrake.systems.analysis import Simulator

    from drake_est.systems.identifiers import LtvIdentifier

    x, u, y, A, B = ltv.jump_system(T=60, seed=3)
    lam = 10.0
    off = ltv.ltv_filter(x, u, lam, sigma_e=0.2)
    h = 0.01
    sys = LtvIdentifier(2, 1, lam, period=h, sigma_e=0.2)
    sim = Simulator(sys)
    ctx = sim.get_mutable_context()
    for t in range(x.shape[0]):
        sys.GetInputPort("state").FixValue(ctx, x[t])
        sys.GetInputPort("input").FixValue(ctx, u[min(t, len(u) - 1)])
        sim.AdvanceTo((t + 0.5) * h)
        if t >= 1:        # after the update at t, the estimate uses transitions 0..t-1
            Ah = sys.GetOutputPort("state_matrix").Eval(ctx).reshape(2, 2)
            Bh = sys.GetOutputPort("input_matrix").Eval(ctx).reshape(2, 1)
            cov = sys.GetOutputPort("parameter_covariance").Eval(ctx).reshape(6, 6)
            assert np.allclose(Ah, off.A[t - 1], atol=1e-10)
            assert np.allclose(Bh, off.B[t - 1], atol=1e-10)
            assert np.allclose(cov, off.cov[t - 1], atol=1e-10)


def test_online_filter_tracks_the_jump():
    x, u, y, A, B = ltv.jump_system(T=400, sigma=0.05, seed=0)
    f = ltv.ltv_filter(x, u, 5.0, sigma_e=0.05)
    assert np.max(np.abs(f.A[190] - A[190])) < 0.15
    assert np.max(np.abs(f.A[-1] - A[-1])) < 0.15
    # filter covariance is positive definite and shrinks with data
    assert np.all(np.linalg.eigvalsh(f.cov_row[-1]) > 0)
    assert np.trace(f.cov_row[-1]) < np.trace(f.cov_row[2])


def test_ltv_identifier_rejects_bad_configuration():
    from drake_est.systems.identifiers import LtvIdentifier

    with pytest.raises(DataError):
        LtvIdentifier(2, 1, lam=0.0, period=0.1)


def test_old_import_path_still_works():
    from drake_est.identification.ltv_system import LtvIdentifier as Old
    from drake_est.systems.identifiers import LtvIdentifier as New

    assert Old is New


def test_contract_case_outputs_equal_offline_filter():
    from pydrake.systems.analysis import Simulator

    from drake_est.systems.identifiers import contract_cases

    for case in contract_cases():
        sys = case.make()
        sim = Simulator(sys)
        ctx = sim.get_mutable_context()
        for name, val in case.inputs.items():
            sys.GetInputPort(name).FixValue(ctx, val)
        sim.AdvanceTo(case.t_final)
        for name, val in case.expected_outputs(sys).items():
            np.testing.assert_allclose(sys.GetOutputPort(name).Eval(ctx), val, rtol=case.rtol, atol=case.atol)
