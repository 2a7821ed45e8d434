"""The candidates' trial fits by the normal equations (core.InnerFits) equal least squares on the rows."""
import numpy as np

from drake_est.diagnose.core import InnerFits, _lstsq_kv


def _problem(seed=0, n=3000, p=5, k=3):
    rng = np.random.default_rng(seed)
    v = rng.uniform(-1, 1, n)
    X = np.column_stack([v, np.sign(v)] + [rng.standard_normal(n) for _ in range(p - 2)])
    C = rng.standard_normal((n, k))
    y = X @ rng.standard_normal(p) + C @ rng.standard_normal(k) + 0.1 * rng.standard_normal(n)
    a = rng.uniform(size=n) < 0.5
    return X, C, y, a, ~a


def _reference(X, C, y, a, b, nonneg):
    A = np.hstack([X, C])
    c = _lstsq_kv(A[a], y[a], nonneg)
    e = y[b] - A[b] @ c
    return float(e @ e), c


def test_inner_fits_equal_least_squares():
    X, C, y, a, b = _problem()
    f = InnerFits(X, y, a, b, nonneg=(0,))
    err, c = f.error(C)
    ref_err, ref_c = _reference(X, C, y, a, b, [0])
    np.testing.assert_allclose(c, ref_c, rtol=1e-8, atol=1e-10)
    assert abs(err - ref_err) <= 1e-9 * ref_err
    # training error (error rows = fitted rows)
    g = InnerFits(X, y, a, None, nonneg=(0,))
    err_tr, _ = g.error(C)
    assert abs(err_tr - _reference(X, C, y, a, a, [0])[0]) <= 1e-9 * err_tr


def test_inner_fits_hold_negative_kv_and_nonneg_columns_at_zero():
    X, C, y, a, b = _problem(1)
    y = y - 5.0 * X[:, 0] - 3.0 * C[:, 1]          # kv and C's 2nd coefficient want to be negative
    f = InnerFits(X, y, a, b, nonneg=(0,))
    err, c = f.error(C, nonneg=True)
    ref_err, ref_c = _reference(X, C, y, a, b, [0, X.shape[1], X.shape[1] + 1, X.shape[1] + 2])
    assert c[0] == 0.0 and c[X.shape[1] + 1] == 0.0
    np.testing.assert_allclose(c, ref_c, rtol=1e-8, atol=1e-10)
    assert abs(err - ref_err) <= 1e-9 * ref_err


def test_inner_fits_fall_back_to_least_squares_when_collinear():
    """A candidate column equal to a model column: the scaled Gram matrix is singular, the trial falls back to
    least squares on the rows and gives its error (no failure, no huge coefficients)."""
    X, C, y, a, b = _problem(2)
    C = np.column_stack([C[:, 0], X[:, 2]])
    f = InnerFits(X, y, a, b, nonneg=(0,))
    err, c = f.error(C)
    ref_err, _ = _reference(X, C, y, a, b, [0])
    assert np.all(np.isfinite(c)) and np.max(np.abs(c)) < 1e3
    assert abs(err - ref_err) <= 1e-8 * ref_err
