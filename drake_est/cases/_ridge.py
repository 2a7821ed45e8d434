"""Fast K-fold cross-validation of ridge regression over a grid of penalties (case studies).

A thin alias of :func:`drake_est.regression.ridge_cv` with unit-norm column scaling and the
historical jitter of 1e-12 x mean diagonal (results pinned by tests/test_regression.py).
"""
from __future__ import annotations

import numpy as np

from drake_est.regression import ridge_cv


def ridge_cv_grid(A, y, pen, lams, folds: int = 5) -> np.ndarray:
    """Mean squared contiguous-fold CV error for every penalty in ``lams`` (array of len(lams))."""
    return ridge_cv(A, y, lams, pen, folds=folds, scale_columns=True, rel_jitter=1e-12)
