"""Model-fit metrics on validation data (definitions as in Johansson, 1993).

All functions take the measured output ``y`` and the model output ``yhat`` of
equal shape ``(N,)`` or ``(N, m)``; multi-output data are treated column-wise
and then averaged (Fit) or pooled (RMSE, MAE, FPE).
"""
from __future__ import annotations

import numpy as np

from drake_est.errors import DrakeEstError


def _pair(y, yhat):
    y = np.asarray(y, dtype=float)
    yhat = np.asarray(yhat, dtype=float)
    if y.shape != yhat.shape:
        raise DrakeEstError(f"metric: y has shape {y.shape} but yhat has shape {yhat.shape}")
    if y.size == 0:
        raise DrakeEstError("metric: no samples")
    return y, yhat


def rmse(y, yhat) -> float:
    """Root-mean-square error sqrt(mean((y - yhat)^2))."""
    y, yhat = _pair(y, yhat)
    return float(np.sqrt(np.mean((y - yhat) ** 2)))


def mae(y, yhat) -> float:
    """Mean absolute error mean(|y - yhat|)."""
    y, yhat = _pair(y, yhat)
    return float(np.mean(np.abs(y - yhat)))


def fit_percent(y, yhat) -> float:
    """Fit (%) = 100 (1 - ||y - yhat|| / ||y - mean(y)||); 100 is perfect, 0 is the mean."""
    y, yhat = _pair(y, yhat)
    y2 = y.reshape(len(y), -1)
    e2 = (y - yhat).reshape(len(y), -1)
    fits = []
    for j in range(y2.shape[1]):
        den = np.linalg.norm(y2[:, j] - y2[:, j].mean())
        fits.append(100.0 * (1.0 - np.linalg.norm(e2[:, j]) / den) if den > 0 else np.nan)
    fits = np.asarray(fits, dtype=float)
    if not np.any(np.isfinite(fits)):
        return float("nan")       # constant targets: Fit is undefined (no RuntimeWarning of nanmean)
    return float(np.nanmean(fits))


def fpe(y, yhat, n_params: int) -> float:
    """Akaike's final prediction error V (1 + d/N) / (1 - d/N), V = mean squared error, d = n_params."""
    y, yhat = _pair(y, yhat)
    n = y.size
    d = int(n_params)
    if d >= n:
        return float("inf")
    v = float(np.mean((y - yhat) ** 2))
    return v * (1.0 + d / n) / (1.0 - d / n)


def npe(estimate, truth) -> float:
    """Normalized parameter error, Eq. (9.28): sqrt(sum(((x_hat - x) / |x|)^2))."""
    estimate = np.asarray(estimate, dtype=float).ravel()
    truth = np.asarray(truth, dtype=float).ravel()
    if estimate.shape != truth.shape:
        raise DrakeEstError(f"npe: estimate has {estimate.size} parameters, truth has {truth.size}")
    if np.any(truth == 0):
        raise DrakeEstError("npe: a true parameter is zero; NPE (9.28) normalizes by |x| and is undefined")
    return float(np.sqrt(np.sum(((estimate - truth) / np.abs(truth)) ** 2)))


def metrics_table(y, yhat, n_params: int) -> dict:
    """All validation metrics in one dict: rmse, mae, fit (%), fpe."""
    return {
        "rmse": rmse(y, yhat),
        "mae": mae(y, yhat),
        "fit": fit_percent(y, yhat),
        "fpe": fpe(y, yhat, n_params),
    }
