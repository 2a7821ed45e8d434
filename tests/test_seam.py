"""Seam tracking (thesis Ch. 14): seams and compression (14.8), densities (14.6)-(14.7), the filter on the
generic ParticleFilter, the Diagram against the numpy loop, bad input, the CLI."""
import math
import subprocess
import sys

import numpy as np
import pytest

from drake_est.errors import DataError
from drake_est.seam import filter as F
from drake_est.seam.seam import Seam, compress_seam, load_seam_csv, plane_intersection, thesis_seam
from drake_est.seam.simulate import ScenarioConfig, make_scenario, run_loop, tracking_metrics


@pytest.fixture(scope="module")
def scn():
    # a fast scenario: 200 mm at 0.25 m/s, 1 kHz -> 800 steps
    return make_scenario(thesis_seam("xy"), ScenarioConfig(speed=0.25), seed=0)


def test_compression_is_sparse_and_within_tolerance():
    for kind in ("xy", "yz"):
        s = thesis_seam(kind)
        c = compress_seam(s, eps=2e-4)
        assert c.knots.shape[0] < s.points.shape[0] / 5
        assert c.max_error <= 1.5 * 2e-4 + 1e-9
        assert c.indices[0] == 0 and c.indices[-1] == s.points.shape[0] - 1


def test_straight_seam_compresses_to_its_ends():
    pts = np.column_stack([np.zeros(50), np.linspace(0, 0.2, 50), np.zeros(50)])
    c = compress_seam(Seam(pts, np.tile([0, 0, 1.0], (50, 1))))
    assert c.knots.shape[0] == 2


def test_plane_intersection_eq_14_7():
    pts = np.array([[0, 0, 0], [0, 1.0, 0], [1.0, 2.0, 0]])
    p, i, g = plane_intersection(pts, np.array([0.3, 1.5, 0.0]), np.array([0, 1.0, 0]))
    assert i == 1 and np.allclose(p, [0.5, 1.5, 0]) and math.isclose(g, 0.5)
    p, i, _ = plane_intersection(pts, np.array([0, 5.0, 0]), np.array([0, 1.0, 0]))
    assert p is None and i == -1


@pytest.mark.parametrize("pts, msg", [
    (np.zeros((1, 3)), "at least 2 points"),
    (np.array([[0, 0, 0], [0, 0.1, 0], [0, 0.1, 0]], float), "duplicate"),
    (np.array([[0, 0, 0], [0, np.nan, 0]]), "NaN"),
    (np.zeros((3, 2)), "(M, 3)"),
])
def test_bad_seam_points_one_line(pts, msg):
    with pytest.raises(DataError) as e:
        Seam(pts, np.ones((len(pts), 3)) if pts.ndim == 2 else None)
    assert msg in str(e.value) and "\n" not in str(e.value)


def test_seam_out_of_reach():
    far = thesis_seam("xy", origin=(2.5, -0.1, 0.3))
    with pytest.raises(DataError, match="out of the robot's reach"):
        make_scenario(far, ScenarioConfig(speed=1.0))


def test_laser_never_meets_seam(scn):
    from drake_est.seam.analysis import check_laser_sees_seam
    cfg = F.SeamFilterConfig(sensor_distances=(0.5,))   # 500 mm ahead: beyond the 200 mm seam
    with pytest.raises(DataError, match="never meets the seam"):
        check_laser_sees_seam(scn, cfg)


def test_csv_seam(tmp_path):
    p = tmp_path / "s.csv"
    s = thesis_seam("yz", n_points=30)
    np.savetxt(p, s.points, delimiter=",", header="x,y,z", comments="")
    c = load_seam_csv(p)
    assert np.allclose(c.points, s.points)
    (tmp_path / "bad.csv").write_text("x,y\n1,2\n")
    with pytest.raises(DataError, match="3 columns"):
        load_seam_csv(tmp_path / "bad.csv")


def test_hybrid_density_eq_14_6():
    d, sig = 1e-3, 2e-4
    inside = F.hybrid_logpdf(np.array([[0, 0, 0], [5e-4, 0, 0], [0, 0, 9.99e-4]]), d, sig)
    assert np.allclose(inside, inside[0])
    out = F.hybrid_logpdf(np.array([[0, d + sig, 0]]), d, sig)
    assert math.isclose(out[0], inside[0] - 0.5, rel_tol=1e-12)
    # the thesis' constant D = 1 / ((2 pi)^(3/2) sigma^3 + V(d, 3))
    assert math.isclose(inside[0], -math.log((2 * math.pi) ** 1.5 * sig ** 3 + 4 / 3 * math.pi * d ** 3))
    # with d -> 0 it is the normalised Gaussian (radial integral over R^3 = 1); for d > 0 the thesis' D is an
    # approximation (the Gaussian shell around the ball is not counted in full): the integral exceeds 1
    def total(d):
        r = np.linspace(0, d + 10 * sig, 40001)
        dens = np.exp(F.hybrid_logpdf(np.column_stack([r, 0 * r, 0 * r]), d, sig))
        return np.trapezoid(4 * np.pi * r ** 2 * dens, r)
    assert abs(total(0.0) - 1.0) < 1e-3
    assert total(d) > 1.0


def test_so3_exp_log_roundtrip():
    w = np.array([0.1, -0.2, 0.05])
    R = F.so3_exp(w)
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.allclose(F.so3_log(R), w, atol=1e-12)


def test_numba_and_numpy_likelihood_agree(scn):
    pf, model = F.make_seam_filter(scn.robot, scn.X_FT, scn.compressed, F.SeamFilterConfig(n_particles=300))
    rng = np.random.default_rng(1)
    x = rng.standard_normal((300, 6)) * np.array([1e-3] * 3 + [2e-3] * 3)
    k = 200
    q = scn.q_ref[k]
    from drake_est.seam.simulate import measure_all, true_tool_pose
    y = measure_all(scn, model, true_tool_pose(scn, q, scn.force[k])[0], q, scn.force[k], 0, k)
    X = model.tool_pose(q)
    args = (x, X[:3, :3], X[:3, 3], np.full(3, 1e-4), np.zeros(3), np.array([1e-3, 2e-4, 1.0, 2e-3, 1e-3, 2.0]),
            model.T_S_arr, y[9:].reshape(2, 4)[:, 1:].copy(), np.ones(2, np.int64), 0.01, model.knots,
            model.normals, 1e-4, 0.005, True)
    a = F.seam_loglik(*args, numba_ok=True)
    b = F.seam_loglik(*args, numba_ok=False)
    fin = np.isfinite(b)
    assert fin.sum() > 250
    assert np.array_equal(np.isfinite(a), fin)
    np.testing.assert_allclose(a[fin], b[fin], rtol=1e-10, atol=1e-10)


@pytest.mark.skipif(F.numba is None, reason="numba not installed")
def test_fused_step_equals_the_generic_filter_path(scn, monkeypatch):
    """The compiled step (likelihood + weighting + resampling + prediction) gives the generic
    ParticleFilter path's particles, weights, mean and ESS to 1e-10, resampling included."""
    from drake_est.seam.simulate import measure_all, true_tool_pose
    monkeypatch.delenv("DRAKE_EST_NO_NUMBA", raising=False)
    pf, model = F.make_seam_filter(scn.robot, scn.X_FT, scn.compressed, F.SeamFilterConfig(n_particles=200))
    xa, la = pf.initial_belief()
    xb, lb = xa.copy(), la.copy()
    n_res = 0
    for k in range(40):
        q = scn.q_ref[k]
        y = measure_all(scn, model, true_tool_pose(scn, q, scn.force[k])[0], q, scn.force[k], 0, k)
        u = np.concatenate([q, y[6:9]])
        ra = F.filter_step(pf, xa, la, y, u, k)
        monkeypatch.setenv("DRAKE_EST_NO_NUMBA", "1")
        rb = F.filter_step(pf, xb, lb, y, u, k)
        monkeypatch.delenv("DRAKE_EST_NO_NUMBA")
        for a, b in zip(ra[:4], rb[:4]):
            np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-10)
        assert ra[4] == rb[4]
        xa, la, xb, lb = ra[0], ra[1], rb[0], rb[1]
        n_res += bool(np.all(la == la[0]))
    assert n_res > 3           # resampling happened, so the index draw was compared too


@pytest.mark.skipif(F.numba is None, reason="numba not installed")
def test_laser_measurement_compiled_equals_numpy(scn, monkeypatch):
    """The compiled stripe simulation gives the numpy one's seam point and surface angle (and None when
    the plane misses the seam) on perturbed tool poses along the path."""
    from drake_est.seam.simulate import true_tool_pose
    rng = np.random.default_rng(3)
    P, Nrm = scn.seam.points, scn.seam.normals
    n_hit = n_miss = 0
    for k in range(0, scn.T, 37):
        X = true_tool_pose(scn, scn.q_ref[k], scn.force[k])[0].copy()
        X[:3, 3] += rng.normal(0, 2e-3, 3)
        for d in (0.04, 0.08, 0.5):
            T = F.sensor_mount(d)
            monkeypatch.delenv("DRAKE_EST_NO_NUMBA", raising=False)
            a = F.laser_measurement(X, T, P, Nrm)
            monkeypatch.setenv("DRAKE_EST_NO_NUMBA", "1")
            b = F.laser_measurement(X, T, P, Nrm)
            assert (a is None) == (b is None)
            if a is None:
                n_miss += 1
                continue
            n_hit += 1
            np.testing.assert_allclose(a[0], b[0], rtol=1e-10, atol=1e-12)
            assert abs(a[1] - b[1]) < 1e-10
    assert n_hit > 10 and n_miss > 0


def test_filter_is_the_generic_particle_filter(scn):
    from drake_est.estimation.pf import ParticleFilter
    pf, model = F.make_seam_filter(scn.robot, scn.X_FT, scn.compressed, F.SeamFilterConfig(n_particles=100))
    assert type(pf) is ParticleFilter and pf.nx == 6 and pf.ny == 17


def test_filter_recovers_a_fixed_deviation(scn):
    """With a constant true deviation of the tool from the nominal pose, two stripes and the robot
    measurement, the estimate converges to the deviation in the laser-observable directions."""
    from drake_est.seam.simulate import measure_all
    cfg = F.SeamFilterConfig(n_particles=300)
    pf, model = F.make_seam_filter(scn.robot, scn.X_FT, scn.compressed, cfg, seed=2)
    xi_true = np.array([1.0e-3, 0.0, -0.6e-3, 0.0, 0.0, 1.5e-3])      # cross, height, yaw
    x, logw = pf.initial_belief()
    for k in range(150, 450):
        q = scn.q_ref[k]
        Xt = F.deviation_to_pose(model.tool_pose(q), xi_true)
        y = measure_all(scn, model, Xt, q, scn.force[k], 5, k)
        x, logw, xi, ess, deg = F.filter_step(pf, x, logw, y, np.concatenate([q, y[6:9]]), k)
        assert not deg and np.all(np.isfinite(xi))
    assert abs(xi[0] - xi_true[0]) < 2e-4          # cross-seam (tool x) [m]
    assert abs(xi[2] - xi_true[2]) < 2e-4          # height (tool z) [m]
    # yaw about the tool z axis is weakly observable: the stripes 40 mm apart see 40 mm x yaw (0.06 mm here)
    # against 0.05 mm laser noise and the 0.17 mm compression error; bounded well below 0.5 deg
    assert abs(xi[5] - xi_true[5]) < 4e-3


def test_degenerate_measurement_is_reported_not_nan(scn):
    from drake_est.seam.simulate import measure_all, true_tool_pose
    pf, model = F.make_seam_filter(scn.robot, scn.X_FT, scn.compressed, F.SeamFilterConfig(n_particles=100))
    k = 300
    q = scn.q_ref[k]
    y = measure_all(scn, model, true_tool_pose(scn, q, scn.force[k])[0], q, scn.force[k], 0, k)
    u = np.concatenate([q, y[6:9]])
    # ESS collapse: the stripe reports the seam 0.5 m off -- finite but absurd under every particle
    y_bad = y.copy()
    y_bad[10] += 0.5
    x, logw = pf.initial_belief()
    x2, logw2, xi, ess, deg = F.filter_step(pf, x, logw, y_bad, u, k)
    assert ess < 2.0 and np.all(np.isfinite(x2)) and np.all(np.isfinite(xi))
    # all weights zero: every particle turned 90 deg about the tool x axis, so no laser plane meets the seam
    x = x.copy()
    x[:, 3] = np.pi / 2
    x3, logw3, xi3, ess3, deg3 = F.filter_step(pf, x, logw, y, u, k)
    assert deg3
    assert np.all(np.isfinite(x3)) and np.all(np.isfinite(logw3)) and np.all(np.isfinite(xi3))
    # and the filter goes on: the next good measurement is weighted normally
    x4, _, xi4, ess4, deg4 = F.filter_step(pf, *pf.initial_belief(), y, u, k + 1)
    assert not deg4 and np.all(np.isfinite(xi4))


def test_closed_loop_beats_open_loop(scn):
    cfg = F.SeamFilterConfig(n_particles=200, compliance=(1 - 0.3) / scn.config.stiffness)
    closed = tracking_metrics(scn, run_loop(scn, cfg, closed_loop=True, seed=0))
    opened = tracking_metrics(scn, run_loop(scn, cfg, closed_loop=False, seed=0))
    assert opened["cross_seam_rmse_mm"] > 1.0                       # the process force deflects the arm
    assert closed["cross_seam_rmse_mm"] < 0.5 * opened["cross_seam_rmse_mm"]
    assert closed["n_degenerate"] == 0


def test_diagram_reproduces_the_numpy_loop():
    from pydrake.systems.analysis import Simulator
    from drake_est.systems.seam import MakeSeamTrackingDiagram
    scn = make_scenario(thesis_seam("xy", n_points=101), ScenarioConfig(speed=1.0), seed=1)
    cfg = F.SeamFilterConfig(n_particles=60)
    ref = run_loop(scn, cfg, closed_loop=True, seed=3)
    d, h = MakeSeamTrackingDiagram(scn, cfg, closed_loop=True, seed=3)
    sim = Simulator(d)
    sim.AdvanceTo((scn.T - 1) * scn.config.dt)
    pose = h["log_pose"].FindLog(sim.get_context()).data().T.reshape(-1, 4, 4)
    cmd = h["log_cmd"].FindLog(sim.get_context()).data().T
    n = min(len(pose), scn.T)
    assert n >= scn.T - 1
    np.testing.assert_allclose(pose[:n], ref.X_true[:n], atol=1e-10)
    np.testing.assert_allclose(cmd[:n], ref.q_cmd[:n], atol=1e-10)


def test_cli_bad_seam_exits_2(tmp_path):
    (tmp_path / "one.csv").write_text("0.5,0,0.3\n")
    r = subprocess.run([sys.executable, "-m", "drake_est", "track", "--seam", str(tmp_path / "one.csv"),
                        "--out", str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "at least 2 points" in r.stderr and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    with pytest.raises(DataError, match="does not exist"):
        load_seam_csv(tmp_path / "none.csv")


@pytest.mark.slow
def test_reproduce_seam_sensors_quick(tmp_path):
    from drake_est.reproduce.seam import seam_sensors
    r = seam_sensors(tmp_path, quick=True, n_seeds=2, workers=1)
    e = r["errors"]
    # laser stripes make the cross-seam direction (x on the xy seam) measurable
    assert e["xy_2_sensors"]["x [mm]"]["median"] < e["xy_0_sensors"]["x [mm]"]["median"]
    assert (tmp_path / "seam_sensors.png").stat().st_size > 5000
