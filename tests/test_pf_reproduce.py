"""ng-growth reproduction (univariate nonstationary growth model): PF < UKF < EKF."""
import json

import numpy as np

from drake_est.reproduce import experiments
from drake_est.reproduce.estimation import ng_growth, simulate_ng


def test_ng_growth_order_and_outputs(tmp_path):
    assert experiments()["ng-growth"] is ng_growth
    res = ng_growth(tmp_path, quick=True, n_runs=4, T=50, n_particles=300)
    m = res["rmse_mean"]
    assert m["PF"] < m["UKF"] < m["EKF"], m
    assert res["pf_beats_ukf_runs"] >= 3
    assert (tmp_path / "ng_growth.png").stat().st_size > 10_000
    json.dumps(res, allow_nan=False)
    # the simulated data are seeded
    a, b = simulate_ng(20, seed=3), simulate_ng(20, seed=3)
    assert np.array_equal(a[1], b[1]) and not np.array_equal(a[1], simulate_ng(20, seed=4)[1])
