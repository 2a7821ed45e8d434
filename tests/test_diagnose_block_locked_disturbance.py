"""A disturbance periodic in time at half the held-out split's alternation frequency (fresh loop spec 40305): the
training blocks (nominal.block_split, blocks of nominal.BLOCK_S) see one half of its cycle and the held-out blocks the
other half.  With the default split 40305 is named a ripple, which the ninety-ninth round reports ambiguous with the
disturbance (tests/test_diagnose_ripple_split_locked.py)."""
import numpy as np

from drake_est.diagnose import diagnose, nominal
from conftest import closed_loop_case


def test_the_one_second_split_locks_to_a_half_hertz_disturbance():
    # with the default blocks (1 s) each training block holds the same half of a 0.5 Hz cycle: shifted by the phase,
    # the training rows' sin(pi (t - t0)) never changes sign within a block and has the same sign in every block
    assert nominal.BLOCK_S == 1.0
    t = np.arange(0.0, 120.0, 1e-3)
    train, val = nominal.block_split(t, np.arange(t.size))
    h = np.sin(np.pi * t)           # 0.5 Hz, zero at every block boundary
    assert (h[train] >= -1e-9).all() and (h[val] <= 1e-9).all()
    # blocks of 0.7 s: both halves of the cycle in training and in held-out rows
    train7, val7 = nominal.block_split(t, np.arange(t.size), n_blocks=int(np.ceil(120 / 0.7)) + 1)
    assert (h[train7] > 0.5).any() and (h[train7] < -0.5).any()
    assert (h[val7] > 0.5).any() and (h[val7] < -0.5).any()
    # 2 Hz (whole periods in a block) is not locked: both signs in each half of the split
    h2 = np.sin(4 * np.pi * t)
    assert (h2[train] > 0.5).any() and (h2[train] < -0.5).any()


def test_spec_40305_with_blocks_that_do_not_lock_names_the_disturbance(monkeypatch):
    # fresh loop spec 40305: a time-periodic disturbance alone at 0.5 Hz (1000 Hz, quantized torque) on an axis that
    # barely moves; with 0.7 s blocks the diagnosis names it at 0.5 Hz, with most of the residual gone
    mod, spec, log, _ = closed_loop_case(40305)
    assert spec["effects"]["_f_hz"] == 0.5
    monkeypatch.setattr(nominal, "BLOCK_S", 0.7)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    assert [(f["effect"], f["status"]) for f in d["findings"]] == [("time_periodic_disturbance", "named")]
    f = d["findings"][0]
    assert abs(f["parameters"]["frequency_hz"] - 0.5) < 1e-3
    assert f["evidence"]["heldout_rmse_reduction"] > 0.8
    assert d["unexplained"] == [] and mod.judge(spec, d)["correct"]
