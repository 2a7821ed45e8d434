"""The diagnosis on real measurements nobody on this project generated (../shared/data, MIT licensed):

* ODrive brushless motor at slow speed without anti-cogging compensation (gchenfc/ODrive,
  analysis/cogging_torque): the cogging torque is a ripple in the motor angle; its known harmonics
  are multiples of 7 per revolution (7, 14, 28, 36 dominate).
* EMPS electro-mechanical positioning system (Janot, Gautier and Brunot 2019, wmkouw/NSI-EMPS): a
  prismatic axis whose friction shows a repeatable pattern along the position.

Both are diagnosed as generic axes from t, position and torque/current only."""
from __future__ import annotations

import numpy as np
import pytest

from drake_est.data import Log
from drake_est.datasets.paths import default_data_dir
from drake_est.diagnose import diagnose

DATA = default_data_dir()


@pytest.mark.requires_data("odrive_cogging/slow2/nocomp_0.npy")  # skip locally, fail under CI=true
def test_odrive_cogging_is_found_as_motor_position_ripple():
    t, pos, cur = np.load(DATA / "odrive_cogging" / "slow2" / "nocomp_0.npy")
    q = pos / 8192 * 2 * np.pi                       # encoder counts -> motor angle [rad]
    rep = diagnose(Log(t=t - t[0], q=q, tau=cur, joints=[1]), robot="generic", simulate=False)
    ripple = [f for f in rep.findings if f["effect"] == "motor_position_ripple"]
    assert ripple, [f["effect"] for f in rep.findings]
    per_rev = np.array(ripple[0]["evidence"]["frequencies_per_arm_rad"]) * 2 * np.pi
    # the strongest component is a cogging harmonic: a multiple of 7 per revolution
    k = per_rev[0] / 7.0
    assert abs(k - round(k)) < 0.05 and round(k) >= 1, per_rev
    d = rep.to_dict()
    assert d["final"]["validation"]["rmse"] < 0.6 * d["nominal"]["validation"]["rmse"]


@pytest.mark.requires_data("emps/DATA_EMPS.mat")  # skip locally, fail under CI=true
@pytest.mark.long
def test_emps_position_dependent_friction():
    import scipy.io
    m = scipy.io.loadmat(DATA / "emps" / "DATA_EMPS.mat", squeeze_me=True)
    force = m["gtau"] * m["vir"]                     # drive force [N]
    rep = diagnose(Log(t=m["t"], q=m["qm"], tau=force, joints=[1]), robot="generic", simulate=False)
    effects = [f["effect"] for f in rep.findings]
    assert "position_dependent_friction" in effects, effects
    d = rep.to_dict()
    assert d["final"]["validation"]["rmse"] < 0.5 * d["nominal"]["validation"]["rmse"]
