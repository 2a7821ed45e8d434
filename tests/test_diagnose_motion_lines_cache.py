"""The motion's own spectral lines (detectors.motion_lines_hz) are computed once per joint and reused while the
joint's full-length t, q and v arrays are the same objects (nineteenth round: they were computed again in every
round of the search, 28 % of a closed-loop log's diagnosis)."""
from __future__ import annotations

import pickle

import numpy as np

from drake_est.diagnose import detectors as det
from drake_est.diagnose.nominal import JointData


def _joint(seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(6000) * 0.01
    q = 0.8 * np.sin(2 * np.pi * 0.2 * t) + 0.3 * np.sin(2 * np.pi * 0.7 * t)
    v = np.gradient(q, t) + 1e-3 * rng.standard_normal(t.size)
    z = np.zeros_like(t)
    return JointData(joint=1, col=0, t=t, q=q, v=v, a=z, tau=z, rb=z, rows=np.arange(t.size),
                     train=np.arange(t.size) % 2 == 0, val=np.arange(t.size) % 2 == 1)


def test_lines_are_computed_once_and_again_for_new_arrays(monkeypatch):
    jd = _joint()
    want = det._motion_lines_hz(jd, det.MOTION_LINE_SHARE, det.MOTION_LINE_SWING)
    assert want.size >= 2 and np.any(np.abs(want - 0.2) < 0.01)
    calls = []
    real = det._motion_lines_hz
    monkeypatch.setattr(det, "_motion_lines_hz", lambda *a: calls.append(1) or real(*a))
    first = det.motion_lines_hz(jd)
    first[:] = -1.0                                   # a caller's copy: the stored lines do not change
    second = det.motion_lines_hz(jd)
    assert len(calls) == 1 and np.array_equal(second, want)
    det.motion_lines_hz(jd, share=0.5)                # another share: computed
    assert len(calls) == 2
    jd.drop_rows(np.arange(jd.rows.size) < 100)      # rows dropped: the full-length arrays stay, so does the cache
    det.motion_lines_hz(jd)
    assert len(calls) == 2
    jd.v = jd.v.copy()                                # a new velocity array: computed again
    assert np.array_equal(det.motion_lines_hz(jd), want) and len(calls) == 3


def test_objects_without_the_cache_and_pickles():
    jd = _joint(1)
    from types import SimpleNamespace
    plain = SimpleNamespace(t=jd.t, q=jd.q, v=jd.v)   # e.g. a caller's own record: no cache, same lines
    assert np.array_equal(det.motion_lines_hz(plain), det.motion_lines_hz(jd))
    assert jd.motion_lines and not pickle.loads(pickle.dumps(jd)).motion_lines
