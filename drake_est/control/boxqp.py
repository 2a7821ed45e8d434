"""Box-constrained quadratic program by projected Newton (Tassa, Mansard and Todorov 2014).

Solves ``min_x 0.5 x^T H x + g^T x  s.t.  lower <= x <= upper`` as used in the control-limited
iLQR backward pass (thesis Sec. 11.2: "to incorporate control signal bounds, we employ a variant of iLQR
due to Tassa et al. (2014)").  Each iteration splits the variables into *clamped* (on a bound with the
gradient pushing outwards) and *free*, takes a Newton step in the free subspace (Cholesky of ``H_ff``),
and runs an Armijo line search along the projected path.  The Cholesky factor of the final free block is
returned: the backward pass needs it for the feedback gain ``K_f = -H_ff^{-1} Q_{u_f x}``.

Pure numpy; :mod:`drake_est.control.kernels` has a numba twin (same iterates, tested to 1e-10).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# result codes (shared with the numba kernel)
HESSIAN_NOT_PD = -1
NO_DESCENT = 0
MAX_ITER = 1
SMALL_IMPROVEMENT = 2
SMALL_GRADIENT = 3
ALL_CLAMPED = 4

_ARMIJO = 0.1
_STEP_DEC = 0.6
_MIN_STEP = 1e-22
_MIN_GRAD = 1e-8
_MIN_REL_IMPROVE = 1e-8


@dataclass
class BoxQPResult:
    """x: solution; free: bool mask of unclamped variables; L: lower Cholesky factor of H[free][:, free]
    (m x m array, only the leading nf x nf block is meaningful); status: one of the result codes."""
    x: np.ndarray
    free: np.ndarray
    L: np.ndarray
    status: int
    iterations: int


def _qp_value(H, g, x):
    return float(x @ g + 0.5 * x @ H @ x)


def boxqp(H, g, lower, upper, x0=None, max_iter=100):
    """Projected-Newton box QP (Tassa et al. 2014, Algorithm 1 of "Control-limited DDP").

    ``H`` (m, m) symmetric, ``g`` (m,), ``lower``/``upper`` (m,) with lower <= upper (may be +-inf),
    ``x0`` warm start (clamped into the box).  Returns :class:`BoxQPResult`; ``status == -1`` when the free
    block of ``H`` is not positive definite (the iLQR caller then raises its regularization)."""
    H = np.asarray(H, float)
    g = np.asarray(g, float)
    lower = np.asarray(lower, float)
    upper = np.asarray(upper, float)
    m = g.shape[0]
    x = np.zeros(m) if x0 is None else np.asarray(x0, float).copy()
    x = np.minimum(np.maximum(x, lower), upper)
    L = np.zeros((m, m))
    free = np.ones(m, bool)
    old_free = np.zeros(m, bool)
    first = True
    value = _qp_value(H, g, x)
    status = MAX_ITER
    it = 0
    for it in range(1, max_iter + 1):
        grad = g + H @ x
        clamped = ((x == lower) & (grad > 0)) | ((x == upper) & (grad < 0))
        free = ~clamped
        if not free.any():
            status = ALL_CLAMPED
            break
        if first or np.any(free != old_free):
            Hff = H[np.ix_(free, free)]
            try:
                Lf = np.linalg.cholesky(Hff)
            except np.linalg.LinAlgError:
                status = HESSIAN_NOT_PD
                break
            L[:] = 0.0
            nf = int(free.sum())
            L[:nf, :nf] = Lf
        first = False
        old_free = free
        gnorm = np.sqrt(np.sum(grad[free] ** 2))
        if gnorm < _MIN_GRAD:
            status = SMALL_GRADIENT
            break
        nf = int(free.sum())
        Lf = L[:nf, :nf]
        # Newton step on the free variables with the clamped ones fixed
        gf = g[free] + H[np.ix_(free, clamped)] @ x[clamped]
        z = np.linalg.solve(Lf, gf)
        xf_new = -np.linalg.solve(Lf.T, z)
        dx = np.zeros(m)
        dx[free] = xf_new - x[free]
        sdotg = float(dx @ grad)
        if sdotg >= 0:
            status = NO_DESCENT
            break
        step = 1.0
        xc = np.minimum(np.maximum(x + step * dx, lower), upper)
        vc = _qp_value(H, g, xc)
        while (vc - value) / (step * sdotg) < _ARMIJO:
            step *= _STEP_DEC
            xc = np.minimum(np.maximum(x + step * dx, lower), upper)
            vc = _qp_value(H, g, xc)
            if step < _MIN_STEP:
                break
        if step < _MIN_STEP:
            status = NO_DESCENT
            break
        improve = value - vc
        x = xc
        old_value = value
        value = vc
        if improve < _MIN_REL_IMPROVE * abs(old_value):
            status = SMALL_IMPROVEMENT
            break
    return BoxQPResult(x, free, L, status, it)
