"""Interval regression of quantized readings (quantization.interval_fit, interval_loglik): least squares on a torque
rounded by a coarse ADC is biased when the noise before the ADC is small against its step; the likelihood of the
readings themselves is not.  The diagnosis' check built on it (core.gain_within_rounding, kept in the thirty-ninth
round) is tested in tests/test_diagnose_gain_within_rounding.py."""
import numpy as np
import pytest
import scipy.stats

from drake_est.diagnose.quantization import interval_fit, interval_loglik


def _staircase(n=4000, seed=0, noise=0.03, step=0.25):
    """A friction line kc + kv v over slow speeds, read by an ADC of ``step`` after Gaussian noise ``noise``."""
    rng = np.random.default_rng(seed)
    v = rng.uniform(0.0, 0.3, n)
    X = np.column_stack([np.ones(n), v])
    y = X @ np.array([3.7, 0.6]) + rng.normal(0.0, noise, n)
    return X, step * np.round(y / step), step


def test_interval_fit_is_unbiased_where_least_squares_on_the_rounded_values_is_not():
    X, yq, step = _staircase()
    ols = np.linalg.lstsq(X, yq, rcond=None)[0]
    coef, sigma = interval_fit(X, yq - step / 2, yq + step / 2)
    assert abs(ols[1] - 0.6) > 0.1                  # the rounding bends the least-squares slope
    assert abs(coef[1] - 0.6) < 0.05 and abs(coef[0] - 3.7) < 0.01
    assert 0.02 < sigma < 0.04                       # the noise before the ADC, not the rounding error


def test_interval_fit_with_fine_steps_is_least_squares():
    X, yq, step = _staircase(noise=0.05, step=1e-4)
    ols = np.linalg.lstsq(X, yq, rcond=None)[0]
    coef, sigma = interval_fit(X, yq - step / 2, yq + step / 2)
    assert np.allclose(coef, ols, atol=1e-3)
    assert sigma == pytest.approx(np.std(yq - X @ ols), rel=0.02)


def test_interval_loglik_is_the_probability_of_the_interval_also_far_in_the_tails():
    X = np.array([[1.0], [1.0], [1.0]])
    lo, hi = np.array([-0.5, 40.0, -41.0]), np.array([0.5, 41.0, -40.0])
    ll = interval_loglik(X, [0.0], 1.0, lo, hi)
    assert ll[0] == pytest.approx(np.log(scipy.stats.norm.cdf(0.5) - scipy.stats.norm.cdf(-0.5)))
    # 40 standard deviations out: finite, and the two tails agree
    assert np.all(np.isfinite(ll)) and ll[1] == pytest.approx(ll[2]) and ll[1] < -790


def test_interval_fit_keeps_the_bounded_columns_nonnegative():
    X, yq, step = _staircase()
    coef, _ = interval_fit(X, -(yq + step / 2), -(yq - step / 2), nonneg=[1])     # a falling line: kv held at 0
    assert coef[1] == 0.0 and coef[0] < 0
    coef, _ = interval_fit(X, yq - step / 2, yq + step / 2, nonneg=[1])
    assert abs(coef[1] - 0.6) < 0.05


def test_interval_fit_of_a_nested_model_started_at_the_smaller_one_is_no_worse():
    # a misfit far larger than the step, whose least-squares slope is negative (loop spec 6215's case: the fit once
    # ended far off, below the smaller model, after an overflow at a far trial point of the line search)
    from drake_est.diagnose.quantization import interval_nll_at
    rng = np.random.default_rng(3)
    n = 3000
    v = rng.uniform(-1.0, 1.0, n)
    y = 3.0 * np.sign(v) - 2.0 * v + 0.8 * np.sin(9.0 * v) + rng.normal(0.0, 0.5, n)
    step = 0.15
    yq = step * np.round(y / step)
    X0 = np.column_stack([v, np.sign(v)])
    X1 = np.column_stack([X0, np.sin(9.0 * v), np.cos(9.0 * v)])
    c0, s0 = interval_fit(X0, yq - step / 2, yq + step / 2, nonneg=[0])
    assert c0[0] == 0.0 and np.isfinite(s0)
    c1, s1 = interval_fit(X1, yq - step / 2, yq + step / 2, coef0=np.r_[c0, 0.0, 0.0], sigma0=s0, nonneg=[0])
    nll0 = interval_nll_at(X0, c0, s0, yq - step / 2, yq + step / 2)
    nll1 = interval_nll_at(X1, c1, s1, yq - step / 2, yq + step / 2)
    assert nll1 <= nll0 and abs(c1[2] - 0.8) < 0.1 and s1 < s0


def test_interval_fit_with_a_ridge_and_fine_steps_is_ridge_least_squares():
    # the penalty sum(w coef^2) / (2 sigma^2) is the least-squares ridge as a Gaussian prior: with steps far below the
    # noise its optimum solves (X'X + diag(w)) coef = X'y, and an unpenalized column (w = 0) is left free
    rng = np.random.default_rng(5)
    n = 2000
    X = np.column_stack([np.ones(n), rng.normal(size=n), rng.normal(size=n)])
    y = X @ np.array([1.0, 0.5, -0.3]) + rng.normal(0.0, 0.2, n)
    step = 1e-5
    yq = step * np.round(y / step)
    w = np.array([0.0, 300.0, 3000.0])
    coef, _ = interval_fit(X, yq - step / 2, yq + step / 2, ridge=w)
    expect = np.linalg.solve(X.T @ X + np.diag(w), X.T @ yq)
    assert np.allclose(coef, expect, atol=2e-4)
    assert abs(coef[2]) < 0.2 and abs(coef[2] - expect[2]) < 2e-4      # shrunk from -0.3 by its weight


def test_interval_fit_refuses_bad_intervals():
    X, yq, step = _staircase(n=50)
    with pytest.raises(ValueError, match="hi > lo"):
        interval_fit(X, yq + step, yq)
    with pytest.raises(ValueError, match="one row per interval"):
        interval_fit(X, yq[:-1] - step, yq[:-1] + step)
