"""Model-based reinforcement learning with trajectory optimization: thesis Algorithm 7 (Sec. 11.2).

    repeat: perform rollout -> fit dynamics model -> optimize trajectory and controller -> until convergence

* rollout: the Gaussian controller p(u|x) = N(u_hat + K (x - x_hat), Sigma) (11.11) on the true system (a Drake
  system, e.g. :class:`drake_est.systems.cartpole_plant.CartPoleTrueSystem`); the exploration noise has the
  controller's covariance Sigma = Q_uu^{-1} of the last optimization (the first rollout uses ``sigma0``^2);
* fit: ``"ltv"`` — x_{t+1} = A_t x_t + B_t u_t + c_t by the Kalman smoother (7.5) (second-order random walk of
  the parameters, :func:`drake_est.identification.ltv.ltv_smoother` with ``order=2``; the affine term enters as a
  constant input) with lambda by maximum likelihood (:func:`ltv_select_lambda_ml`), on the last rollout;
  ``"lti"`` — one (A, B, c) by least squares on all rollouts so far; ``"true"`` — the exact model (optimal
  control with the true model, the reference of Fig. 11.1);
* optimize: control-limited iLQR under the KL constraint to the last controller
  (:func:`drake_est.control.ilqr.ilqr_kl`, Eqs. (11.14)-(11.15)).

The cost recorded per learning iteration is the cost of the noise-free controller (mean action) on the true
system; the cost of the exploring rollout is recorded beside it.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drake_est.control.ilqr import LinearGaussianController, LtvModel, ilqr, ilqr_kl
from drake_est.errors import DataError, IdentifiabilityError
from drake_est.progress import progress

MODELS = ("true", "ltv", "lti", "ltv-nn")


@dataclass
class MbrlResult:
    """Per learning iteration: ``costs`` (noise-free controller on the true system), ``rollout_costs`` (the
    exploring experiment), ``kl`` reached, ``lam`` of the LTV fit; the final controller and trajectories."""
    model: str
    costs: list = field(default_factory=list)
    rollout_costs: list = field(default_factory=list)
    kl: list = field(default_factory=list)
    lam: list = field(default_factory=list)
    kl_bounds: list = field(default_factory=list)
    X: np.ndarray | None = None
    U: np.ndarray | None = None
    X_rollout: np.ndarray | None = None
    U_rollout: np.ndarray | None = None
    controller: LinearGaussianController | None = None
    queries: int = 0


def fit_lti(Xs, Us):
    """x_{t+1} = A x_t + B u_t + c by least squares on all (X, U) pairs; returns (A, B, c)."""
    Phi = np.vstack([np.hstack([X[:-1], U, np.ones((len(U), 1))]) for X, U in zip(Xs, Us)])
    Y = np.vstack([X[1:] for X in Xs])
    n, m = Xs[0].shape[1], Us[0].shape[1]
    W, *_ = np.linalg.lstsq(Phi, Y, rcond=None)
    W = W.T
    return W[:, :n], W[:, n:n + m], W[:, -1]


def fit_ltv(X, U, lams=None, prior=None, prior_cov=None):
    """LTV model along one trajectory by (7.5) (order-2 random walk), lambda by maximum likelihood on the grid
    ``lams`` (the log-likelihood of :func:`drake_est.identification.ltv.ltv_smoother` without the prior).
    A lambda whose fit is singular (too weak a random-walk prior for the excitation) is left out of the
    selection; if every one is, IdentifiabilityError.  ``prior`` (T, n, n+m+1): prior mean of [A_t B_t c_t]
    (7.15) with covariance ``prior_cov`` (n+m+1, n+m+1) per row.  Returns (LtvModel, lambda)."""
    from drake_est.identification.ltv import ltv_smoother
    Ub = np.hstack([U, np.ones((len(U), 1))])
    lams = np.logspace(-2, 4, 7) if lams is None else lams
    best, lam = -np.inf, None
    res = None
    for l in lams:
        try:
            r = ltv_smoother(X, Ub, float(l), order=2, check=False)
        except IdentifiabilityError:   # too little regularization for this trajectory: not a candidate
            continue
        if r.loglik > best:
            best, lam, res = r.loglik, float(l), r
    if res is None:
        raise IdentifiabilityError(f"lams: the LTV fit (7.5) is singular for every lambda in the grid {list(lams)}")
    if prior is not None:
        res = ltv_smoother(X, Ub, lam, order=2, prior=prior, prior_cov=prior_cov, check=False)
    return LtvModel.from_result(res, bias_input=True), lam


def nn_prior(Xs, Us, X, U, seed=0, epochs=200):
    """Sec. 11.2 prior: a network x+ = g(x, u) + x (Ch. 8, :class:`drake_est.identification.nn.NeuralDynamicsModel`)
    refit on all rollouts so far; returns its linearization [A_t B_t c_t] (T, n, n+m+1) along (X, U)
    (c_t = g(x_t,u_t) + x_t - A_t x_t - B_t u_t, the affine term)."""
    from drake_est.identification.nn import NeuralDynamicsModel
    net = NeuralDynamicsModel(hidden=(30, 30), form="g", epochs=epochs, learning_rate=3e-3, weight_decay=1e-4,
                              progress_bar=False, seed=seed)
    net.fit([x for x in Xs], [np.vstack([u, u[-1:]]) for u in Us])
    J = net.jacobian(X[:-1], U)
    n = X.shape[1]
    c = net.predict(X[:-1], U) - np.einsum("tij,tj->ti", J[:, :, :n], X[:-1]) - np.einsum("tij,tj->ti", J[:, :, n:], U)
    return np.concatenate([J, c[:, :, None]], axis=2)


def mbrl(true_system, true_model, cost, x0, T, model="ltv", iterations=20, kl_step=400.0, sigma0=1.0,
         lower=-10.0, upper=10.0, seed=0, show_progress=False, kl_increase=2.0, kl_decrease=0.5, kl_max=1e5,
         nn_prior_cov=1e-3, noise_scale=1.0, lams=None):
    """Algorithm 7 on ``true_system`` (``.rollout(x0, T, policy)``), cost ``cost``, horizon ``T``.

    ``model="ltv-nn"``: the LTV fit with the prior of a network refit on all data every iteration, prior
    covariance ``nn_prior_cov`` / iteration (Sec. 11.2).  The KL bound starts at ``kl_step`` and adapts (Levine and Abbeel 2014): multiplied by ``kl_increase``
    (up to ``kl_max``) after an iteration that lowered the noise-free cost on the true system, by ``kl_decrease``
    after one that raised it.

    ``noise_scale``: the exploration noise is N(0, noise_scale * Q_uu^{-1}) (1: the controller's own covariance
    (11.11)); ``lams``: the lambda grid of the LTV fit (default :func:`fit_ltv`'s).

    ``true_model``: the exact :class:`drake_est.control.ilqr.Model` of the system (used only when
    ``model == "true"``).  Returns :class:`MbrlResult`."""
    if model not in MODELS:
        raise DataError(f"model must be one of {MODELS}, got {model!r}")
    if not (noise_scale >= 0 and np.isfinite(noise_scale)):
        raise DataError(f"noise_scale must be finite and >= 0, got {noise_scale}")
    if iterations < 1:
        raise DataError(f"iterations must be >= 1, got {iterations}")
    rng = np.random.default_rng(seed)
    n, m = len(x0), 1 if np.ndim(lower) == 0 else len(lower)
    lb = np.full((T, m), lower, float)
    ub = np.full((T, m), upper, float)
    out = MbrlResult(model)
    if model == "true":
        r = ilqr(true_model, cost, x0, np.zeros((T, m)), lb, ub)
        X, U = true_system.rollout(x0, T, lambda t, x: np.clip(r.U[t] + r.K[t] @ (x - r.X[t]), lb[t], ub[t]))
        J = cost.value(X, U)
        out.costs = [J] * iterations
        out.rollout_costs = [J] * iterations
        out.X, out.U, out.X_rollout, out.U_rollout = X, U, X, U
        out.controller = r.controller(lb, ub)
        out.queries = r.iterations
        return out
    ctrl = LinearGaussianController(np.tile(x0, (T + 1, 1)), np.zeros((T, m)), np.zeros((T, m, n)),
                                    np.tile(sigma0 ** 2 * np.eye(m), (T, 1, 1)), lb, ub)
    Xs, Us = [], []
    eps = float(kl_step)
    out.kl_bounds = []
    it = range(iterations)
    for _ in (progress(it, desc=f"mbrl {model} seed {seed}") if show_progress else it):
        noise = ctrl.noise(rng, noise_scale)
        Xr, Ur = true_system.rollout(x0, T, lambda t, x: ctrl.action(t, x, noise[t]))
        Xd, Ud = true_system.rollout(x0, T, lambda t, x: ctrl.action(t, x, None))
        out.rollout_costs.append(cost.value(Xr, Ur))
        out.costs.append(cost.value(Xd, Ud))
        if len(out.costs) > 1:
            eps = min(eps * kl_increase, kl_max) if out.costs[-1] < out.costs[-2] else eps * kl_decrease
        out.kl_bounds.append(eps)
        Xs.append(Xr)
        Us.append(Ur)
        if model == "ltv":
            mdl, lam = fit_ltv(Xr, Ur, lams=lams)
            out.lam.append(lam)
        elif model == "ltv-nn":
            pr = nn_prior(Xs, Us, Xr, Ur, seed=seed)
            mdl, lam = fit_ltv(Xr, Ur, lams=lams, prior=pr, prior_cov=nn_prior_cov / len(Xs) * np.eye(pr.shape[2]))
            out.lam.append(lam)
        else:
            A, B, c = fit_lti(Xs, Us)
            mdl = LtvModel(np.tile(A, (T, 1, 1)), np.tile(B, (T, 1, 1)), np.tile(c, (T, 1)))
        # the old trajectory distribution is the executed controller, nominal along the executed rollout
        old = LinearGaussianController(Xd, ctrl.u_nom, ctrl.K, ctrl.cov, lb, ub)
        kr = ilqr_kl(mdl, cost, x0, old, eps, lb, ub, max_iter=50)
        out.kl.append(kr.kl)
        ctrl = kr.controller
        out.X, out.U, out.X_rollout, out.U_rollout = Xd, Ud, Xr, Ur
    out.controller = ctrl
    out.queries = 2 * iterations
    return out
