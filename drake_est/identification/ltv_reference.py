"""Reference formulations of the LTV problems (7.3)/(7.6) as Drake ``MathematicalProgram`` s (solved with
Clarabel/OSQP); the tests and benchmarks compare the fast solvers against them.

Split out of :mod:`drake_est.identification.ltv`, which re-exports every name."""
from __future__ import annotations

import numpy as np

from drake_est.errors import DataError
from drake_est.identification.ltv_common import _as_regression, _as_state_space, _poly
from drake_est.identification.ltv_lasso import _group_lasso_cost


# =============================================================================================
# MathematicalProgram references (tests and benchmarks)
# =============================================================================================
def _mp_program(Phi, Y, lam, c, kind):
    from pydrake.solvers import MathematicalProgram

    T, m, p = Phi.shape
    r = Y.shape[2]
    d = c.size - 1
    prog = MathematicalProgram()
    k = prog.NewContinuousVariables(T, p * r, "k")          # k[t] = vec of the (p, r) block, column major
    for t in range(T):
        A = np.kron(np.eye(r), Phi[t])
        prog.Add2NormSquaredCost(A, Y[t].T.reshape(-1), k[t])
    Dm = np.kron(c[None, :], np.eye(p * r))
    if kind == "squared":
        for t in range(T - d):
            prog.Add2NormSquaredCost(lam * Dm, np.zeros(p * r), k[t:t + d + 1].reshape(-1))
    else:
        s = prog.NewContinuousVariables(T - d, "s")
        prog.AddLinearCost(lam * np.ones(T - d), 0.0, s)
        A = np.zeros((1 + p * r, 1 + (d + 1) * p * r))
        A[0, 0] = 1.0
        A[1:, 1:] = Dm
        for t in range(T - d):
            prog.AddLorentzConeConstraint(A, np.zeros(1 + p * r), np.concatenate([[s[t]], k[t:t + d + 1].reshape(-1)]))
    return prog, k


def _mp_solve(prog, k, solver, T, p, r, tight=True):
    """Solve with tight tolerances (reference accuracy) or the solver's defaults (``tight=False``)."""
    from pydrake.solvers import ClarabelSolver, OsqpSolver, ScsSolver, SolverOptions

    opts = SolverOptions()
    if solver == "clarabel":
        s = ClarabelSolver()
        if tight:
            for name in ("tol_gap_abs", "tol_gap_rel", "tol_feas", "tol_ktratio"):
                opts.SetOption(s.solver_id(), name, 1e-10)
    elif solver == "osqp":
        s = OsqpSolver()
        if tight:
            opts.SetOption(s.solver_id(), "eps_abs", 1e-10)
            opts.SetOption(s.solver_id(), "eps_rel", 1e-10)
            opts.SetOption(s.solver_id(), "max_iter", 200000)
    elif solver == "scs":
        s = ScsSolver()
    else:
        raise DataError(f"solver must be 'clarabel', 'osqp' or 'scs', got {solver!r}")
    result = s.Solve(prog, None, opts)
    if not result.is_success():
        raise DataError(f"{solver} did not solve the reference program: {result.get_solution_result()}")
    kk = result.GetSolution(k).reshape(T, r, p)
    return np.swapaxes(kk, 1, 2), result


def tv_regression_qp_reference(Phi, y, lam, order=1, P=None, solver="clarabel", return_program=False):
    """(7.3)/(7.5)/(7.13) written as a QP in Drake's ``MathematicalProgram`` (reference solution)."""
    Phi, Y = _as_regression(Phi, y)
    prog, k = _mp_program(Phi, Y, float(lam), _poly(order, P), "squared")
    kk, res = _mp_solve(prog, k, solver, Phi.shape[0], Phi.shape[2], 1)
    return (kk[:, :, 0], prog) if return_program else kk[:, :, 0]


def tv_regression_group_lasso_reference(Phi, y, lam, order=1, P=None, solver="clarabel"):
    """(7.6)/(7.9) in ``MathematicalProgram`` with second-order cones (Clarabel or SCS through Drake).
    Returns (k, cost)."""
    Phi, Y = _as_regression(Phi, y)
    c = _poly(order, P)
    prog, k = _mp_program(Phi, Y, float(lam), c, "lasso")
    kk, res = _mp_solve(prog, k, solver, Phi.shape[0], Phi.shape[2], 1)
    G = np.einsum("tmi,tmj->tij", Phi, Phi)
    Bt = np.einsum("tmi,tmr->tir", Phi, Y)
    return kk[:, :, 0], _group_lasso_cost(G, Bt, float(np.sum(Y * Y)), kk, c, float(lam))


def ltv_qp_reference(x, u, lam, order=1, y=None, solver="clarabel", tight=True):
    """(7.3)/(7.5) for the state-space model as a ``MathematicalProgram`` QP; returns (A, B).
    ``tight=False`` keeps the solver's default tolerances (what the benchmark times)."""
    phi, Yn, n, m, _ = _as_state_space(x, u, y)
    prog, k = _mp_program(phi[:, None, :], Yn[:, None, :], float(lam), _poly(order), "squared")
    kk, _ = _mp_solve(prog, k, solver, phi.shape[0], phi.shape[1], n, tight)
    AB = np.swapaxes(kk, 1, 2)
    return AB[:, :, :n], AB[:, :, n:]


def ltv_group_lasso_reference(x, u, lam, order=1, y=None, solver="clarabel"):
    """(7.6)/(7.9) for the state-space model in ``MathematicalProgram``; returns (A, B, cost)."""
    phi, Yn, n, m, _ = _as_state_space(x, u, y)
    Phi, Y = phi[:, None, :], Yn[:, None, :]
    c = _poly(order)
    prog, k = _mp_program(Phi, Y, float(lam), c, "lasso")
    kk, _ = _mp_solve(prog, k, solver, phi.shape[0], phi.shape[1], n)
    G = np.einsum("tmi,tmj->tij", Phi, Phi)
    Bt = np.einsum("tmi,tmr->tir", Phi, Y)
    cost = _group_lasso_cost(G, Bt, float(np.sum(Y * Y)), kk, c, float(lam))
    AB = np.swapaxes(kk, 1, 2)
    return AB[:, :, :n], AB[:, :, n:], cost
