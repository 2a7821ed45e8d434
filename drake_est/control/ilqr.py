"""iLQR / DDP trajectory optimization with control bounds and a KL trust region (thesis Sec. 5.1, Ch. 11).

* :func:`ilqr` — iterative LQR (Eqs. (11.1)-(11.10)); ``second_order=True`` adds the second-order dynamics
  terms ``V_x . f_ss`` to Q (full DDP).  Levenberg–Marquardt regularization ``Q_uu + mu I`` (raised when a
  backward pass meets a non-positive-definite Q_uu, lowered after every accepted step), a backtracking line
  search on the feed-forward step ``u = u_hat + alpha k + K (x - x_hat)``, and control bounds handled by the
  box-QP of Tassa et al. (2014) (:mod:`drake_est.control.boxqp`): clamped controls get no feedback.
* :func:`ilqr_kl` — the same on an LTV model with the KL-divergence constraint between consecutive trajectory
  distributions (11.14)-(11.15), solved through its Lagrangian ``c / eta - log p_hat(u|x)`` and a 1-D search
  on the dual variable eta; the controller is the Gaussian p(u|x) = N(K x_bar + k, Q_uu^{-1}) (11.11).
* Derivatives (:class:`Model`): analytic callables (:class:`FunctionModel`), Drake AutoDiffXd of any Drake
  system (:class:`drake_est.control.drake_model.DrakeModel`), or an LTV model ``A_t, B_t`` (:class:`LtvModel`,
  e.g. from :func:`drake_est.identification.ltv.ltv_smoother`).  :class:`drake_est.control.cartpole.CartPoleModel`
  has compiled rollout and derivatives.

The backward pass is a numba kernel (:func:`drake_est.control.kernels.backward_pass_nb`) with the numpy twin
:func:`backward_pass_numpy` (same iterates to 1e-10; ``DRAKE_EST_NO_NUMBA=1`` forces numpy).

Cost convention: ``J = sum_t c(x_t, u_t) + c_T(x_T)``, no factor 1/2 (as in the issue's benchmark).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from drake_est.control import kernels
from drake_est.control.boxqp import HESSIAN_NOT_PD, boxqp
from drake_est.errors import DataError


# =============================================================================================
# costs
# =============================================================================================
class QuadraticCost:
    """c(x, u) = (x - x_ref)^T Q (x - x_ref) + (u - u_ref)^T R (u - u_ref), terminal (x_T - x_ref)^T Qf (..).

    ``x_ref`` (n,) or (T+1, n), ``u_ref`` (m,) or (T, m); Eq. (11.2) is its second-order expansion (exact)."""

    def __init__(self, Q, R, Qf=None, x_ref=None, u_ref=None):
        self.Q = np.atleast_2d(np.asarray(Q, float))
        self.R = np.atleast_2d(np.asarray(R, float))
        self.Qf = self.Q if Qf is None else np.atleast_2d(np.asarray(Qf, float))
        n, m = self.Q.shape[0], self.R.shape[0]
        for name, M, k in (("Q", self.Q, n), ("R", self.R, m), ("Qf", self.Qf, n)):
            if M.shape != (k, k):
                raise DataError(f"cost matrix {name} must be square ({k}x{k}), got {M.shape}")
            if not np.all(np.isfinite(M)):
                raise DataError(f"cost matrix {name} contains NaN/Inf")
            if np.any(np.linalg.eigvalsh(0.5 * (M + M.T)) < -1e-12 * max(1.0, np.abs(M).max())):
                raise DataError(f"cost matrix {name} is not positive semidefinite")
        self.n, self.m = n, m
        self.x_ref = np.zeros(n) if x_ref is None else np.asarray(x_ref, float)
        self.u_ref = np.zeros(m) if u_ref is None else np.asarray(u_ref, float)
        if self.x_ref.shape[-1] != n or self.u_ref.shape[-1] != m:
            raise DataError(f"x_ref must have {n} columns and u_ref {m}")
        self._cache = None

    def _refs(self, T):
        xr = self.x_ref if self.x_ref.ndim == 1 else self.x_ref[: T + 1]
        ur = self.u_ref if self.u_ref.ndim == 1 else self.u_ref[:T]
        if self.x_ref.ndim == 2 and self.x_ref.shape[0] < T + 1:
            raise DataError(f"x_ref has {self.x_ref.shape[0]} rows, the horizon needs {T + 1}")
        if self.u_ref.ndim == 2 and self.u_ref.shape[0] < T:
            raise DataError(f"u_ref has {self.u_ref.shape[0]} rows, the horizon needs {T}")
        return xr, ur

    def stage(self, X, U):
        """Per-step costs (T+1,) (last entry terminal)."""
        T = U.shape[0]
        xr, ur = self._refs(T)
        dx = X - xr
        du = U - ur
        c = np.empty(T + 1)
        c[:T] = np.einsum("ti,ij,tj->t", dx[:T], self.Q, dx[:T]) + np.einsum("ti,ij,tj->t", du, self.R, du)
        c[T] = dx[T] @ self.Qf @ dx[T]
        return c

    def value(self, X, U):
        """Total cost J."""
        T = U.shape[0]
        xr, ur = self._refs(T)
        dx = X - xr
        du = U - ur
        return float(np.sum((dx[:T] @ self.Q) * dx[:T]) + np.sum((du @ self.R) * du) + dx[T] @ self.Qf @ dx[T])

    def derivatives(self, X, U):
        """(lx (T+1,n), lu (T,m), lxx (T+1,n,n), luu (T,m,m), lux (T,m,n))."""
        T = U.shape[0]
        n, m = self.n, self.m
        xr, ur = self._refs(T)
        if self._cache is None or self._cache[0] != T:
            lxx = np.empty((T + 1, n, n))
            lxx[:T] = 2 * self.Q
            lxx[T] = 2 * self.Qf
            luu = np.broadcast_to(2 * self.R, (T, m, m)).copy()
            lux = np.zeros((T, m, n))
            self._cache = (T, lxx, luu, lux)
        _, lxx, luu, lux = self._cache
        dx = X - xr
        lx = np.empty((T + 1, n))
        lx[:T] = 2 * dx[:T] @ self.Q
        lx[T] = 2 * dx[T] @ self.Qf
        lu = 2 * (U - ur) @ self.R
        return lx, lu, lxx, luu, lux


class FunctionCost:
    """A cost from analytic callables: ``stage(t, x, u) -> float``, ``terminal(x) -> float`` and
    ``derivatives(X, U) -> (lx, lu, lxx, luu, lux)`` with the shapes of :meth:`QuadraticCost.derivatives`."""

    def __init__(self, stage, terminal, derivatives):
        self._stage, self._terminal, self._derivatives = stage, terminal, derivatives

    def value(self, X, U):
        return float(sum(self._stage(t, X[t], U[t]) for t in range(U.shape[0])) + self._terminal(X[-1]))

    def derivatives(self, X, U):
        return tuple(np.asarray(a, float) for a in self._derivatives(X, U))


# =============================================================================================
# dynamics models
# =============================================================================================
class Model:
    """Discrete-time dynamics x_{t+1} = f_t(x_t, u_t) with derivatives.

    Subclasses implement :meth:`step` and :meth:`linearize`; :meth:`forward` (closed-loop rollout) has a
    generic Python loop that compiled models override."""
    n: int
    m: int
    has_second_order = False

    def step(self, t, x, u):
        raise NotImplementedError

    def linearize(self, X, U, second_order=False):
        """Returns (fx (T,n,n), fu (T,n,m), fxx (T,n,n,n), fux (T,n,m,n), fuu (T,n,m,m)); the last three may be
        None when ``second_order`` is False or the model has no second derivatives."""
        raise NotImplementedError

    def forward(self, x0, Xn, Un, K, k, alpha, lb, ub):
        """Closed-loop rollout u_t = clip(Un_t + alpha k_t + K_t (x_t - Xn_t), lb_t, ub_t).

        Returns (X, U, ok); ok is False when a state became non-finite (X then holds NaN from there on)."""
        T = Un.shape[0]
        X = np.full((T + 1, self.n), np.nan)
        U = np.zeros((T, self.m))
        X[0] = x0
        for t in range(T):
            u = Un[t] + alpha * k[t] + K[t] @ (X[t] - Xn[t])
            U[t] = np.minimum(np.maximum(u, lb[t]), ub[t])
            xn = np.asarray(self.step(t, X[t], U[t]), float)
            if xn.shape != (self.n,):
                raise DataError(f"dynamics returned shape {xn.shape}, expected ({self.n},)")
            X[t + 1] = xn
            if not np.all(np.isfinite(xn)):
                return X, U, False
        return X, U, True


class FunctionModel(Model):
    """Dynamics from analytic callables: ``f(t, x, u) -> x+``, ``jac(t, x, u) -> (A, B)`` and optionally
    ``hess(t, x, u) -> (fxx (n,n,n), fux (n,m,n), fuu (n,m,m))`` for full DDP."""

    def __init__(self, f, jac, n, m, hess=None):
        self.f, self.jac, self.hess = f, jac, hess
        self.n, self.m = int(n), int(m)
        self.has_second_order = hess is not None

    def step(self, t, x, u):
        return self.f(t, x, u)

    def linearize(self, X, U, second_order=False):
        T = U.shape[0]
        n, m = self.n, self.m
        fx = np.empty((T, n, n))
        fu = np.empty((T, n, m))
        for t in range(T):
            A, B = self.jac(t, X[t], U[t])
            fx[t] = np.reshape(A, (n, n))
            fu[t] = np.reshape(B, (n, m))
        if not (second_order and self.hess is not None):
            return fx, fu, None, None, None
        fxx = np.empty((T, n, n, n))
        fux = np.empty((T, n, m, n))
        fuu = np.empty((T, n, m, m))
        for t in range(T):
            a, b, c = self.hess(t, X[t], U[t])
            fxx[t], fux[t], fuu[t] = a, b, c
        return fx, fu, fxx, fux, fuu


class LtvModel(Model):
    """Linear time-varying model x_{t+1} = A_t x_t + B_t u_t + c_t (Eq. (11.1)); ``A`` (T,n,n), ``B`` (T,n,m),
    ``c`` (T,n) or None.  Build from an identified model with :meth:`from_result`."""

    def __init__(self, A, B, c=None):
        self.A = np.asarray(A, float)
        self.B = np.asarray(B, float)
        if self.A.ndim != 3 or self.B.ndim != 3 or self.A.shape[0] != self.B.shape[0] \
                or self.A.shape[1] != self.A.shape[2] or self.B.shape[1] != self.A.shape[1]:
            raise DataError(f"LTV model needs A (T,n,n) and B (T,n,m), got {self.A.shape} and {self.B.shape}")
        T, self.n = self.A.shape[:2]
        self.m = self.B.shape[2]
        self.c = np.zeros((T, self.n)) if c is None else np.asarray(c, float).reshape(T, self.n)
        for name, a in (("A", self.A), ("B", self.B), ("c", self.c)):
            if not np.all(np.isfinite(a)):
                raise DataError(f"LTV model {name} contains NaN/Inf")
        self.T = T

    @classmethod
    def from_result(cls, res, bias_input=False):
        """From :class:`drake_est.identification.ltv.LtvResult`; ``bias_input``: the last input column of the
        identification was a constant 1, so that column of B is the affine term c_t."""
        if bias_input:
            return cls(res.A, res.B[:, :, :-1], res.B[:, :, -1])
        return cls(res.A, res.B)

    def step(self, t, x, u):
        return self.A[t] @ x + self.B[t] @ u + self.c[t]

    def linearize(self, X, U, second_order=False):
        T = U.shape[0]
        if T > self.T:
            raise DataError(f"the LTV model covers {self.T} steps, the horizon is {T}")
        return self.A[:T], self.B[:T], None, None, None

    def forward(self, x0, Xn, Un, K, k, alpha, lb, ub):
        T = Un.shape[0]
        X = np.empty((T + 1, self.n))
        U = np.empty((T, self.m))
        if kernels.use_numba():
            ok = kernels.ltv_forward_nb(np.asarray(x0, float), Xn, Un, K, k, float(alpha), lb, ub,
                                        self.A, self.B, self.c, X, U)
            return X, U, bool(ok)
        return super().forward(x0, Xn, Un, K, k, alpha, lb, ub)


# =============================================================================================
# backward pass (numpy twin of kernels.backward_pass_nb)
# =============================================================================================
def backward_pass_numpy(fx, fu, fxx, fux, fuu, second_order, lx, lu, lxx, luu, lux, U, lb, ub, mu,
                        k_warm, K, k, Quu_out, free_out, dV):
    """Eqs. (11.3)-(11.8) with the box-QP of Tassa et al. (2014) and regularization ``Q_uu + mu I``.

    Writes K, k, Quu_out (unregularized Q_uu), free_out, dV = (sum k^T Q_u, sum k^T Q_uu k / 2); returns -1 on
    success or the time index where the regularized Q_uu is not positive definite."""
    T, n, _ = fx.shape
    m = fu.shape[2]
    Vx = lx[T].copy()
    Vxx = lxx[T].copy()
    dV[:] = 0.0
    I = np.eye(m)
    for t in range(T - 1, -1, -1):
        A, B = fx[t], fu[t]
        Qx = lx[t] + A.T @ Vx
        Qu = lu[t] + B.T @ Vx
        VA = Vxx @ A
        Qxx = lxx[t] + A.T @ VA
        Quu = luu[t] + B.T @ (Vxx @ B)
        Qux = lux[t] + B.T @ VA
        if second_order:
            Qxx = Qxx + np.tensordot(Vx, fxx[t], axes=1)
            Qux = Qux + np.tensordot(Vx, fux[t], axes=1)
            Quu = Quu + np.tensordot(Vx, fuu[t], axes=1)
        Quu_out[t] = Quu
        Qs = 0.5 * (Quu + Quu.T)
        res = boxqp(Qs + mu * I, Qu, lb[t] - U[t], ub[t] - U[t], x0=k_warm[t])
        if res.status == HESSIAN_NOT_PD:
            return t
        kk = res.x
        free_out[t] = res.free
        k[t] = kk
        K[t] = 0.0
        nf = int(res.free.sum())
        if nf:
            Lf = res.L[:nf, :nf]
            K[t][res.free] = -np.linalg.solve(Lf.T, np.linalg.solve(Lf, Qux[res.free]))
        Kt = K[t]
        Quk = Qs @ kk
        dV[0] += kk @ Qu
        dV[1] += 0.5 * kk @ Quk
        Vx = Qx + Kt.T @ (Quk + Qu) + Qux.T @ kk
        Vn = Qxx + Kt.T @ (Qs @ Kt) + Kt.T @ Qux + Qux.T @ Kt
        Vxx = 0.5 * (Vn + Vn.T)
    return -1


# =============================================================================================
# the solver
# =============================================================================================
@dataclass
class IlqrOptions:
    """Solver settings.  mu: LM regularization of Q_uu (Tassa's schedule: factor ``mu_factor``, floor
    ``mu_min`` below which it is 0, give up above ``mu_max``); ``alphas``: line-search steps; a step is
    accepted when actual/expected reduction > ``z_min``; stop when the relative cost decrease of an accepted
    step is < ``tol_rel`` or the relative feed-forward step is < ``tol_grad``."""
    max_iter: int = 200
    mu_init: float = 0.0
    mu_min: float = 1e-6
    mu_max: float = 1e10
    mu_factor: float = 1.6
    alphas: tuple = tuple(10.0 ** np.linspace(0, -3, 11))
    z_min: float = 0.0
    tol_rel: float = 1e-10
    tol_grad: float = 1e-7
    second_order: bool = False
    numba: bool | None = None


@dataclass
class IlqrResult:
    """Optimized trajectory ``X`` (T+1,n), ``U`` (T,m), feedback ``K`` (T,m,n), last feed-forward step ``k``,
    ``Quu`` (T,m,m) of the last backward pass (controller covariance Q_uu^{-1}, Eq. (11.11)), ``J`` the cost,
    ``costs``/``times`` per accepted iteration (times in s since the start, index 0 = initial rollout),
    ``status`` ("converged", "max_iter", "regularization", "diverged") and a one-line ``message``."""
    X: np.ndarray
    U: np.ndarray
    K: np.ndarray
    k: np.ndarray
    Quu: np.ndarray
    J: float
    iterations: int
    status: str
    message: str
    costs: list = field(default_factory=list)
    times: list = field(default_factory=list)
    free: np.ndarray | None = None
    mu: float = 0.0
    rejected_nonfinite: int = 0

    @property
    def converged(self):
        return self.status == "converged"

    @property
    def diverged(self):
        return self.status == "diverged"

    def controller(self, lower=None, upper=None):
        """The Gaussian controller N(K x_bar + u, Q_uu^{-1}) of Eq. (11.11) along this trajectory."""
        return LinearGaussianController.from_result(self, lower, upper)


def _bounds(lower, upper, T, m):
    lb = np.full((T, m), -np.inf) if lower is None else np.broadcast_to(np.asarray(lower, float), (T, m)).copy() \
        if np.ndim(lower) <= 1 else np.asarray(lower, float)
    ub = np.full((T, m), np.inf) if upper is None else np.broadcast_to(np.asarray(upper, float), (T, m)).copy() \
        if np.ndim(upper) <= 1 else np.asarray(upper, float)
    if lb.shape != (T, m) or ub.shape != (T, m):
        raise DataError(f"bounds lower/upper must be scalars, ({m},) or ({T}, {m}) arrays")
    if np.any(np.isnan(lb)) or np.any(np.isnan(ub)):
        raise DataError("bounds lower/upper contain NaN")
    bad = np.argwhere(lb > ub)
    if bad.size:
        t, i = bad[0]
        raise DataError(f"infeasible bounds: lower > upper for input {i + 1} at step {t} "
                        f"({lb[t, i]:g} > {ub[t, i]:g})")
    return lb, ub


def check_problem(model, cost, x0, U0):
    """Shapes and finiteness of the problem; returns (x0, U0) as float arrays or raises DataError."""
    x0 = np.asarray(x0, float).ravel()
    U0 = np.asarray(U0, float)
    if U0.ndim == 1:
        U0 = U0.reshape(-1, model.m) if model.m > 1 else U0[:, None]
    if U0.ndim != 2 or U0.shape[0] == 0:
        raise DataError(f"horizon must be >= 1: U0 has shape {U0.shape}")
    if U0.shape[1] != model.m:
        raise DataError(f"U0 has {U0.shape[1]} columns, the model has {model.m} inputs")
    if x0.shape[0] != model.n:
        raise DataError(f"x0 has {x0.shape[0]} entries, the model has {model.n} states")
    if not np.all(np.isfinite(x0)):
        raise DataError("x0 contains NaN/Inf")
    if not np.all(np.isfinite(U0)):
        raise DataError("U0 contains NaN/Inf")
    cn, cm = getattr(cost, "n", model.n), getattr(cost, "m", model.m)
    if (cn, cm) != (model.n, model.m):
        raise DataError(f"cost is for {cn} states/{cm} inputs, the model has {model.n}/{model.m}")
    return x0, U0


def _check_finite(arrs, names, what):
    for a, nm in zip(arrs, names):
        if a is not None and not np.all(np.isfinite(a)):
            t = int(np.argwhere(~np.isfinite(a))[0][0])
            raise DataError(f"{what} {nm} is NaN/Inf at step {t}")


def ilqr(model, cost, x0, U0, lower=None, upper=None, options: IlqrOptions | None = None, callback=None,
         **kw):
    """Control-limited iLQR / DDP (thesis Sec. 5.1 and Eqs. (11.1)-(11.10); Tassa et al. 2014 for bounds).

    ``model``: a :class:`Model`; ``cost``: :class:`QuadraticCost` or anything with ``value`` and
    ``derivatives``; ``x0`` (n,); ``U0`` (T, m) initial controls (clipped to the bounds); ``lower``/``upper``
    scalars, (m,) or (T, m).  Keyword arguments override :class:`IlqrOptions` fields.  A non-finite rollout
    during the line search counts as a rejected step; if no finite step is found before the regularization
    exceeds ``mu_max`` the result has ``status == "diverged"`` and holds the last good trajectory.
    Raises :class:`DataError` for bad input and NaN from cost or dynamics at the initial guess."""
    opt = options or IlqrOptions()
    if kw:
        opt = IlqrOptions(**{**opt.__dict__, **kw})
    x0, U0 = check_problem(model, cost, x0, U0)
    T, m, n = U0.shape[0], model.m, model.n
    lb, ub = _bounds(lower, upper, T, m)
    use_nb = kernels.use_numba(opt.numba)
    second = bool(opt.second_order and model.has_second_order)
    t_start = time.perf_counter()

    K = np.zeros((T, m, n))
    k = np.zeros((T, m))
    X, U, ok = model.forward(x0, np.zeros((T + 1, n)), U0, K, k, 0.0, lb, ub)
    if not ok:
        t = int(np.argwhere(~np.all(np.isfinite(X), axis=1))[0][0])
        raise DataError(f"dynamics returned NaN/Inf at step {t - 1} of the initial rollout")
    J = float(cost.value(X, U))
    if not np.isfinite(J):
        raise DataError("cost returned NaN/Inf on the initial rollout")
    costs, times = [J], [time.perf_counter() - t_start]
    Knew = np.zeros((T, m, n))
    knew = np.zeros((T, m))
    Quu = np.zeros((T, m, m))
    free = np.ones((T, m), bool)
    dV = np.zeros(2)
    mu, dmu = opt.mu_init, 1.0
    f = opt.mu_factor
    status, message = "max_iter", f"stopped after {opt.max_iter} iterations"
    need_derivs = True
    rejected_nonfinite = 0
    it = 0
    dummy4 = np.zeros((T, n, 1, 1))
    for it in range(1, opt.max_iter + 1):
        if need_derivs:
            fx, fu, fxx, fux, fuu = model.linearize(X, U, second)
            _check_finite((fx, fu), ("fx", "fu"), "dynamics Jacobian")
            lx, lu, lxx, luu, lux = cost.derivatives(X, U)
            _check_finite((lx, lu, lxx, luu, lux), ("lx", "lu", "lxx", "luu", "lux"), "cost derivative")
            if second and fxx is not None:
                _check_finite((fxx, fux, fuu), ("fxx", "fux", "fuu"), "dynamics second derivative")
                sfxx, sfux, sfuu = fxx, fux, fuu
            else:
                sfxx = sfux = sfuu = dummy4
            need_derivs = False
        # ---- backward pass, raising mu until Q_uu is positive definite
        while True:
            if use_nb:
                fail = kernels.backward_pass_nb(fx, fu, sfxx, sfux, sfuu, second and fxx is not None, lx, lu,
                                                lxx, luu, lux, U, lb, ub, mu, k, Knew, knew, Quu, free, dV)
            else:
                fail = backward_pass_numpy(fx, fu, sfxx, sfux, sfuu, second and fxx is not None, lx, lu, lxx,
                                           luu, lux, U, lb, ub, mu, k, Knew, knew, Quu, free, dV)
            if fail < 0:
                break
            dmu = max(dmu * f, f)
            mu = max(mu * dmu, opt.mu_min)
            if mu > opt.mu_max:
                break
        if mu > opt.mu_max:
            status, message = "regularization", f"Q_uu not positive definite even with mu = {opt.mu_max:g}"
            break
        K, k = Knew.copy(), knew.copy()
        gnorm = float(np.mean(np.max(np.abs(k) / (np.abs(U) + 1.0), axis=1)))
        if gnorm < opt.tol_grad and mu < 1e-5:
            status, message = "converged", f"feed-forward step below {opt.tol_grad:g} after {it} iterations"
            costs.append(J)
            times.append(time.perf_counter() - t_start)
            break
        # ---- forward pass with backtracking on alpha
        accepted = False
        for alpha in opt.alphas:
            Xn, Un, ok = model.forward(x0, X, U, K, k, alpha, lb, ub)
            if not ok:
                rejected_nonfinite += 1
                continue
            Jn = float(cost.value(Xn, Un))
            if not np.isfinite(Jn):
                rejected_nonfinite += 1
                continue
            expected = -alpha * (dV[0] + alpha * dV[1])
            dJ = J - Jn
            z = dJ / expected if expected > 0 else np.sign(dJ)
            if z > opt.z_min:
                accepted = True
                break
        if accepted:
            dmu = min(dmu / f, 1.0 / f)
            mu = mu * dmu if mu * dmu > opt.mu_min else 0.0
            X, U, J = Xn, Un, Jn
            need_derivs = True
            costs.append(J)
            times.append(time.perf_counter() - t_start)
            if callback is not None:
                callback(it, X, U, J)
            if dJ < opt.tol_rel * abs(J):
                status, message = "converged", f"relative cost decrease below {opt.tol_rel:g} after {it} iterations"
                break
        else:
            dmu = max(dmu * f, f)
            mu = max(mu * dmu, opt.mu_min)
            if mu > opt.mu_max:
                if rejected_nonfinite:
                    status = "diverged"
                    message = (f"diverged: every line-search step gave NaN/Inf ({rejected_nonfinite} rejected); "
                               f"returning the last good trajectory (J = {J:.6g})")
                else:
                    status, message = "regularization", f"no cost decrease even with mu = {opt.mu_max:g}"
                break
    return IlqrResult(X, U, K, k, Quu, J, it, status, message, costs, times, free, mu, rejected_nonfinite)


# =============================================================================================
# Gaussian controller (11.11) and the KL trust region (11.14)-(11.15)
# =============================================================================================
@dataclass
class LinearGaussianController:
    """p(u_t | x_t) = N(u_nom_t + K_t (x_t - x_nom_t), cov_t) (Eq. (11.11)), actions clipped to the bounds."""
    x_nom: np.ndarray
    u_nom: np.ndarray
    K: np.ndarray
    cov: np.ndarray
    lower: np.ndarray | None = None
    upper: np.ndarray | None = None

    @classmethod
    def from_result(cls, res, lower=None, upper=None, jitter=1e-9):
        T, m = res.U.shape
        cov = spd_inverse_batch(res.Quu, jitter)
        return cls(res.X.copy(), res.U.copy(), res.K.copy(), cov,
                   None if lower is None else np.broadcast_to(lower, (T, m)).astype(float),
                   None if upper is None else np.broadcast_to(upper, (T, m)).astype(float))

    @property
    def T(self):
        return self.u_nom.shape[0]

    def mean_action(self, t, x):
        return self.u_nom[t] + self.K[t] @ (x - self.x_nom[t])

    def action(self, t, x, noise=None):
        """u_t for state x: mean + ``noise`` (a draw of N(0, cov_t), or None), clipped to the bounds."""
        u = self.mean_action(t, x)
        if noise is not None:
            u = u + noise
        if self.lower is not None:
            u = np.maximum(u, self.lower[t])
        if self.upper is not None:
            u = np.minimum(u, self.upper[t])
        return u

    def noise(self, rng, scale=1.0):
        """One draw of the exploration noise N(0, scale * cov_t) for every t, (T, m)."""
        T, m = self.u_nom.shape
        out = np.empty((T, m))
        for t in range(T):
            L = np.linalg.cholesky(0.5 * (self.cov[t] + self.cov[t].T) + 1e-15 * np.eye(m))
            out[t] = np.sqrt(scale) * (L @ rng.standard_normal(m))
        return out


def spd_inverse_batch(H, jitter=1e-9):
    """H_t^{-1} for a stack (T, m, m) of symmetric positive definite matrices: Cholesky check, then a batched
    linear solve against the identity (no explicit inverse); a non-PD H_t falls back to :func:`_spd_inverse`."""
    H = np.asarray(H, float)
    Hs = 0.5 * (H + np.swapaxes(H, 1, 2))
    try:
        np.linalg.cholesky(Hs)
    except np.linalg.LinAlgError:
        return np.stack([_spd_inverse(h, jitter) for h in Hs])
    I = np.broadcast_to(np.eye(H.shape[1]), H.shape)
    out = np.linalg.solve(Hs, I)
    return 0.5 * (out + np.swapaxes(out, 1, 2))


def _spd_inverse(H, jitter=1e-9):
    """(H)^{-1} for a symmetric positive (semi)definite H by Cholesky, adding jitter if needed."""
    m = H.shape[0]
    Hs = 0.5 * (H + H.T)
    scale = max(1.0, float(np.abs(Hs).max()))
    for j in range(8):
        try:
            c = cho_factor(Hs + (0.0 if j == 0 else jitter * scale * 10.0 ** (2 * j)) * np.eye(m))
            return cho_solve(c, np.eye(m))
        except np.linalg.LinAlgError:
            continue
    raise DataError("Q_uu is not positive definite: cannot form the controller covariance Q_uu^{-1}")


def trajectory_kl(model, ctrl, ctrl_old, mu0, S0=None, Sf=None):
    """KL(p || p_hat) of the trajectory distributions (11.15) of two Gaussian controllers under the same
    linear-Gaussian dynamics ``model`` (LtvModel) and initial state N(mu0, S0), process noise covariance
    ``Sf`` (n,n).  Returns (total KL, per-step KL (T,)).  Bounds are ignored (the Gaussian approximation)."""
    T = ctrl.T
    n, m = model.n, model.m
    mu = np.asarray(mu0, float).copy()
    S = np.zeros((n, n)) if S0 is None else np.asarray(S0, float).copy()
    Sf = np.zeros((n, n)) if Sf is None else np.asarray(Sf, float)
    kl = np.empty(T)
    P_all = spd_inverse_batch(ctrl_old.cov)
    _, ld_old_all = np.linalg.slogdet(ctrl_old.cov)
    _, ld_new_all = np.linalg.slogdet(ctrl.cov)
    for t in range(T):
        P_old = P_all[t]
        dK = ctrl.K[t] - ctrl_old.K[t]
        # mean actions at the mean state
        dmean = ctrl.mean_action(t, mu) - ctrl_old.mean_action(t, mu)
        ld_old, ld_new = ld_old_all[t], ld_new_all[t]
        kl[t] = 0.5 * (np.trace(P_old @ ctrl.cov[t]) + dmean @ P_old @ dmean + np.trace(dK.T @ P_old @ dK @ S)
                       - m + ld_old - ld_new)
        A, B = model.A[t], model.B[t]
        AK = A + B @ ctrl.K[t]
        u_mean = ctrl.mean_action(t, mu)
        mu = A @ mu + B @ u_mean + model.c[t]
        S = AK @ S @ AK.T + B @ ctrl.cov[t] @ B.T + Sf
    return float(np.sum(kl)), kl


class _KLCost:
    """The Lagrangian cost c(x,u)/eta - log p_hat(u|x) of the KL-constrained problem (11.14)."""

    def __init__(self, cost, old, eta):
        self.cost, self.old, self.eta = cost, old, float(eta)
        self.n, self.m = old.x_nom.shape[1], old.u_nom.shape[1]
        T = old.T
        self.P = spd_inverse_batch(old.cov[:T])

    def _e(self, X, U):
        T = U.shape[0]
        return U - self.old.u_nom[:T] - np.einsum("tij,tj->ti", self.old.K[:T], X[:T] - self.old.x_nom[:T])

    def value(self, X, U):
        e = self._e(X, U)
        return self.cost.value(X, U) / self.eta + 0.5 * float(np.einsum("ti,tij,tj->", e, self.P[: len(e)], e))

    def derivatives(self, X, U):
        lx, lu, lxx, luu, lux = self.cost.derivatives(X, U)
        T = U.shape[0]
        e = self._e(X, U)
        Pe = np.einsum("tij,tj->ti", self.P[:T], e)
        Kt = self.old.K[:T]
        lx = lx / self.eta
        lx[:T] -= np.einsum("tji,tj->ti", Kt, Pe)
        lu = lu / self.eta + Pe
        lxx = lxx / self.eta
        lxx[:T] += np.einsum("tji,tjk,tkl->til", Kt, self.P[:T], Kt)
        luu = luu / self.eta + self.P[:T]
        lux = lux / self.eta - np.einsum("tij,tjk->tik", self.P[:T], Kt)
        return lx, lu, lxx, luu, lux


@dataclass
class KLResult:
    """Result of :func:`ilqr_kl`: the new Gaussian ``controller``, the inner iLQR ``result`` (on the model),
    the dual variable ``eta``, the achieved ``kl`` and the model-predicted cost ``J`` (no 1/eta scaling)."""
    controller: LinearGaussianController
    result: IlqrResult
    eta: float
    kl: float
    J: float
    searches: int


def ilqr_kl(model, cost, x0, old, kl_step, lower=None, upper=None, eta_range=(1e-6, 1e8), Sf=None, S0=None,
            max_search=30, rel_tol=0.1, **ilqr_kw):
    """iLQR with the KL-divergence constraint D_KL(p(tau) || p_hat(tau)) <= ``kl_step`` (Eqs. (11.14)-(11.15)).

    ``model``: :class:`LtvModel` (fitted along the last trajectory); ``old``: the previous
    :class:`LinearGaussianController` p_hat.  For a dual variable eta the Lagrangian cost
    c/eta - log p_hat(u|x) is minimized by control-limited iLQR started at the old nominal controls; its
    maximum-entropy controller is N(K x_bar + k, Q_uu^{-1}) (11.11).  eta is found by bisection in log eta so that
    the KL lies within ``rel_tol`` of ``kl_step`` (or is below it at the smallest eta)."""
    if not (kl_step > 0):
        raise DataError(f"kl_step must be > 0, got {kl_step}")
    T = old.T
    lb, ub = _bounds(lower, upper, T, model.m)

    def solve(eta):
        c = _KLCost(cost, old, eta)
        r = ilqr(model, c, x0, old.u_nom, lb, ub, **ilqr_kw)
        ctrl = LinearGaussianController.from_result(r, lb, ub)
        kl, _ = trajectory_kl(model, ctrl, old, x0, S0, Sf)
        return r, ctrl, kl

    lo, hi = np.log(eta_range[0]), np.log(eta_range[1])
    r, ctrl, kl = solve(np.exp(lo))
    n_search = 1
    eta = np.exp(lo)
    if kl > kl_step * (1 + rel_tol):
        best = None
        for n_search in range(2, max_search + 2):
            mid = 0.5 * (lo + hi)
            eta = np.exp(mid)
            r, ctrl, kl = solve(eta)
            if kl > kl_step:
                lo = mid
            else:
                hi = mid
                best = (r, ctrl, kl, eta)
            if abs(kl - kl_step) <= rel_tol * kl_step:
                break
        else:
            if best is not None:
                r, ctrl, kl, eta = best
        if kl > kl_step * (1 + rel_tol) and best is not None:
            r, ctrl, kl, eta = best
    return KLResult(ctrl, r, float(eta), float(kl), float(cost.value(r.X, r.U)), n_search)
