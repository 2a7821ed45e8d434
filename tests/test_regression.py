"""The one regression core (drake_est.regression) against verbatim copies of the four solvers it replaced.

The copies below are the pre-#18 implementations (bfe.ridge_fit/cv_error, identification.friction
ridge_cv/_gram_ridge, cases._ridge.ridge_cv_grid, diagnose.core._ridge_lstsq), kept here only to pin
that the switch changed no result by more than 1e-8."""
import numpy as np
import pytest
import scipy.linalg

from drake_est import regression as reg
from drake_est.errors import DrakeEstError, IdentifiabilityError


# ----------------------------------------------------------------- old implementations (reference only)
def _old_gram_ridge(G, b, lam, pen):
    p = G.shape[0]
    jitter = 1e-10 * max(float(np.trace(G)) / max(p, 1), 1e-300)
    H = G + np.diag(lam * pen + jitter)
    return scipy.linalg.cho_solve(scipy.linalg.cho_factor(H, lower=True, check_finite=False), b, check_finite=False)


def _old_friction_ridge_cv(A, y, lams, pen, folds=5):
    n = A.shape[0]
    edges = np.linspace(0, n, folds + 1).astype(int)
    G, b = A.T @ A, A.T @ y
    scores = np.zeros(len(lams))
    for i in range(folds):
        sl = slice(edges[i], edges[i + 1])
        Ak, yk = A[sl], y[sl]
        Gt, bt = G - Ak.T @ Ak, b - Ak.T @ yk
        for li, lam in enumerate(lams):
            r = yk - Ak @ _old_gram_ridge(Gt, bt, lam, pen)
            scores[li] += float(r @ r)
    return scores / n


def _old_ridge_cv_grid(A, y, pen, lams, folds=5):
    n, p = A.shape
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    As = A / scale
    G, b = As.T @ As, As.T @ y
    edges = np.linspace(0, n, folds + 1).astype(int)
    sse = np.zeros(len(lams))
    for i in range(folds):
        sl = slice(edges[i], edges[i + 1])
        At, yt = As[sl], y[sl]
        Gt, bt = G - At.T @ At, b - At.T @ yt
        for k, lam in enumerate(lams):
            M = Gt + np.diag(lam * pen / scale**2)
            M[np.diag_indices(p)] += 1e-12 * np.trace(Gt) / p
            c = scipy.linalg.cho_solve(scipy.linalg.cho_factor(M), bt)
            sse[k] += float(np.sum((yt - At @ c) ** 2))
    return sse / n


def _old_ridge_lstsq(A, y, penalize, RIDGE=1e-4):
    p = A.shape[1]
    mask = np.arange(p) >= penalize if isinstance(penalize, int) else np.asarray(penalize, bool)
    if not mask.any():
        return np.linalg.lstsq(A, y, rcond=None)[0]
    w = np.sqrt(RIDGE * np.maximum(np.sum(A[:, mask] ** 2, axis=0), 1e-300))
    R = np.zeros((int(mask.sum()), p))
    R[np.arange(int(mask.sum())), np.flatnonzero(mask)] = w
    return np.linalg.lstsq(np.vstack([A, R]), np.concatenate([y, np.zeros(R.shape[0])]), rcond=None)[0]


def _old_ridge_fit_coef(A, y, lam, pen):
    p = A.shape[1]
    d = np.ones(p) if pen is None else np.asarray(pen, float)
    Aa = np.vstack([A, np.sqrt(lam) * np.diag(d)]) if lam > 0 else A
    ya = np.concatenate([y, np.zeros(p)]) if lam > 0 else y
    return scipy.linalg.lstsq(Aa, ya, lapack_driver="gelsd")[0]


# ----------------------------------------------------------------- fixed data
@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(7)
    n = 600
    t = np.linspace(0, 10, n)
    v = np.sin(t) + 0.3 * rng.standard_normal(n)
    base = np.c_[v, np.sign(v)]
    centers = np.linspace(-1.5, 1.5, 12)
    Phi = np.exp(-((v[:, None] - centers) ** 2) / 0.1) * np.array([1.0, 30.0] * 6)  # mixed scales
    A = np.hstack([base, Phi])
    y = A @ rng.standard_normal(A.shape[1]) + 0.1 * rng.standard_normal(n)
    pen = np.r_[0.0, 0.0, np.ones(12)]
    return A, y, pen


def test_gram_cv_matches_old_friction_ridge_cv(data):
    A, y, pen = data
    lams = np.logspace(-6, 2, 9) * A.shape[0]
    np.testing.assert_allclose(reg.ridge_cv(A, y, lams, pen), _old_friction_ridge_cv(A, y, lams, pen),
                               rtol=1e-8, atol=0)


def test_scaled_gram_cv_matches_old_case_ridge(data):
    A, y, pen = data
    lams = np.logspace(-4, 3, 8)
    new = reg.ridge_cv(A, y, lams, pen, scale_columns=True, rel_jitter=1e-12)
    np.testing.assert_allclose(new, _old_ridge_cv_grid(A, y, pen, lams), rtol=1e-8, atol=0)
    from drake_est.cases._ridge import ridge_cv_grid
    np.testing.assert_allclose(ridge_cv_grid(A, y, pen, lams), new, rtol=1e-12, atol=0)


def test_column_scaled_solve_matches_old_diagnosis_ridge(data):
    A, y, pen = data
    np.testing.assert_allclose(reg.ridge_solve(A, y, 1e-4, pen, column_scaled=True),
                               _old_ridge_lstsq(A, y, 2), rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(reg.ridge_solve(A, y, 1e-4, np.zeros(A.shape[1]), column_scaled=True),
                               _old_ridge_lstsq(A, y, np.zeros(A.shape[1], bool)), rtol=1e-8, atol=1e-10)


def test_normal_equation_solve_matches_svd_and_falls_back(data):
    """ridge_solve(normal_equations=True): the Cholesky path equals the SVD (gelsd) path on a well-posed system,
    for one and for several right-hand sides; with two identical unpenalized columns the scaled factor is singular
    and the SVD's minimum-norm answer comes back (the normal equations would not give it)."""
    A, y, pen = data
    for yy in (y, np.column_stack([y, 2 * y + 1])):
        np.testing.assert_allclose(reg.ridge_solve(A, yy, 1e-4, pen, column_scaled=True, normal_equations=True),
                                   reg.ridge_solve(A, yy, 1e-4, pen, column_scaled=True), rtol=1e-7, atol=1e-9)
    assert reg._normal_solve(A, y, reg._weights(A, 1e-4, pen, True)) is not None
    Ad = np.column_stack([A[:, :1], A])                 # column 0 twice, both unpenalized
    pd = np.concatenate([[0.0], pen])
    assert reg._normal_solve(Ad, y, reg._weights(Ad, 1e-4, pd, True)) is None
    k = reg.ridge_solve(Ad, y, 1e-4, pd, column_scaled=True, normal_equations=True)
    np.testing.assert_array_equal(k, reg.ridge_solve(Ad, y, 1e-4, pd, column_scaled=True))
    assert k[0] == pytest.approx(k[1], rel=1e-6)        # the minimum-norm split of the shared coefficient


def test_svd_ridge_and_cv_match_old(data):
    A, y, pen = data
    for lam in (0.0, 1e-3, 10.0):
        fit = reg.ridge_fit(A, y, lam, pen)
        np.testing.assert_allclose(fit.coef, _old_ridge_fit_coef(A, y, lam, pen), rtol=1e-8, atol=1e-10)
        if lam > 0:
            np.testing.assert_allclose(reg.ridge_solve(A, y, lam, pen), fit.coef, rtol=1e-7, atol=1e-9)
    # the Gram CV and the SVD-refit CV are the same objective
    lams = [1e-2, 1.0, 100.0]
    np.testing.assert_allclose(reg.ridge_cv(A, y, lams, pen), [reg.cv_error(A, y, l, pen) for l in lams],
                               rtol=1e-4)  # Cholesky vs SVD on mixed-scale columns


def test_ridge_dof_and_limits(data):
    A, y, pen = data
    p = A.shape[1]
    assert reg.ridge_fit(A, y, 0.0).dof == p
    d_small, d_big = reg.ridge_fit(A, y, 1e-8, pen).dof, reg.ridge_fit(A, y, 1e8, pen).dof
    assert d_small == pytest.approx(p, rel=1e-3)
    assert d_big == pytest.approx(2, abs=1e-2)          # only the two unpenalized columns remain
    G = A.T @ A
    assert reg.ridge_gram_dof(G, 1.0, pen) == pytest.approx(reg.ridge_fit(A, y, 1.0, pen).dof, rel=1e-6)


def test_bad_input_errors(data):
    A, y, pen = data
    with pytest.raises(DrakeEstError, match="penalize mask has 3 entries"):
        reg.ridge_fit(A, y, 1.0, [1, 0, 1])
    with pytest.raises(DrakeEstError, match="NaN"):
        reg.ridge_fit(np.where(np.eye(*A.shape) > 0, np.nan, A), y, 1.0)
    B = np.c_[A[:, 0], 2 * A[:, 0]]
    with pytest.raises(IdentifiabilityError, match="linearly dependent"):
        reg.check_excitation(B, ["a", "b"])


def test_old_names_still_importable():
    from drake_est.bfe import RidgeFit, check_excitation, cv_error, ridge_fit, select_ridge  # noqa: F401
    from drake_est.identification.friction import ridge_cv  # noqa: F401
    assert ridge_fit is reg.ridge_fit and cv_error is reg.cv_error
