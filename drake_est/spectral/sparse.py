"""Sparse spectral estimation (thesis Sec. 10.2 "Line-spectral estimation", Eq. (10.20)).

Both problems are instances of the group lasso

    minimize_theta  1/2 ||A theta - y||^2 + lam * sum_g ||theta_g||_2

* line-spectral (L1) estimation: the plain spectrum (10.5) with one group per frequency
  holding ``[Re k_w, Im k_w]`` (the L1 norm of the complex coefficients, ``sum |k_w|``);
* group-lasso LPV spectrum (10.20): one group per frequency holding all 2J real
  coefficients ``[Re k_w; Im k_w]`` of its basis expansion, so whole frequencies drop out.

:func:`group_lasso_admm` solves it with ADMM (Parikh and Boyd 2014): the x-update is a ridge
problem solved with one cached Cholesky factorization (of ``A^T A + rho I``, or of
``A A^T + rho I`` with the matrix-inversion lemma when there are more parameters than
samples), the z-update is the group soft threshold, which sets groups exactly to zero.
:func:`group_lasso_drake` writes the same problem as a Drake ``MathematicalProgram``
(quadratic cost, one Lorentz cone per group) and solves it with Clarabel, for cross-checks.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from drake_est.errors import DataError
from drake_est.spectral.lpv import LPVSpectrum
from drake_est.spectral.lssa import _clean_1d, check_frequency_grid


@dataclass
class ADMMResult:
    coef: np.ndarray          # the sparse iterate z (exact zeros in inactive groups)
    iterations: int
    converged: bool
    primal_residual: float
    dual_residual: float
    objective: float


def _groups_array(groups, p):
    groups = np.asarray(groups)
    if groups.shape != (p,):
        raise DataError(f"group labels must have one entry per parameter ({p}), got shape {groups.shape}")
    return groups


def group_lasso_objective(A, y, coef, lam, groups, weights=None) -> float:
    r = A @ coef - y
    labels = np.unique(groups[groups >= 0])
    w = np.ones(labels.size) if weights is None else np.asarray(weights, float)
    pen = sum(wi * np.linalg.norm(coef[groups == g]) for g, wi in zip(labels, w))
    return 0.5 * float(r @ r) + lam * float(pen)


def group_lasso_admm(A, y, lam: float, groups, weights=None, rho: float | None = None, max_iter: int = 5000,
                     eps_abs: float = 1e-8, eps_rel: float = 1e-6, x0=None) -> ADMMResult:
    """Solve ``min 1/2||A x - y||^2 + lam sum_g w_g ||x_g||_2`` by ADMM.

    ``groups``: integer label per column; label ``-1`` marks unpenalized columns.
    ``weights``: per group (in the order of the sorted labels), default 1."""
    A = np.asarray(A, dtype=float)
    y = np.asarray(y, dtype=float).ravel()
    N, p = A.shape
    if y.size != N:
        raise DataError(f"group lasso: A has {N} rows, y has {y.size}")
    if lam < 0:
        raise DataError(f"group-lasso penalty must be >= 0, got {lam}")
    groups = _groups_array(groups, p)
    labels = np.unique(groups[groups >= 0])
    w = np.ones(labels.size) if weights is None else np.asarray(weights, float).ravel()
    if w.size != labels.size:
        raise DataError(f"group weights: {w.size} given for {labels.size} groups")
    members = [np.flatnonzero(groups == g) for g in labels]
    free = np.flatnonzero(groups < 0)
    Aty = A.T @ y
    if rho is None:
        # scale-aware default: the mean squared column norm
        rho = max(float(np.mean(np.sum(A * A, axis=0))), 1e-12)
    if p <= N:
        cf = scipy.linalg.cho_factor(A.T @ A + rho * np.eye(p), check_finite=False)

        def xsolve(q):
            return scipy.linalg.cho_solve(cf, q, check_finite=False)
    else:
        cf = scipy.linalg.cho_factor(A @ A.T + rho * np.eye(N), check_finite=False)

        def xsolve(q):
            return (q - A.T @ scipy.linalg.cho_solve(cf, A @ q, check_finite=False)) / rho

    z = np.zeros(p) if x0 is None else np.asarray(x0, float).copy()
    u = np.zeros(p)
    converged = False
    r_norm = s_norm = np.inf
    it = 0
    for it in range(1, max_iter + 1):
        x = xsolve(Aty + rho * (z - u))
        z_old = z
        v = x + u
        z = np.empty(p)
        z[free] = v[free]
        for idx, wg in zip(members, w):
            vg = v[idx]
            nrm = np.linalg.norm(vg)
            thr = lam * wg / rho
            z[idx] = 0.0 if nrm <= thr else (1.0 - thr / nrm) * vg
        u = u + x - z
        r_norm = float(np.linalg.norm(x - z))
        s_norm = float(rho * np.linalg.norm(z - z_old))
        eps_pri = np.sqrt(p) * eps_abs + eps_rel * max(np.linalg.norm(x), np.linalg.norm(z))
        eps_dual = np.sqrt(p) * eps_abs + eps_rel * rho * np.linalg.norm(u)
        if r_norm <= eps_pri and s_norm <= eps_dual:
            converged = True
            break
    obj = group_lasso_objective(A, y, z, lam, groups, w)
    return ADMMResult(coef=z, iterations=it, converged=converged, primal_residual=r_norm, dual_residual=s_norm,
                      objective=obj)


def group_lasso_drake(A, y, lam: float, groups, weights=None, solver: str = "clarabel"):
    """The same group-lasso problem as a Drake ``MathematicalProgram``: quadratic cost
    ``1/2 x^T A^T A x - (A^T y)^T x`` plus ``lam sum_g w_g t_g`` with Lorentz cones
    ``t_g >= ||x_g||``, solved by Clarabel (or SCS).  Returns the solution vector."""
    from pydrake.solvers import ClarabelSolver, MathematicalProgram, ScsSolver

    A = np.asarray(A, dtype=float)
    y = np.asarray(y, dtype=float).ravel()
    N, p = A.shape
    groups = _groups_array(groups, p)
    labels = np.unique(groups[groups >= 0])
    w = np.ones(labels.size) if weights is None else np.asarray(weights, float).ravel()
    prog = MathematicalProgram()
    x = prog.NewContinuousVariables(p, "x")
    t = prog.NewContinuousVariables(labels.size, "t")
    Q = A.T @ A
    prog.AddQuadraticCost(Q, -(A.T @ y), 0.5 * float(y @ y), x, is_convex=True)
    prog.AddLinearCost(lam * w, 0.0, t)
    for gi, g in enumerate(labels):
        idx = np.flatnonzero(groups == g)
        prog.AddLorentzConeConstraint(np.r_[t[gi], x[idx]])
    s = ClarabelSolver() if solver == "clarabel" else ScsSolver()
    res = s.Solve(prog)
    if not res.is_success():
        raise DataError(f"Drake {solver} failed on the group-lasso problem: {res.get_solution_result()}")
    return res.GetSolution(x)


class SparseLPVSpectrum(LPVSpectrum):
    """LPV spectrum with a sparsity penalty solved by ADMM.

    ``penalty="group"``: group lasso over frequencies (10.20) -- all 2J coefficients of a frequency
    form a group; ``penalty="l1"``: L1 on the complex coefficients, groups ``[Re k_wj, Im k_wj]``
    (with ``n_basis=1`` this is the L1-regularized line spectrum).  ``lam_sparse`` is the penalty
    weight; ``lam_sparse_rel`` (used when ``lam_sparse`` is None) sets it relative to the smallest
    penalty that zeroes every group, ``max_g ||A_g^T y||``.  No covariance is available."""

    def __init__(self, freqs, n_basis: int = 10, lam_sparse: float | None = None, lam_sparse_rel: float = 0.1,
                 penalty: str = "group", sign_split: bool = False, basis=None, width_factor: float = 1.0,
                 max_iter: int = 5000, eps_abs: float = 1e-8, eps_rel: float = 1e-6, rho=None, check_grid=True):
        super().__init__(freqs, n_basis=n_basis, sign_split=sign_split, lam=0.0, basis=basis,
                         width_factor=width_factor, check_grid=check_grid)
        if penalty not in ("group", "l1"):
            raise DataError(f"unknown sparse penalty '{penalty}'; use 'group' or 'l1'")
        self.penalty = penalty
        self.lam_sparse = lam_sparse
        self.lam_sparse_rel = lam_sparse_rel
        self.max_iter, self.eps_abs, self.eps_rel, self.rho = max_iter, eps_abs, eps_rel, rho

    def group_labels(self) -> np.ndarray:
        O, J = self.n_freqs, self.n_basis
        if self.penalty == "group":
            return np.repeat(np.arange(O), 2 * J)
        lab = np.empty((O, 2, J), dtype=int)
        lab[:, 0, :] = np.arange(O * J).reshape(O, J)
        lab[:, 1, :] = lab[:, 0, :]
        return lab.ravel()

    def fit(self, x, y, v=None, base=None):
        from drake_est.spectral.basis import ScheduleBasis

        x = _clean_1d(x, "sample locations")
        y = _clean_1d(y, "signal")
        if y.size != x.size:
            raise DataError(f"signal has {y.size} samples, sample locations {x.size}")
        if self.basis is None:
            self.basis = (ScheduleBasis(1) if self.n_basis == 1 else
                          ScheduleBasis.from_data(v, self.n_basis, sign_split=self.sign_split,
                                                  width_factor=self.width_factor))
        if self.check_grid:
            check_frequency_grid(x, self.freqs)
        A = self.regressor(x, v, base)
        groups = self.group_labels()
        if base is not None:
            groups = np.r_[groups, -np.ones(A.shape[1] - groups.size, dtype=int)]
        labels = np.unique(groups[groups >= 0])
        lam_max = max(np.linalg.norm(A[:, groups == g].T @ y) for g in labels)
        lam = self.lam_sparse if self.lam_sparse is not None else self.lam_sparse_rel * lam_max
        self.lam_sparse_used = float(lam)
        self.lam_sparse_max = float(lam_max)
        res = group_lasso_admm(A, y, lam, groups, rho=self.rho, max_iter=self.max_iter, eps_abs=self.eps_abs,
                               eps_rel=self.eps_rel)
        self.admm = res
        theta = res.coef
        p_spec = self.n_spectral_params
        self.theta = theta
        c = theta[:p_spec].reshape(self.n_freqs, 2, self.n_basis)
        self.coef = c[:, 0, :] + 1j * c[:, 1, :]
        self.base_coef = theta[p_spec:]
        resid = y - A @ theta
        self.rss = float(resid @ resid)
        self.sumsq = float(y @ y)
        self.n_samples = x.size
        self.dof = float(np.count_nonzero(theta))
        self.sigma2 = self.rss / max(x.size - self.dof, 1.0)
        self.solver_used = "admm"
        self._cov_state = None
        return self

    def active_frequencies(self) -> np.ndarray:
        """Grid frequencies whose coefficients are not all exactly zero."""
        return self.freqs[np.any(self.coef != 0, axis=1)]
