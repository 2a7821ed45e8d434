"""Friction identification (thesis Ch. 9) on numpy-simulated joints with known truth."""
import numpy as np
import pytest

from drake_est.errors import DrakeEstError, IdentifiabilityError
from drake_est.identification.friction import fit_energy, initial_guess, simulate_energy_system
from drake_est.identification.friction import (
    JointFriction, build_model, fit_friction, motor_position, select_steady)
from drake_est.metrics import npe


def sweep(rng, duration=200.0, fs=50.0, lo=-2.0, hi=2.0, levels=(0.2, 0.4, 0.6, 0.9, 1.2), ramp=2.0):
    """Piecewise-constant velocities between two limits (Sec. 9.6) with finite acceleration."""
    dt = 1.0 / fs
    t = np.arange(0.0, duration, dt)
    q = np.empty_like(t)
    v = np.empty_like(t)
    a = np.empty_like(t)
    qk, vk, d, vc = 0.0, 0.0, 1.0, rng.choice(levels)
    for k in range(t.size):
        acc = np.clip((d * vc - vk) / dt, -ramp, ramp)
        vk += acc * dt
        qk += vk * dt
        if (d > 0 and qk >= hi) or (d < 0 and qk <= lo):
            d, vc = -d, rng.choice(levels)
        q[k], v[k], a[k] = qk, vk, acc
    return t, q, v, a


def test_selection_counts_and_thresholds():
    rng = np.random.default_rng(0)
    t, q, v, a = sweep(rng, duration=60)
    sel = select_steady(v, a)
    assert sel.n_kept + sel.n_low_velocity + sel.n_accelerating == sel.n_total == t.size
    assert sel.n_low_velocity > 0 and sel.n_accelerating > 0
    assert np.all(np.abs(v[sel.mask]) > sel.v_min)
    assert np.all(np.abs(a[sel.mask]) < sel.a_max)
    assert "dropped" in sel.summary()


def test_asymmetric_nominal_recovers_parameters():
    rng = np.random.default_rng(1)
    t, q, v, a = sweep(rng)
    y = 1.5 * v + np.where(v > 0, 4.0, -6.0) * (v != 0) + 0.3 * a + 0.1 * rng.standard_normal(t.size)
    res = fit_friction(t, q, v, y, model="nominal", ddq=a)
    p = res.model.params()
    assert p["kv"] == pytest.approx(1.5, rel=0.05)
    assert p["kc+"] == pytest.approx(4.0, rel=0.03)
    assert p["kc-"] == pytest.approx(6.0, rel=0.03)
    assert res.validation["rmse"] < 0.12


@pytest.fixture(scope="module")
def position_data():
    rng = np.random.default_rng(2)
    t, q, v, a = sweep(rng, duration=300)
    kc, kv, sigma = 5.0, 2.0, 0.1
    bump = 1.8 * np.exp(-0.5 * ((q - 0.6) / 0.25) ** 2) - 1.2 * np.exp(-0.5 * ((q + 0.9) / 0.3) ** 2)
    F = kv * v + np.sign(v) * (kc + bump)
    y = F + sigma * rng.standard_normal(t.size)
    return t, q, v, a, y, sigma


def test_position_model_beats_nominal_on_held_out_data(position_data):
    t, q, v, a, y, sigma = position_data
    nom = fit_friction(t, q, v, y, model="nominal", nominal="viscous", ddq=a)
    pos = fit_friction(t, q, v, y, model="position", nominal="viscous", ddq=a)
    assert pos.validation["rmse"] < 0.5 * nom.validation["rmse"]
    assert pos.validation["rmse"] < 1.15 * sigma
    assert pos.validation["fit"] > nom.validation["fit"]
    assert pos.model.params()["kv"] == pytest.approx(2.0, rel=0.1)


def test_motor_position_model_captures_ripple():
    rng = np.random.default_rng(3)
    t, q, v, a = sweep(rng, duration=300, fs=100)
    g, sigma = 117.0, 0.05
    pm = motor_position(q, g)
    ripple = 1.0 / (1 + np.abs(v) / 0.6) * np.sin(2 * pm + 0.7)
    y = 2.0 * v + 5.0 * np.sign(v) + ripple + sigma * rng.standard_normal(t.size)
    nom = fit_friction(t, q, v, y, model="nominal", ddq=a)
    mot = fit_friction(t, q, v, y, model="motor", ddq=a, gear_ratio=g, n_motor=18, n_velocity=4)
    assert mot.validation["rmse"] < 0.3 * nom.validation["rmse"]
    assert mot.validation["rmse"] < 1.15 * sigma * np.sqrt(1 + 0.5)   # noise + small basis error


def test_gear_coupled_wrist_joint():
    rng = np.random.default_rng(4)
    N = 6000
    t = np.arange(N) * 0.02
    DQ = np.stack([np.sin(0.31 * t + p) + 0.3 * np.sin(1.7 * t + 2 * p) for p in (0.0, 1.0, 2.0)], axis=1)
    Q = np.cumsum(DQ, axis=0) * 0.02
    coupling = np.array([[54.0, 0, 0], [1.1, 56.0, 0], [0.9, 1.2, 48.0]])
    v = DQ
    y = 1.8 * np.sign(v[:, 2]) + 0.5 * v[:, 2] + 0.8 * np.sign(v[:, 0]) + 0.3 * v[:, 0] \
        + 0.6 * np.sign(v[:, 1]) + 0.2 * v[:, 1] + 0.05 * rng.standard_normal(N)
    sel = select_steady(v[:, 2], a_max=np.inf, v_min=0.05)
    nom = fit_friction(t, Q, DQ, y, model="nominal", nominal="viscous", index=2, selection=sel)
    cpl = fit_friction(t, Q, DQ, y, model="coupled", nominal="viscous", index=2, coupling=coupling, selection=sel)
    p = cpl.model.params()
    truth = {"kc": 1.8, "kv": 0.5, "kc_q1": 0.8, "kv_q1": 0.3, "kc_q2": 0.6, "kv_q2": 0.2}
    for k, val in truth.items():
        assert p[k] == pytest.approx(val, rel=0.1), k
    assert cpl.validation["rmse"] < 0.3 * nom.validation["rmse"]


def test_energy_algorithm6_small():
    """Sec. 9.5 setting (Table 9.1), 3 realizations, initial guesses U(0, 3x)."""
    truth = np.array([5.0, 15.0, -0.5, 600.0])
    errs = []
    for r in range(3):
        rng = np.random.default_rng(100 + r)
        t = np.arange(3600.0)
        v = np.repeat(rng.uniform(0.1, 1.0, 360) * rng.choice([-1, 1], 360), 10)
        tau, F, E, W = simulate_energy_system(t, v, 5.0, 15.0, -0.5, 600.0, 0.5, rng)
        m = build_model("energy", v, v, nominal="viscous")
        fit = fit_energy(m, t, v, v, tau, gain0=-0.5 * rng.uniform(0, 3), tau0=600 * rng.uniform(0, 3), n_iter=50)
        p = fit.model.params()
        errs.append(npe([p["kv"], p["kc"], p["ke"], p["tau_e"]], truth))
        assert fit.history[-1]["rmse"] < 0.55
    assert np.median(errs) < 0.05


def test_energy_initial_guess_from_envelope():
    rng = np.random.default_rng(7)
    t = np.arange(3600.0)
    v = np.repeat(rng.uniform(0.1, 1.0, 360) * rng.choice([-1, 1], 360), 10)
    tau, F, E, W = simulate_energy_system(t, v, 5.0, 15.0, -0.5, 600.0, 0.5, rng)
    g = initial_guess(t, v, tau)
    assert g["gain"] == pytest.approx(-0.5, rel=0.3)
    assert g["time_constant"] == pytest.approx(600, rel=0.4)


def test_roundtrip_dict(position_data):
    t, q, v, a, y, sigma = position_data
    res = fit_friction(t, q, v, y, model="position", ddq=a, n_position=12, width_factor=1.0)
    m2 = JointFriction.from_dict(res.model.to_dict())
    np.testing.assert_allclose(m2.predict(q[:50], v[:50]), res.model.predict(q[:50], v[:50]))


# ---------------------------------------------------------------- bad input

def test_single_speed_single_direction_is_not_identifiable():
    t = np.arange(500) * 0.01
    v = np.full(500, 0.5)
    q = 0.5 * t
    y = 3 + 0.5 * v
    with pytest.raises(IdentifiabilityError, match="both directions|single speed"):
        fit_friction(t, q, v, y, model="nominal", ddq=np.zeros(500))
    with pytest.raises(IdentifiabilityError, match="single speed"):
        fit_friction(t, q, v * np.sign(np.sin(t * 3)), y, model="nominal", nominal="viscous",
                     ddq=np.zeros(500))


def test_too_few_points_for_basis():
    rng = np.random.default_rng(5)
    t, q, v, a = sweep(rng, duration=8, fs=10)
    y = 3 * np.sign(v) + v
    with pytest.raises(IdentifiabilityError, match="too few samples"):
        fit_friction(t, q, v, y, model="motor", ddq=a, gear_ratio=100.0)


def test_unknown_model_and_missing_gear_ratio():
    with pytest.raises(DrakeEstError, match="unknown friction model"):
        build_model("bogus", np.zeros(3), np.ones(3))
    with pytest.raises(DrakeEstError, match="gear ratio"):
        build_model("motor", np.zeros(3), np.ones(3))


@pytest.mark.benchmark
def test_benchmark_fit_times():
    """Wall time of fits on a 30,000-sample sweep (prints; no timed assertion)."""
    import time
    rng = np.random.default_rng(9)
    t, q, v, a = sweep(rng, duration=300, fs=100)
    y = 2.0 * v + 5.0 * np.sign(v) + np.sin(2 * motor_position(q, 117.0)) + 0.1 * rng.standard_normal(t.size)
    for model, kw in (("nominal", {}), ("position", {}), ("motor", {"gear_ratio": 117.0})):
        t0 = time.perf_counter()
        res = fit_friction(t, q, v, y, model=model, ddq=a, **kw)
        print(f"BENCH fit_friction {model:8s} N={t.size} p={res.model.n_params}: {time.perf_counter() - t0:.2f} s")
    t = np.arange(3600.0)
    v = np.repeat(rng.uniform(0.1, 1.0, 360) * rng.choice([-1, 1], 360), 10)
    tau, *_ = simulate_energy_system(t, v, 5.0, 15.0, -0.5, 600.0, 0.5, rng)
    t0 = time.perf_counter()
    fit_energy(build_model("energy", v, v, nominal="viscous"), t, v, v, tau, n_iter=50)
    print(f"BENCH fit_energy 50 iterations N=3600: {time.perf_counter() - t0:.2f} s")


def test_friction_package_has_no_import_cycle_and_old_names_work():
    """issue #18: friction.py split by idea; energy <-> friction cycle gone; old import paths keep working."""
    import ast
    import pathlib
    import warnings

    import drake_est.identification.friction as fr
    pkg = pathlib.Path(fr.__file__).parent
    graph = {}
    for f in pkg.glob("*.py"):
        mods = set()
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith(
                    "drake_est.identification.friction."):
                mods.add(node.module.rsplit(".", 1)[1])
        graph[f.stem] = mods

    def reaches(a, b, seen=()):
        return any(m == b or (m not in seen and reaches(m, b, seen + (m,))) for m in graph.get(a, ()))
    cyc = [m for m in graph if m != "__init__" and reaches(m, m)]
    assert not cyc, f"import cycle through {cyc}"
    for name in fr.__all__:
        assert hasattr(fr, name)
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        from drake_est.identification.energy import fit_energy as old
    assert old is fr.fit_energy


def test_joint_means_one_based_and_index_is_the_column():
    """issue #18: the 0-based data column is `index`; an old `joint=` still means that column (never
    silently re-read as a joint number) but warns; coupled_joints exists once (1-based)."""
    import warnings

    from drake_est.errors import DataError
    from drake_est.identification.friction import JointFriction
    from drake_est.joints import coupled_joints
    from drake_est.robots import irb140_metadata
    m = JointFriction.coulomb_viscous(2.0, 1.0, index=1, joint_number=2)
    assert m.index == 1 and m.to_dict()["joint"] == 2 and m.to_dict()["index"] == 1
    with pytest.warns(DeprecationWarning, match="index="):
        old = JointFriction.coulomb_viscous(2.0, 1.0, joint=1)
    assert old.index == 1
    with pytest.raises(DataError, match="index= only"):
        JointFriction.coulomb_viscous(2.0, 1.0, joint=1, index=1)
    N = irb140_metadata().motor_from_arm
    assert coupled_joints(N, 6) == [4, 5] and coupled_joints(N, 5) == [4] and coupled_joints(N, 1) == []
    assert coupled_joints(None, 2, [1, 2, 3]) == [1, 3]
    with pytest.raises(DataError, match="joint 7 does not exist"):
        coupled_joints(N, 7)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        from drake_est.identification.friction import coupled_joints as old_cj
        assert old_cj(N, 5) == [3, 4]          # deprecated 0-based form, same answer
