"""Least squares and total least squares (errors-in-variables) used by the calibration methods."""
from __future__ import annotations

import numpy as np

from drake_est.errors import IdentifiabilityError


def lstsq(A, y):
    """Ordinary least squares (SVD based); returns x, singular values of A."""
    x, _, _, sv = np.linalg.lstsq(A, y, rcond=None)
    return x, sv


def tls(A, y, exact_cols=None):
    """Total least squares for ``A x ~ y`` when A and y both carry noise [Golub & Van Loan, 2012].

    ``exact_cols`` lists columns of A known without error (e.g. bias columns of ones); they are
    handled by the mixed LS-TLS method: a QR factorization separates them, TLS is applied to the
    remainder, and their coefficients follow by back substitution.
    """
    A = np.asarray(A, dtype=float)
    y = np.asarray(y, dtype=float).reshape(-1)
    n = A.shape[1]
    exact = sorted(exact_cols or [])
    noisy = [j for j in range(n) if j not in exact]
    if not exact:
        C = np.column_stack([A, y])
        _, s, Vt = np.linalg.svd(C, full_matrices=False)
        v = Vt[-1]
        if abs(v[-1]) < 1e-12 * np.linalg.norm(v):
            raise IdentifiabilityError("total least squares is not solvable: the data are degenerate "
                                       "(smallest singular vector has no component on the right-hand side)")
        return -v[:n] / v[-1]
    k = len(exact)
    C = np.column_stack([A[:, exact], A[:, noisy], y])
    Q, Rq = np.linalg.qr(C, mode="reduced")
    R11, R12 = Rq[:k, :k], Rq[:k, k:]
    x2 = tls(Rq[k:, k:-1], Rq[k:, -1])
    from scipy.linalg import solve_triangular

    x1 = solve_triangular(R11, R12[:, -1] - R12[:, :-1] @ x2)
    x = np.empty(n)
    x[exact] = x1
    x[noisy] = x2
    return x
