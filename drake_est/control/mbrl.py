"""Model-based reinforcement learning with trajectory optimization: thesis Algorithm 7 (Sec. 11.2).

    repeat: perform rollout -> fit dynamics model -> optimize trajectory and controller -> until convergence

* rollout: the Gaussian controller p(u|x) = N(u_hat + K (x - x_hat), Sigma) (11.11) on the true system (a Drake
  system, e.g. :class:`drake_est.systems.cartpole_plant.CartPoleTrueSystem`); the exploration noise has the
  controller's covariance Sigma = Q_uu^{-1} of the last optimization (the first rollout uses ``sigma0``^2);
* fit: ``"ltv"`` — x_{t+1} = A_t x_t + B_t u_t + c_t by the Kalman smoother (7.5) (second-order random walk of
  the parameters, :func:`drake_est.identification.ltv.ltv_smoother` with ``order=2``; the affine term enters as a
  constant input) with lambda by maximum likelihood (:func:`ltv_select_lambda_ml`), on the last rollout;
  ``"lti"`` — one (A, B, c) by least squares on all rollouts so far; ``"true"`` — the exact model (optimal
  control with the true model, the reference of Fig. 11.1); the two neural-network-prior variants of Sec. 11.2,
  where the linearization [A_t B_t c_t] of a network x+ = g(x, u) + x (:class:`NetworkPrior`) along the last
  rollout is the prior (7.15) of the LTV fit: ``"ltv-nn"`` — the network is refit on all rollouts every
  iteration (warm start from the previous weights), prior covariance decaying as 1/iteration;
  ``"ltv-nn-pretrained"`` — the network is trained once before learning starts on random-input identification
  experiments (:func:`pretrain_network_prior`) and never updated, fixed prior covariance;
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

MODELS = ("true", "ltv", "lti", "ltv-nn", "ltv-nn-pretrained")


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


def fit_ltv(X, U, lams=None, prior=None, prior_cov=None, sigma_e="ml"):
    """LTV model along one trajectory by (7.5) (order-2 random walk), lambda by maximum likelihood on the grid
    ``lams`` (the log-likelihood of :func:`drake_est.identification.ltv.ltv_smoother` without the prior).
    A lambda whose fit is singular (too weak a random-walk prior for the excitation) is left out of the
    selection; if every one is, IdentifiabilityError.  ``prior`` (T, n, n+m+1): prior mean of [A_t B_t c_t]
    (7.15) with covariance ``prior_cov`` (n+m+1, n+m+1) per row, in absolute parameter units; the data term is
    then weighted with the noise standard deviation ``sigma_e``: ``"ml"`` (default) the maximum-likelihood noise
    level of the fit without the prior at the selected lambda (Eqs. (7.16)-(7.18) with the measurement noise
    of the data), or a number; if the prior fit at the most likely lambda is numerically singular, the next most
    likely lambda is used (IdentifiabilityError if none works).  Returns (LtvModel, lambda)."""
    from drake_est.identification.ltv import ltv_smoother
    if isinstance(sigma_e, str) and sigma_e != "ml":
        raise DataError(f"sigma_e must be 'ml' or a positive number, got {sigma_e!r}")
    if not isinstance(sigma_e, str) and not (np.isfinite(sigma_e) and sigma_e > 0):
        raise DataError(f"sigma_e must be 'ml' or a positive number, got {sigma_e!r}")
    Ub = np.hstack([U, np.ones((len(U), 1))])
    lams = np.logspace(-2, 4, 7) if lams is None else lams
    cands = []
    for l in lams:
        try:
            r = ltv_smoother(X, Ub, float(l), order=2, check=False)
        except IdentifiabilityError:   # too little regularization for this trajectory: not a candidate
            continue
        cands.append((r.loglik, float(l), r))
    if not cands:
        raise IdentifiabilityError(f"lams: the LTV fit (7.5) is singular for every lambda in the grid {list(lams)}")
    cands.sort(key=lambda c: -c[0])
    if prior is None:
        return LtvModel.from_result(cands[0][2], bias_input=True), cands[0][1]
    # with the prior: the most likely lambda whose prior fit is numerically regular (with a noise-free system
    # the ML noise level can be ~1e-15 and the normal equations borderline; the next lambda is then used)
    for _, lam, r in cands:
        sig = float(np.sqrt(max(r.sigma2, 1e-300))) if isinstance(sigma_e, str) else float(sigma_e)
        try:
            res = ltv_smoother(X, Ub, lam, order=2, prior=prior, prior_cov=prior_cov, sigma_e=sig, check=False)
        except IdentifiabilityError:
            continue
        return LtvModel.from_result(res, bias_input=True), lam
    raise IdentifiabilityError(f"prior: the LTV fit (7.5) with the prior is singular for every lambda in the grid "
                               f"{list(lams)}")


class NetworkPrior:
    """Neural dynamics model x+ = g(x, u) + x (thesis Eq. (8.8), tanh hidden layers as in Ch. 8) used as the
    prior of the LTV fit (7.15) in Sec. 11.2.

    Trained by Adam on standardized data (inputs z = (x, u), targets x+ - x; the standardization is fixed
    at the first :meth:`fit` so that later fits can continue from the current weights) with a fixed number of
    mini-batch gradient steps per call: every :meth:`fit` *continues* from the current weights and Adam
    state (warm start, as in the thesis' successive refit), so the cost of a refit does not grow with the
    amount of data.  Weight decay only; the tangent-space penalty (8.9) of the thesis is left out to keep the
    per-iteration refit cheap.  ``seed`` seeds the initialization and the mini-batches."""

    def __init__(self, hidden=(30, 30), steps=200, batch_size=256, learning_rate=3e-3, weight_decay=1e-4,
                 seed=0):
        hidden = tuple(int(h) for h in hidden)
        if not hidden or any(h < 1 for h in hidden):
            raise DataError(f"hidden: layer sizes must be positive, got {hidden}")
        if int(steps) < 1 or int(batch_size) < 1:
            raise DataError(f"steps and batch_size must be >= 1, got {steps} and {batch_size}")
        if not (np.isfinite(learning_rate) and learning_rate > 0):
            raise DataError(f"learning_rate must be > 0, got {learning_rate}")
        if not (np.isfinite(weight_decay) and weight_decay >= 0):
            raise DataError(f"weight_decay must be finite and >= 0, got {weight_decay}")
        self.hidden, self.steps, self.batch_size = hidden, int(steps), int(batch_size)
        self.learning_rate, self.weight_decay = float(learning_rate), float(weight_decay)
        self.rng = np.random.default_rng(seed)
        self.params_s = None        # weights acting on standardized data
        self.scaling = None         # (mu_z, s_z, mu_t, s_t)
        self._adam = None
        self.model_ = None          # NeuralDynamicsModel with the weights in original units
        self.total_steps = 0

    def fit(self, Xs, Us, steps=None):
        """Continue training on the trajectories ``Xs`` [(T+1, n)], ``Us`` [(T, m)] for ``steps`` (default
        ``self.steps``) mini-batch steps.  Returns self."""
        from drake_est.identification.nn import Adam, NeuralDynamicsModel, init_params, loss_and_grad
        if len(Xs) == 0 or len(Xs) != len(Us):
            raise DataError(f"Xs/Us: need the same positive number of state and input trajectories, got "
                            f"{len(Xs)} and {len(Us)}")
        Z = np.vstack([np.hstack([X[:-1], U]) for X, U in zip(Xs, Us)])
        D = np.vstack([X[1:] - X[:-1] for X in Xs])
        if not (np.all(np.isfinite(Z)) and np.all(np.isfinite(D))):
            raise DataError("Xs/Us: non-finite values in the training trajectories")
        n, m = Xs[0].shape[1], Us[0].shape[1]
        if self.scaling is None:
            def sd(a):
                s = a.std(axis=0)
                return np.where(s > 1e-12, s, 1.0)
            self.scaling = (Z.mean(0), sd(Z), D.mean(0), sd(D))
            self.params_s = init_params([n + m, *self.hidden, n], self.rng, 0.1)
            self._adam = Adam(self.params_s, self.learning_rate)
        elif Z.shape[1] != len(self.scaling[0]):
            raise DataError(f"Xs/Us: {Z.shape[1]} state+input columns, the network was trained on "
                            f"{len(self.scaling[0])}")
        mu_z, s_z, mu_t, s_t = self.scaling
        Zs, Ds = (Z - mu_z) / s_z, (D - mu_t) / s_t
        N = Zs.shape[0]
        B = min(self.batch_size, N)
        pairs = np.zeros((0, 2), int)
        w = np.full(B, 1.0 / B)
        params = self.params_s
        for _ in range(self.steps if steps is None else int(steps)):
            idx = self.rng.integers(0, N, B)
            cost, _, _, grads = loss_and_grad(params, Zs[idx], Ds[idx], w, pairs, 0.0, self.weight_decay)
            if not (np.isfinite(cost) and all(np.all(np.isfinite(g)) for gw in grads for g in gw)):
                raise IdentifiabilityError("network prior: training diverged (non-finite loss); lower "
                                           "learning_rate")
            params = self._adam.update(params, grads)
            self.total_steps += 1
        self.params_s = params
        # fold the standardization into the first and last layers: g(z) = s_t * net_s((z - mu_z)/s_z) + mu_t
        folded = [(W.copy(), b.copy()) for W, b in params]
        W1, b1 = folded[0]
        W1 = W1 / s_z
        folded[0] = (W1, b1 - W1 @ mu_z)
        WL, bL = folded[-1]
        folded[-1] = (s_t[:, None] * WL, s_t * bL + mu_t)
        self.model_ = NeuralDynamicsModel(hidden=self.hidden, form="g", progress_bar=False).set_params(folded, n, m)
        return self

    def linearization(self, X, U):
        """[A_t B_t c_t] (T, n, n+m+1) of the network along (X (T+1, n), U (T, m)): the prior mean of the
        LTV fit (7.15); c_t = f(x_t, u_t) - A_t x_t - B_t u_t is the affine term."""
        if self.model_ is None:
            raise DataError("network prior is not trained; call fit() first")
        J = self.model_.jacobian(X[:-1], U)
        n = X.shape[1]
        c = (self.model_.predict(X[:-1], U) - np.einsum("tij,tj->ti", J[:, :, :n], X[:-1])
             - np.einsum("tij,tj->ti", J[:, :, n:], U))
        return np.concatenate([J, c[:, :, None]], axis=2)


def pretrain_network_prior(n_rollouts=20, T=400, seed=0, steps=6000, h=0.01, l=1.0, d=0.1, input_std=3.0,
                           bound=10.0, **net_kw):
    """The network of the pretrained-prior variant of Sec. 11.2 ("pretrain a neural network model of the system
    in a standard system-identification fashion"), trained once before learning starts.

    Data source: ``n_rollouts`` open-loop experiments of ``T`` steps on the analytic cart-pole
    (:class:`drake_est.control.cartpole.CartPoleModel`, Eqs. (8.11)-(8.12), explicit Euler step ``h``, pole
    length ``l``, damping ``d``; the defaults are the nominal physics) with random low-pass inputs
    (standard deviation ``input_std``, clipped to +-``bound``) from random initial states (angle uniform on
    [-pi, pi], angular rate and cart velocity uniform on [-3, 3] and [-2, 2]).  This is identification data,
    not data along the task: it covers the whole swing of the pendulum but not the state-visitation
    distribution of the policy under optimization, which is what the thesis' comparison of the two NN-prior
    variants is about; ``l``/``d`` other than 1.0/0.1 give a related but mismatched simulator.  ``net_kw``
    go to :class:`NetworkPrior`.  Returns the trained :class:`NetworkPrior`."""
    from drake_est.control.cartpole import CartPoleModel
    from drake_est.identification.nn_tasks import lowpass_noise
    if int(n_rollouts) < 1 or int(T) < 2:
        raise DataError(f"n_rollouts must be >= 1 and T >= 2, got {n_rollouts} and {T}")
    rng = np.random.default_rng(seed)
    sim = CartPoleModel(h=h, l=l, d=d)
    Xs, Us = [], []
    lb, ub = np.full((T, 1), -bound), np.full((T, 1), bound)
    for _ in range(int(n_rollouts)):
        x0 = np.array([rng.uniform(-np.pi, np.pi), rng.uniform(-3, 3), 0.0, rng.uniform(-2, 2)])
        U = np.clip(input_std * lowpass_noise(rng, T, 1, cutoff=0.05), -bound, bound)
        X, U, ok = sim.forward(x0, np.zeros((T + 1, 4)), U, np.zeros((T, 1, 4)), np.zeros((T, 1)), 0.0, lb, ub)
        if not ok:
            raise DataError(f"pretraining: the simulated cart-pole (l={l}, d={d}, h={h}) became non-finite")
        Xs.append(X)
        Us.append(U)
    net = NetworkPrior(seed=seed, **net_kw)
    return net.fit(Xs, Us, steps=steps)


def mbrl(true_system, true_model, cost, x0, T, model="ltv", iterations=20, kl_step=400.0, sigma0=1.0,
         lower=-10.0, upper=10.0, seed=0, show_progress=False, kl_increase=2.0, kl_decrease=0.5, kl_max=1e5,
         nn_prior_cov=None, noise_scale=1.0, lams=None, pretrained=None, nn_sigma_e="ml", nn_steps=200,
         nn_first_steps=1000):
    """Algorithm 7 on ``true_system`` (``.rollout(x0, T, policy)``), cost ``cost``, horizon ``T``.

    ``model="ltv-nn"``: the LTV fit with the prior of a network (:class:`NetworkPrior`) refit on all data every
    iteration, prior covariance ``nn_prior_cov`` / iteration (Sec. 11.2; default 1.0); the refit continues from
    the previous iteration's weights (``nn_first_steps`` mini-batch steps at the first iteration, ``nn_steps`` after).
    ``model="ltv-nn-pretrained"``: the prior is the linearization along the current rollout of a network trained
    before learning starts and never updated (``pretrained``, a :class:`NetworkPrior`; default
    :func:`pretrain_network_prior` with seed 0), with the fixed prior covariance ``nn_prior_cov`` (default 10.0).
    Both covariances are per parameter of [A_t B_t c_t] with the data weighted by the ML noise level
    (:func:`fit_ltv`); the defaults were picked on a small grid (seeds 0-5, 8-10 iterations; see
    docs/readme/ilqr.md); ``nn_sigma_e``: the noise level of the data term of the prior fit (``"ml"`` or a
    number, :func:`fit_ltv`).  The KL bound starts at ``kl_step`` and adapts (Levine and Abbeel 2014):
    multiplied by ``kl_increase`` (up to ``kl_max``) after an iteration that lowered the noise-free cost on the
    true system, by ``kl_decrease`` after one that raised it.

    ``noise_scale``: the exploration noise is N(0, noise_scale * Q_uu^{-1}) (1: the controller's own covariance
    (11.11)); ``lams``: the lambda grid of the LTV fit (default :func:`fit_ltv`'s).

    ``true_model``: the exact :class:`drake_est.control.ilqr.Model` of the system (used only when
    ``model == "true"``).  Returns :class:`MbrlResult`."""
    if model not in MODELS:
        raise DataError(f"model must be one of {MODELS}, got {model!r}")
    if pretrained is not None and model != "ltv-nn-pretrained":
        raise DataError(f"pretrained: a pretrained network is only used by model='ltv-nn-pretrained', got {model!r}")
    if pretrained is not None and not callable(getattr(pretrained, "linearization", None)):
        raise DataError("pretrained: expected a NetworkPrior (with .linearization(X, U)), got "
                        f"{type(pretrained).__name__}")
    if int(nn_steps) < 1 or int(nn_first_steps) < 1:
        raise DataError(f"nn_steps and nn_first_steps must be >= 1, got {nn_steps} and {nn_first_steps}")
    if nn_prior_cov is None:      # the values used in the reproduction (drake-est reproduce mbrl-cartpole)
        nn_prior_cov = 10.0 if model == "ltv-nn-pretrained" else 1.0
    if not (np.isfinite(nn_prior_cov) and nn_prior_cov > 0):
        raise DataError(f"nn_prior_cov must be finite and > 0, got {nn_prior_cov}")
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
    net = None
    if model == "ltv-nn":
        net = NetworkPrior(seed=seed, steps=nn_steps)
    elif model == "ltv-nn-pretrained":
        net = pretrain_network_prior(seed=0) if pretrained is None else pretrained
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
            net.fit(Xs, Us, steps=nn_first_steps if len(Xs) == 1 else nn_steps)
            pr = net.linearization(Xr, Ur)
            mdl, lam = fit_ltv(Xr, Ur, lams=lams, prior=pr, prior_cov=nn_prior_cov / len(Xs) * np.eye(pr.shape[2]),
                               sigma_e=nn_sigma_e)
            out.lam.append(lam)
        elif model == "ltv-nn-pretrained":
            pr = net.linearization(Xr, Ur)
            mdl, lam = fit_ltv(Xr, Ur, lams=lams, prior=pr, prior_cov=nn_prior_cov * np.eye(pr.shape[2]),
                               sigma_e=nn_sigma_e)
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
