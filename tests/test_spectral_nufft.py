"""NUFFT engine of the least-squares / LPV periodogram (issue 20): equals the direct sums."""
import numpy as np
import pytest

from drake_est.errors import DataError
from drake_est.spectral.basis import ScheduleBasis
from drake_est.spectral.detect import _SingleFrequencyESS, fft_scan
from drake_est.spectral.lssa import ls_scan
from drake_est.spectral.nufft import trig_sums, trig_sums_direct, uniform_grid_params

TOL = 1e-9


def _rel(a, b):
    return float(np.max(np.abs(a - b) / np.abs(b)))


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(3)
    N = 2500
    x = np.sort(rng.uniform(10.0, 60.0, N))          # offset on purpose: centring is internal
    v = rng.uniform(-1, 1, N)
    y = (1 + v) * np.cos(2 * np.pi * 3.3 * x + 0.4) + 0.3 * rng.standard_normal(N) + 0.5
    return x, y, v


def _phi(v, J, split):
    return np.ones((v.size, 1)) if J == 1 else ScheduleBasis.from_data(v, J, sign_split=split)(v)


@pytest.mark.parametrize("J,split", [(1, False), (4, False), (4, True)])
@pytest.mark.parametrize("fit_mean", [False, True])
@pytest.mark.parametrize("grid", ["uniform", "random"])
def test_nufft_equals_direct(data, J, split, fit_mean, grid):
    x, y, v = data
    rng = np.random.default_rng(1)
    f = 0.03 + 0.007 * np.arange(800) if grid == "uniform" else rng.uniform(0.0, 12.0, 400)
    Phi = _phi(v, J, split)
    d = ls_scan(x, y, f, Phi, method="direct", fit_mean=fit_mean)
    n = ls_scan(x, y, f, Phi, method="nufft", fit_mean=fit_mean)
    assert _rel(n, d) < TOL
    # the periodogram really depends on the model: the offset changes it
    other = ls_scan(x, y, f, Phi, method="direct", fit_mean=not fit_mean)
    assert _rel(other, d) > 1e-3


def test_fit_mean_is_explained_beyond_the_mean(data):
    x, y, _ = data
    f = np.array([0.5, 3.3, 7.1])
    ess = ls_scan(x, y, f, fit_mean=True, method="direct")
    for k, fk in enumerate(f):
        A = np.column_stack([np.ones_like(x), np.cos(2 * np.pi * fk * x), np.sin(2 * np.pi * fk * x)])
        r = y - A @ np.linalg.lstsq(A, y, rcond=None)[0]
        assert abs(ess[k] - (np.sum((y - y.mean()) ** 2) - r @ r)) < 1e-8 * ess[k]


def test_edge_frequencies_match_direct():
    """f = 0, tiny f, and exactly/near the Nyquist rate of regular sampling: the normal equations are
    (nearly) singular; the NUFFT path recomputes them directly, agreeing to the conditioning limit."""
    rng = np.random.default_rng(0)
    N = 3000
    x = np.arange(N) * 0.01                       # regular: Nyquist 50
    y = np.cos(2 * np.pi * 7.0 * x) + 0.2 * rng.standard_normal(N) + 0.3
    f = np.r_[0.0, 1e-7, 1e-4, np.linspace(0.05, 49.9, 400), 50.0 - 1e-6, 50.0]
    for fit_mean in (False, True):
        d = ls_scan(x, y, f, method="direct", fit_mean=fit_mean)
        n = ls_scan(x, y, f, method="nufft", fit_mean=fit_mean)
        assert np.all(np.isfinite(n))
        inner = slice(3, -2)
        assert _rel(n[inner], d[inner]) < TOL
        # edges: the same handling (same jitter, same direct sums) -> equal up to rounding amplified
        # by the (huge) condition number there
        assert np.allclose(n, d, rtol=1e-6, atol=1e-9 * np.max(d))


def test_auto_switch_and_fft_scan_exact(data):
    x, y, v = data
    Phi = _phi(v, 4, True)
    f = np.linspace(0.05, 10, 50)
    # tiny: auto = direct (identical), large: auto = nufft (equal to 1e-9)
    assert np.array_equal(ls_scan(x, y, f, Phi), ls_scan(x, y, f, Phi, method="direct"))
    fr, ess = fft_scan(x, y, Phi, f_max=12.0, f_min=0.05)
    assert fr.size > 500
    assert _rel(ess, ls_scan(x, y, fr, Phi, method="direct")) < TOL
    # the legacy binned scan is only approximate
    _, binned = fft_scan(x, y, Phi, f_max=12.0, f_min=0.05, method="binned")
    assert _rel(binned, ess) > 1e-6
    one = _SingleFrequencyESS(x, y, Phi)
    assert one.PP is not None
    for k in (3, 200):
        assert abs(one(fr[k]) - ess[k]) < 1e-9 * ess[k]


def test_single_frequency_ess_streams_long_logs(data, monkeypatch):
    """Above SINGLE_ESS_MAX_ELEMS the basis pairs are streamed (no pair-product matrix), with the same sums."""
    import drake_est.spectral.detect as det

    x, y, v = data
    Phi = _phi(v, 4, True)
    kept = det._SingleFrequencyESS(x, y, Phi)
    monkeypatch.setattr(det, "SINGLE_ESS_MAX_ELEMS", 10)
    streamed = det._SingleFrequencyESS(x, y, Phi)
    assert streamed.PP is None and kept.live.size < kept.m0.size      # the sign split's disjoint pairs are skipped
    for f in (0.11, 3.3, 7.77):
        assert abs(streamed(f) - kept(f)) <= 1e-12 * kept(f)
        assert abs(kept(f) - ls_scan(x, y, [f], Phi, method="direct")[0]) < 1e-9 * kept(f)


def test_trig_sums_uniform_shift_and_type3():
    rng = np.random.default_rng(5)
    x = rng.uniform(-3, 40, 2000)
    c = rng.standard_normal((2, 2000)) + 1j * rng.standard_normal((2, 2000))
    for f in (1.5 + 0.01 * np.arange(501), 1.5 + 0.01 * np.arange(500), rng.uniform(0, 8, 300)):
        for h in (1.0, 2.0):
            ref = trig_sums_direct(x, c, f, h)
            got = trig_sums(x, c, f, h)
            assert np.max(np.abs(got - ref)) < 1e-11 * np.max(np.abs(ref))
    assert uniform_grid_params(np.linspace(0.1, 3, 77)) is not None
    assert uniform_grid_params(np.r_[0.1, 0.2, 0.31]) is None


def test_bad_input_is_data_error(data):
    x, y, _ = data
    with pytest.raises(DataError, match="method"):
        ls_scan(x, y, [1.0], method="fast")
    with pytest.raises(DataError, match="Phi"):
        ls_scan(x, y, [1.0], Phi=np.ones((3, 2)))
    with pytest.raises(DataError, match="frequency grid"):
        ls_scan(x, y, [1.0, np.nan])


# ----------------------------------------------------------------------------- hardening (issue 19 items 3, 8, 9)

def test_extreme_values_are_a_data_error():
    from drake_est.spectral import find_periodic_components

    rng = np.random.default_rng(0)
    x = np.sort(rng.uniform(0, 6, 2000))
    y = np.sin(2 * np.pi * 3 * x) + 0.1 * rng.standard_normal(2000)
    y[10] = 1e300
    with pytest.raises(DataError, match="too large"):
        find_periodic_components(x, y, n_components=1)


def test_schedule_equal_to_signal_is_a_data_error():
    from drake_est.spectral import find_periodic_components

    rng = np.random.default_rng(1)
    x = np.sort(rng.uniform(0, 6, 2000))
    y = np.sin(2 * np.pi * 3 * x) + 0.1 * rng.standard_normal(2000)
    with pytest.raises(DataError, match="explain the signal entirely"):
        find_periodic_components(x, y, schedule=y, base=np.column_stack([np.sign(y), y]), n_components=1)


def _write_log(path, q, tau):
    t = np.arange(q.size) * 0.01
    dq = np.gradient(q, t)
    rows = "\n".join(",".join(repr(float(v)) for v in r) for r in zip(t, q, dq, tau))
    path.write_text("t,q1,dq1,tau1\n" + rows + "\n")


@pytest.mark.parametrize("extra,quantize,msg", [(["--gear-ratio", "inf"], False, "--gear-ratio"),
                                                (["--gear-ratio", "nan"], False, "--gear-ratio"),
                                                (["--schedule", "tau1"], False, "entirely"),
                                                ([], True, None)])
def test_spectrum_cli_hardening(tmp_path, capsys, extra, quantize, msg):
    from drake_est.cli import main

    rng = np.random.default_rng(0)
    t = np.arange(3000) * 0.01
    q = 2.4 * np.sin(0.3 * t)
    if quantize:
        q = np.round(q / 0.5) * 0.5          # positions quantized to 0.5 rad used to crash the plot
    tau = 0.5 * np.sign(np.gradient(q, t)) + 0.2 * np.sin(37 * q) + 0.05 * rng.standard_normal(t.size)
    _write_log(tmp_path / "log.csv", q, tau)
    args = ["spectrum", str(tmp_path / "log.csv"), "--signal", "tau1", "--position", "q1", "--schedule", "dq1",
            "--n-components", "1", "--out", str(tmp_path / "o")]
    if "--schedule" in extra:
        args[args.index("--schedule") + 1] = extra[1]
    else:
        args += extra
    rc = main(args)
    err = capsys.readouterr().err
    if msg is None:
        assert rc == 0 and (tmp_path / "o" / "spectrum.png").stat().st_size > 1000
    else:
        assert rc == 2 and msg in err and "Traceback" not in err


@pytest.mark.parametrize("fit_mean", [False, True])
@pytest.mark.parametrize("method", ["nufft", "direct"])
def test_scan_plan_reuses_gram_for_many_signals(data, fit_mean, method):
    """LSScanPlan: one Gram part, many signals; each scan equals ls_scan of that signal alone."""
    from drake_est.spectral.lssa import LSScanPlan

    x, y, v = data
    Phi = _phi(v, 4, True)
    f = 0.03 + 0.007 * np.arange(800)
    plan = LSScanPlan(x, f, Phi, method=method, fit_mean=fit_mean)
    rng = np.random.default_rng(7)
    for y_k in (y, y - np.cos(2 * np.pi * 3.3 * x), rng.standard_normal(x.size)):
        ref = ls_scan(x, y_k, f, Phi, method="direct", fit_mean=fit_mean)
        assert _rel(plan.ess(y_k), ref) < TOL
    with pytest.raises(DataError, match="signal has 3 samples"):
        plan.ess(np.ones(3))


def test_factored_gram_blocks_equal_dense_solves(data):
    """LSScanPlan factors its Gram blocks once (gram_factor); each scan is then a forward substitution equal to
    explained_ss's dense solves.  A block that is not positive definite leaves no factor, and the plan solves."""
    from drake_est.spectral.lssa import LSScanPlan
    from drake_est.spectral.nufft import explained_ss, explained_ss_factored, gram_factor

    x, y, v = data
    Phi = _phi(v, 4, True)
    f = 0.03 + 0.007 * np.arange(800)
    plan = LSScanPlan(x, f, Phi, method="nufft")
    assert plan.L is not None and plan.L.shape == (f.size, 8, 8)
    rng = np.random.default_rng(11)
    b = rng.standard_normal((f.size, 8))
    assert _rel(explained_ss_factored(plan.L, b), explained_ss(plan.G, b, plan.jitter)) < 1e-9
    L = plan.L
    plan.L = None
    dense = plan.ess(y)
    plan.L = L
    assert _rel(plan.ess(y), dense) < 1e-9
    G = plan.G.copy()
    G[5] = -G[5]
    assert gram_factor(G) is None
    assert gram_factor(G[:, :2, :2]) is None                 # d = 2: explained_ss' closed form
    assert LSScanPlan(x, f, Phi, method="nufft", fit_mean=True).L is None


def test_periodic_components_with_kept_plans_equal_fresh_ones(data):
    """find_periodic_components(scan_plans=...): the kept plan is reused for another residual at the same
    positions, a new plan made for other positions, at most MAX_SCAN_PLANS kept; results unchanged."""
    from drake_est.spectral.detect import MAX_SCAN_PLANS, find_periodic_components

    x, y, v = data
    plans = {}
    kw = dict(schedule=v, n_components=2, n_basis=4)
    a = find_periodic_components(x, y, scan_plans=plans, **kw)
    assert len(plans) == 1
    y2 = y + 0.5 * np.sin(2 * np.pi * 7.1 * x)
    b = find_periodic_components(x, y2, scan_plans=plans, **kw)
    assert len(plans) == 1                      # same positions, grid and basis: reused
    for got, sig in ((a, y), (b, y2)):
        ref = find_periodic_components(x, sig, **kw)
        np.testing.assert_allclose(got.freqs, ref.freqs, rtol=1e-9)
        np.testing.assert_allclose(got.explained_fraction, ref.explained_fraction, rtol=1e-7, atol=1e-12)
    assert abs(b.freqs[0] - 7.1) < 0.01 or abs(b.freqs[1] - 7.1) < 0.01
    for k in range(MAX_SCAN_PLANS + 1):         # other positions: new plans, the oldest dropped
        find_periodic_components(x + 0.1 * (k + 1), y, scan_plans=plans, **kw)
    assert len(plans) == MAX_SCAN_PLANS
