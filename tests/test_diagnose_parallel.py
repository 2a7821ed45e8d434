"""Threads of one diagnosis (drake_est.diagnose.parallel): the same report on one thread and on two."""
from __future__ import annotations

import threading

import numpy as np
import pytest

from conftest import bench_module
from drake_est.cli import main
from drake_est.diagnose import core, diagnose
from drake_est.diagnose.parallel import THREADS_ENV, check_threads, default_threads, diagnosis_threads, pmap
from drake_est.errors import DataError


def test_pmap_keeps_order_and_runs_on_the_pool_only_inside_the_block():
    names = []

    def f(x):
        names.append(threading.current_thread().name)
        return x * x

    assert pmap(f, range(6)) == [0, 1, 4, 9, 16, 25]
    assert set(names) == {threading.current_thread().name}      # no pool outside a block
    names.clear()
    with diagnosis_threads(2) as n:
        assert n == 2
        assert pmap(f, range(40)) == [x * x for x in range(40)]
    assert all(s.startswith("drake_est_diagnosis") for s in names), set(names)


def test_items_started_first_come_back_in_their_place():
    seven = threading.Event()
    waited_in_vain = []

    def f(x):
        if x == 7:
            seven.set()
        elif not seven.wait(timeout=5.0):       # item 7 is started before any other is done
            waited_in_vain.append(x)
        return -x

    with diagnosis_threads(2):
        assert pmap(f, range(10), first=[7]) == [-x for x in range(10)]
    assert not waited_in_vain
    assert pmap(lambda x: -x, range(4), first=[2]) == [0, -1, -2, -3]      # no pool: in order


def test_nested_pmap_runs_in_its_callers_thread():
    def inner(x):
        return threading.current_thread().name

    def outer(x):
        return set(pmap(inner, range(4))) == {threading.current_thread().name}

    with diagnosis_threads(2):
        assert all(pmap(outer, range(8)))       # and no deadlock with 8 outer items on 2 threads


def test_pmap_raises_the_callers_exception():
    def f(x):
        if x == 3:
            raise DataError("bad item 3")
        return x

    with diagnosis_threads(2), pytest.raises(DataError, match="bad item 3"):
        pmap(f, range(6))


@pytest.mark.parametrize("bad", [0, -1, "two", 2.5, True, None])
def test_bad_thread_counts_are_refused_naming_the_parameter(bad):
    with pytest.raises(DataError, match="threads"):
        check_threads(bad)


def test_the_environment_variable_sets_the_default(monkeypatch):
    monkeypatch.setenv(THREADS_ENV, "3")
    assert default_threads() == 3
    monkeypatch.setenv(THREADS_ENV, "zero")
    with pytest.raises(DataError, match=THREADS_ENV):
        default_threads()


def test_one_thread_and_two_give_the_same_report(monkeypatch):
    """A closed-loop log with an abrupt change, a ripple and Stribeck: three findings, so the backfits of two of them
    run at once on the model as accepted (core._search) as well as the candidates of every round; the report, every
    number of it, is the one-thread report."""
    from drake_est.diagnose.testbench_loop import generate
    lg, _ = generate({"abrupt_change": 1.0, "motor_position_ripple": 1.0, "stribeck": 1.0}, seed=3, duration=150.0,
                     sample_rate=100.0)
    with pytest.raises(DataError, match="threads must be at least 1"):
        diagnose(lg, robot="generic", seed=0, simulate=False, threads=0)
    one = diagnose(lg, robot="generic", seed=0, simulate=False, threads=1)
    ahead = []
    orig = core.pmap

    def spy(fn, items, **kw):
        items = list(items)
        if items and all(isinstance(b, tuple) and getattr(b[1], "__name__", "").startswith("backfit_") for b in items):
            ahead.append([b[0] for b in items])
        return orig(fn, items, **kw)

    monkeypatch.setattr(core, "pmap", spy)
    two = diagnose(lg, robot="generic", seed=0, simulate=False, threads=2)
    assert sorted(one.effects) == ["abrupt_change", "motor_position_ripple", "stribeck"]
    assert ahead and all(len(a) >= 2 for a in ahead), ahead      # the backfits were run ahead, at once
    assert two.result.timing["threads"] == 2 and one.result.timing["threads"] == 1
    report_text = bench_module("bench_diagnose_speed")._report_text       # the speed benchmark's comparison
    assert report_text(two) == report_text(one)


def test_cli_refuses_a_bad_thread_count(tmp_path, capsys):
    t = np.arange(0.0, 20.0, 0.01)
    f = tmp_path / "log.csv"
    np.savetxt(f, np.column_stack([t, np.sin(t), np.cos(t)]), delimiter=",", header="t,q1,tau1", comments="")
    assert main(["diagnose", str(f), "--threads", "0", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--threads" in err and "Traceback" not in err, err


def test_joint_columns_are_kept_while_the_rows_are_the_same():
    """JointData.cached_columns: the detectors' position kernels and Stribeck shapes are built once per set of used
    rows (read-only), built again after rows are dropped, and not kept beyond COLUMN_CACHE_MAX_ELEMS numbers; a
    pickled joint carries none of them."""
    import pickle

    from drake_est.diagnose import nominal

    n = 1000
    t = np.arange(n) * 0.01
    jd = nominal.JointData(joint=1, col=0, t=t, q=np.sin(t), v=np.cos(t), a=-np.sin(t), tau=np.zeros(n),
                           rb=np.zeros(n), rows=np.arange(n), train=np.arange(n) % 2 == 0, val=np.arange(n) % 2 == 1)
    calls = []

    def make():
        calls.append(1)
        return np.outer(jd.q[jd.rows], [1.0, 2.0])

    A = jd.cached_columns(("k", 2), make)
    assert jd.cached_columns(("k", 2), make) is A and len(calls) == 1
    assert not A.flags.writeable
    jd.drop_rows(np.arange(n) < 10)
    B = jd.cached_columns(("k", 2), make)
    assert len(calls) == 2 and B.shape == (n - 10, 2)
    assert "column_cache" in jd.__dict__ and pickle.loads(pickle.dumps(jd)).column_cache == {}
    old = nominal.COLUMN_CACHE_MAX_ELEMS
    try:
        nominal.COLUMN_CACHE_MAX_ELEMS = 10
        C = jd.cached_columns(("k", 3), make)
        assert jd.cached_columns(("k", 3), make) is not C and len(calls) == 4      # too big to keep
    finally:
        nominal.COLUMN_CACHE_MAX_ELEMS = old
