"""Group-lasso solver checks against the MathematicalProgram/Clarabel reference (the timed LTV benchmark and
its targets are in benchmarks/bench_ltv.py: ``python benchmarks/bench_ltv.py --check --json out.json``)."""
import numpy as np
import pytest

from drake_est.identification import ltv


def _piecewise_problem(seed, T, p, m, n_seg, sigma, scale=1.0):
    rng = np.random.default_rng(seed)
    Phi = scale * rng.standard_normal((T, m, p))
    cuts = np.sort(rng.choice(np.arange(1, T), n_seg - 1, replace=False))
    k = np.zeros((T, p))
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, T]):
        k[a:b] = rng.standard_normal(p)
    y = np.einsum("tmp,tp->tm", Phi, k) + sigma * scale * rng.standard_normal((T, m))
    return Phi, y


def _stats(Phi, y):
    Phi = Phi if Phi.ndim == 3 else Phi[:, None, :]
    Y = (y if y.ndim == 2 else y[:, None])[:, :, None]
    return (np.einsum("tmi,tmj->tij", Phi, Phi), np.einsum("tmi,tmr->tir", Phi, Y), float(np.sum(Y * Y)))


@pytest.mark.parametrize("seed,T,p,m,n_seg,sigma,lam,scale", [
    (0, 150, 3, 1, 4, 0.1, 2.0, 1.0),        # few changes
    (1, 120, 2, 2, 3, 0.3, 0.05, 1.0),       # small lam: most differences active
    (2, 200, 4, 1, 5, 0.05, 3e3, 30.0),      # large lam and scaled data: few or no changes
    (3, 90, 1, 2, 2, 0.5, 1e-4, 1e-3),       # tiny scale
])
def test_working_set_solver_reaches_clarabel_optimum_with_certificate(seed, T, p, m, n_seg, sigma, lam, scale):
    Phi, y = _piecewise_problem(seed, T, p, m, n_seg, sigma, scale)
    Phi_in, y_in = (Phi[:, 0], y[:, 0]) if m == 1 else (Phi, y)
    kr, cref = ltv.tv_regression_group_lasso_reference(Phi_in, y_in, lam)
    g = ltv.tv_regression_group_lasso(Phi_in, y_in, lam)
    assert g.converged
    assert abs(g.cost - cref) <= 1e-6 * abs(cref)
    # the relative duality gap is a certificate: never smaller than the true suboptimality
    G, Bt, yy = _stats(Phi, y)
    k, rounds, steps, gap, conv, clean = ltv._gl_active_set(G, Bt, yy, lam)
    cost = ltv._group_lasso_cost(G, Bt, yy, k, ltv._poly(1), lam)
    assert conv and 0 <= gap <= 1e-6
    assert cost - cref <= gap * abs(cost) + 1e-9 * abs(cref)
    # split variable exactly sparse and consistent with k
    assert np.array_equal(g.dk != 0, np.diff(g.k, axis=0) != 0)


def test_working_set_solver_state_space_and_tight_tolerance():
    x, u, y, A, B = ltv.jump_system(T=300, t_switch=150, seed=3)
    Ar, Br, cref = ltv.ltv_group_lasso_reference(x[:-1], u, 10.0, y=y)
    g = ltv.ltv_group_lasso(x[:-1], u, 10.0, y=y, ftol=1e-10)
    assert g.info["converged"]
    assert abs(g.cost - cref) <= 1e-8 * cref
    assert np.max(np.abs(g.A - Ar)) < 1e-4 and np.max(np.abs(g.B - Br)) < 1e-4
    assert abs(ltv.change_points(g.k, n=1)[0] - 150) <= 2


def test_scaled_first_difference_polynomial_and_blocks():
    Phi, y = _piecewise_problem(5, 400, 2, 1, 3, 0.2)
    a = ltv.tv_regression_group_lasso(Phi[:, 0], y[:, 0], 4.0, P=[-2.0, 2.0])
    b = ltv.tv_regression_group_lasso(Phi[:, 0], y[:, 0], 8.0)
    assert abs(a.cost - b.cost) <= 1e-6 * b.cost and np.max(np.abs(a.k - b.k)) < 1e-4
    # block = 4: the same problem on a 4x coarser grid (k constant within blocks)
    blk = ltv.tv_regression_group_lasso(Phi[:, 0], y[:, 0], 8.0, block=4)
    Pb = Phi[:, 0].reshape(100, 4, 2)
    yb = y[:, 0].reshape(100, 4)
    ref = ltv.tv_regression_group_lasso(Pb, yb, 8.0)          # 4 outputs per coarse step
    assert blk.converged and abs(blk.cost - ref.cost) <= 1e-6 * ref.cost
    assert np.max(np.abs(blk.k[::4] - ref.k)) < 1e-4


def test_working_set_gives_up_on_dense_changes_and_admm_takes_over():
    Phi, y = _piecewise_problem(6, 200, 2, 1, 3, 0.5)
    G, Bt, yy = _stats(Phi, y)
    k, rounds, steps, gap, conv, clean = ltv._gl_active_set(G, Bt, yy, 0.05, max_set=5)
    assert not conv and not clean                       # more than 5 change points needed
    k, rounds, steps, gap, conv, clean = ltv._gl_active_set(G, Bt, yy, 0.05)
    assert conv and clean and int(np.sum(np.any(np.diff(k[:, :, 0], axis=0) != 0, axis=1))) > 5
    # state-space drift system (15 parameters per step, changes almost everywhere): ADMM fallback
    x, u, A, B = ltv.drift_system(T=150, seed=2)       # lam = 0.005: 106 of 149 differences active
    phi = np.hstack([x[:-1], u])
    G = np.einsum("ti,tj->tij", phi, phi)
    Bt = np.einsum("ti,tr->tir", phi, x[1:])
    assert not ltv._gl_active_set(G, Bt, float(np.sum(x[1:] ** 2)), 0.005)[5]    # > 100 changes: gives up
    _, _, cref = ltv.ltv_group_lasso_reference(x, u, 0.005)
    g = ltv.ltv_group_lasso(x, u, 0.005)
    assert g.info["converged"] and abs(g.cost - cref) <= 2e-6 * cref      # ADMM stopped by the gap certificate


def test_admm_still_used_for_second_differences_and_explicit_rho():
    x, u, y, A, B = ltv.jump_system(T=120, t_switch=60, seed=1)
    _, _, c2 = ltv.ltv_group_lasso_reference(x[:-1], u, 5.0, order=2, y=y)
    g2 = ltv.ltv_group_lasso(x[:-1], u, 5.0, order=2, y=y, eps_abs=1e-8, eps_rel=1e-7, ftol=1e-9)
    assert abs(g2.cost - c2) <= 1e-4 * c2
    _, _, c1 = ltv.ltv_group_lasso_reference(x[:-1], u, 5.0, y=y)
    g1 = ltv.ltv_group_lasso(x[:-1], u, 5.0, y=y, rho=50.0, eps_abs=1e-8, eps_rel=1e-7, ftol=1e-9)
    assert abs(g1.cost - c1) <= 1e-4 * c1
