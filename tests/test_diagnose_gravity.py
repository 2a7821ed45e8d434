"""Gravity-loaded joints diagnosed with ``--robot generic`` (issue 16 item 6).

A generic axis has no gravity model, so on IRB 140 joints 2 and 3 the gravity load is a real,
direction-independent, position-dependent torque: ``position_dependent_load`` is the right name for it
(it is what bench_diagnose.py's judge sets aside for generic axes). What must not happen is that what a
badly fitted gravity leaves behind is named as other effects (before this change: position-dependent
friction and a motor ripple on a log with nothing planted)."""
from __future__ import annotations

import functools
import os

import numpy as np
import pytest

os.environ.setdefault("DRAKE_EST_NO_PROGRESS", "1")

from drake_est.data import Log  # noqa: E402
from drake_est.diagnose import diagnose  # noqa: E402
from drake_est.diagnose.core import Model, run_diagnosis  # noqa: E402
from drake_est.diagnose.nominal import _load_nuisance  # noqa: E402
from drake_est.identification.friction.extensions import columns_at  # noqa: E402
from drake_est.synth import synthesize  # noqa: E402


@functools.lru_cache(maxsize=None)
def _log(effect, joint):
    log, truth = synthesize(effect, seed=5, joints=[joint], duration=100.0, sample_rate=50.0, noise_std=0.3)
    return Log(t=log.t, q=log.q, tau=log.tau, joints=log.joints), truth


@functools.lru_cache(maxsize=None)
def _findings(effect, joint):
    log, _ = _log(effect, joint)
    d = diagnose(log, robot="generic", seed=0, simulate=False).to_dict()
    return [(f["effect"], f["joint"]) for f in d["findings"]]


@pytest.mark.parametrize("joint", [2, pytest.param(3, marks=pytest.mark.long)])
def test_gravity_joint_without_effect_names_only_the_load(joint):
    f = _findings("none", joint)
    # the gravity load is there and is named; nothing else is
    assert ("position_dependent_load", joint) in f, f
    assert [x for x in f if x[0] != "position_dependent_load"] == [], f


@pytest.mark.parametrize("joint", [pytest.param(2, marks=pytest.mark.long), pytest.param(3, marks=pytest.mark.long)])
def test_gravity_joint_with_ripple_names_the_ripple(joint):
    f = _findings("motor_position_ripple", joint)
    assert ("motor_position_ripple", joint) in f, f
    assert {x[0] for x in f} <= {"motor_position_ripple", "position_dependent_load"}, f


def test_load_extension_fits_gravity_to_noise_level():
    """The load candidate carries sin q, cos q unpenalized: its held-out RMSE is at the noise level even for a
    gravity load hundreds of times the noise (a relative ridge on them left ~20 % more)."""
    log, truth = _log("none", 2)
    res = run_diagnosis(log, robot="generic")
    step = next(s for s in res.steps if s.ext.effect == "position_dependent_load")
    jd = res.prep.joints[2]
    e = (jd.y - step.fit.pred[2])[jd.val]
    assert np.sqrt(np.mean(e ** 2)) < 1.1 * truth["noise_std"]
    # the harmonic columns are the first two, not penalized; the kernels are
    m = Model(res.prep, [step.ext]).penalized(2)
    assert not m[:4].any() and m[4:].all()
    # the spec evaluates to the same columns at the used rows (simulation and report use it)
    C = columns_at(step.ext.spec, jd.q[jd.rows], jd.v[jd.rows], jd.t[jd.rows])
    assert np.allclose(C, step.ext.cols[2])


def test_load_nuisance_drops_collinear_columns():
    q_wide = np.linspace(-1.5, 1.5, 500)
    assert len(_load_nuisance(q_wide)) == 3
    # over 0.01 rad cos q is 1 - q^2/2: not separable from the constant and sin q
    q_small = np.linspace(0.3, 0.31, 500)
    assert len(_load_nuisance(q_small)) == 2
