"""Neural-network dynamics models with tangent-space regularization (thesis Ch. 8).

A feed-forward tanh network ``net`` with a linear output layer models the one-step dynamics in one of
three forms (:class:`NeuralDynamicsModel` ``form=``):

* ``"f"``        x+ = net(x, u)                          (Learning Objective 1)
* ``"g"``        x+ = net(x, u) + x                      (Learning Objective 2, Eq. (8.8): g + x)
* ``"nominal"``  x+ = net(x, u) + A0 x + B0 u            (Sec. 8.4, a nominal linear model)

All three are ``x+ = net(z) + N z`` with z = [x; u] and a constant N (0, [I 0] or [A0 B0]); the model
Jacobian [A B] (8.6) is ``J_net(z) + N``.  The training cost (per mini-batch S of samples and the set P of
consecutive sample pairs (t, t+1) of the same trajectory reachable from S) is

    V(w) = 1/(2|S|) sum_{t in S} ||x+_t - x^_+(z_t)||^2                     (prediction error, Sec. 8.3)
         + weight_decay/2 * sum_l ||W_l||_F^2                               (L2 weight decay, Sec. 8.4)
         + jacprop/|P| * sum_{(t,t+1) in P} ||J_{t+1} - J_t||_F^2            (Jacprop, Eq. (8.9))

(the squared Frobenius norm makes (8.9) differentiable where consecutive Jacobians agree).  The Jacobian is
computed in forward mode along with the forward pass (Algorithm 4); its gradient with respect to the
weights, Eq. (8.10), is computed exactly by reverse-mode differentiation of that forward-mode computation
("double backpropagation", :func:`loss_and_grad`), all in numpy.  Optimization: Adam with mini-batches,
early stopping on validation trajectories (the parameters with the lowest validation prediction error are
kept).  Drake's ``MultilayerPerceptron`` holds the same network (:meth:`NeuralDynamicsModel.to_drake`,
:meth:`NeuralDynamicsModel.from_drake`); its ``BatchOutput`` gives the same forward pass.
"""
from __future__ import annotations

import copy
import json
import math
import warnings
from dataclasses import dataclass

import numpy as np

from drake_est.errors import DataError
from drake_est.progress import progress

FORMS = ("f", "g", "nominal")


# =============================================================================================
# the network: parameters are a list [(W_1, b_1), ..., (W_L, b_L)], tanh hidden layers, linear output
# =============================================================================================
def init_params(sizes, rng, scale=1.0):
    """Random weights for layer sizes ``sizes`` = [d_in, h_1, ..., h_{L-1}, d_out] (Glorot-uniform W, zero b).

    ``scale`` multiplies the output layer's weights (small output layers make f start near 0 and g + x
    near the identity, the starting points discussed in Sec. 8.3)."""
    params = []
    L = len(sizes) - 1
    for i in range(L):
        fan_in, fan_out = sizes[i], sizes[i + 1]
        lim = math.sqrt(6.0 / (fan_in + fan_out))
        W = rng.uniform(-lim, lim, size=(fan_out, fan_in))
        if i == L - 1:
            W = W * scale
        params.append((W, np.zeros(fan_out)))
    return params


def forward(params, Z):
    """Network output for inputs ``Z`` (B, d_in) -> (B, d_out)."""
    l = Z
    for W, b in params[:-1]:
        l = np.tanh(l @ W.T + b)
    W, b = params[-1]
    return l @ W.T + b


def forward_jac(params, Z):
    """Output (B, d_out) and input-output Jacobian (B, d_out, d_in) of the network at each row of ``Z``.

    Forward-mode Jacobian computed alongside the forward pass, thesis Algorithm 4:
    J_i = diag(sech^2(a_i)) W_i J_{i-1}, J_0 = I, J = W_L J_{L-1}."""
    l = Z
    J = None
    for W, b in params[:-1]:
        l = np.tanh(l @ W.T + b)
        s = 1.0 - l * l
        M = np.broadcast_to(W, (Z.shape[0],) + W.shape) if J is None else np.matmul(W, J)
        J = s[:, :, None] * M
    W, b = params[-1]
    out = l @ W.T + b
    J = np.broadcast_to(W, (Z.shape[0],) + W.shape).copy() if J is None else np.matmul(W, J)
    return out, J


def loss_and_grad(params, Z, Y, pred_w, pairs, jacprop=0.0, weight_decay=0.0, N=None, want_grad=True):
    """Training cost and its exact gradient with respect to all weights and biases.

    Z (B, d_in) network inputs; Y (B, d_out) targets of the full model (x+); ``pred_w`` (B,) weight of each
    row in the prediction error (0 for rows that enter only through a Jacobian pair); ``pairs`` (P, 2) row
    indices (t, t+1) of consecutive samples; N (d_out, d_in) the fixed linear part (None = 0).

    cost = sum_t pred_w_t ||Y_t - net(Z_t) - N Z_t||^2 / 2 + weight_decay/2 sum ||W||^2
           + jacprop/P sum_p ||J(Z_{p1}) - J(Z_{p0})||_F^2       (Eq. (8.9); N cancels in the difference)

    The Jacprop gradient (8.10) is obtained by reverse-mode differentiation of :func:`forward_jac`
    (double backpropagation): the adjoint of each J_i = s_i * (W_i J_{i-1}) flows into W_i, into J_{i-1}
    and, through s_i = 1 - tanh(a_i)^2, into a_i and so back along the ordinary forward pass.

    Returns (cost, pred_cost, jac_cost, grads) with grads a list [(dW, db)] shaped like ``params``."""
    L = len(params)
    B, d = Z.shape
    use_jac = jacprop > 0 and len(pairs) > 0
    # ---- forward (with the Jacobian recursion when needed) ----
    # Jacobians are kept transposed, Jt_i (B, d, h_i) = J_i^T, so that every product is one 2-D matmul:
    # M_i^T = Jt_{i-1} W_i^T, Jt_i = M_i^T * s_i.
    ls, ss, Mts, Jts = [Z], [], [], []
    l, Jt = Z, None
    for W, b in params[:-1]:
        l = np.tanh(l @ W.T + b)
        s = 1.0 - l * l
        ls.append(l)
        ss.append(s)
        if use_jac:
            h = W.shape[0]
            Mt = np.broadcast_to(W.T, (B, d, h)) if Jt is None else (Jt.reshape(B * d, -1) @ W.T).reshape(B, d, h)
            Jt = Mt * s[:, None, :]
            Mts.append(Mt)
            Jts.append(Jt)
    WL, bL = params[-1]
    n_out = WL.shape[0]
    out = l @ WL.T + bL
    if N is not None:
        out = out + Z @ N.T
    E = out - Y
    pred_cost = 0.5 * float(np.sum(pred_w * np.einsum("ij,ij->i", E, E)))
    wd_cost = 0.5 * weight_decay * sum(float(np.sum(W * W)) for W, _ in params) if weight_decay > 0 else 0.0
    jac_cost = 0.0
    if use_jac:
        Jout_t = np.broadcast_to(WL.T, (B, d, n_out)) if Jt is None else (Jt.reshape(B * d, -1) @ WL.T).reshape(B, d, n_out)
        p0, p1 = pairs[:, 0], pairs[:, 1]
        D = Jout_t[p1] - Jout_t[p0]
        c = jacprop / len(pairs)
        jac_cost = c * float(np.sum(D * D))
    cost = pred_cost + wd_cost + jac_cost
    if not want_grad:
        return cost, pred_cost, jac_cost, None
    # ---- reverse ----
    grads = [None] * L
    Ebar = pred_w[:, None] * E                        # d cost / d out
    dWL = Ebar.T @ ls[-1]
    dbL = Ebar.sum(0)
    lbar = Ebar @ WL                                  # d cost / d l_{L-1}
    Jbar = None                                       # d cost / d Jt_i  (B, d, h_i)
    if use_jac:
        G = np.zeros((B, d, n_out))                   # d cost / d Jout_t per row
        np.add.at(G, p1, 2 * c * D)
        np.add.at(G, p0, -2 * c * D)
        if Jt is None:                                # linear network: Jout = W_L
            dWL = dWL + G.sum(0).T
        else:
            G2 = G.reshape(B * d, n_out)
            dWL = dWL + G2.T @ Jts[-1].reshape(B * d, -1)
            Jbar = (G2 @ WL).reshape(B, d, -1)
    grads[-1] = (dWL, dbL)
    for i in range(L - 2, -1, -1):                    # hidden layer i (params[i]), output ls[i+1]
        W, _ = params[i]
        h = W.shape[0]
        s, li = ss[i], ls[i + 1]
        dW = np.zeros_like(W)
        if Jbar is not None:
            Mbar = Jbar * s[:, None, :]               # Jt_i = Mt_i * s_i
            sbar = np.sum(Jbar * Mts[i], axis=1)
            lbar = lbar - 2.0 * li * sbar             # s_i = 1 - l_i^2
            if i == 0:                                # Mt_1 = W_1^T
                dW += Mbar.sum(0).T
                Jbar = None
            else:                                     # Mt_i = Jt_{i-1} W_i^T
                Mb2 = Mbar.reshape(B * d, h)
                dW += Mb2.T @ Jts[i - 1].reshape(B * d, -1)
                Jbar = (Mb2 @ W).reshape(B, d, -1)
        abar = lbar * s                               # l_i = tanh(a_i)
        dW += abar.T @ ls[i]
        db = abar.sum(0)
        lbar = abar @ W
        grads[i] = (dW, db)
    if weight_decay > 0:
        grads = [(dW + weight_decay * W, db) for (dW, db), (W, _) in zip(grads, params)]
    return cost, pred_cost, jac_cost, grads


# =============================================================================================
# data handling
# =============================================================================================
@dataclass
class _Data:
    Z: np.ndarray          # (N, n+m) inputs [x_t; u_t]
    Y: np.ndarray          # (N, n) targets x_{t+1}
    nxt: np.ndarray        # (N,) row index of the next sample of the same trajectory, -1 if none
    n_traj: int


def _as_trajectories(x, u, n_x=None, n_u=None, what="x"):
    """Normalize (x, u) given as one (T, n) array or a list of them into lists of 2-D float arrays."""
    if x is None:
        raise DataError(f"{what}: no trajectories given")
    xs = list(x) if isinstance(x, (list, tuple)) else [x]
    if u is None:
        us = [np.zeros((np.asarray(xi).shape[0], 0)) for xi in xs]
    else:
        us = list(u) if isinstance(u, (list, tuple)) else [u]
    if len(us) != len(xs):
        raise DataError(f"{what}: {len(xs)} state trajectories but {len(us)} input trajectories")
    X, U = [], []
    for k, (xi, ui) in enumerate(zip(xs, us)):
        xi = np.asarray(xi, float)
        ui = np.asarray(ui, float)
        if xi.ndim == 1:
            xi = xi[:, None]
        if ui.ndim == 1:
            ui = ui[:, None]
        if xi.ndim != 2 or ui.ndim != 2:
            raise DataError(f"{what}[{k}]: states and inputs must be (T, n) and (T, m) arrays")
        if xi.shape[0] < 2:
            raise DataError(f"{what}[{k}]: trajectory has {xi.shape[0]} samples; at least 2 are needed")
        if ui.shape[0] not in (xi.shape[0], xi.shape[0] - 1) and not (ui.shape[1] == 0 and u is None):
            raise DataError(f"{what}[{k}]: {xi.shape[0]} state samples but {ui.shape[0]} input samples "
                            f"(expected {xi.shape[0]} or {xi.shape[0] - 1})")
        if n_x is not None and xi.shape[1] != n_x:
            raise DataError(f"{what}[{k}]: state has {xi.shape[1]} columns, expected {n_x}")
        if n_u is not None and ui.shape[1] != n_u:
            raise DataError(f"{what}[{k}]: input has {ui.shape[1]} columns, expected {n_u}")
        n_x, n_u = xi.shape[1], ui.shape[1]
        for name, a in (("state", xi), ("input", ui)):
            bad = ~np.isfinite(a)
            if bad.any():
                r, c = np.argwhere(bad)[0]
                raise DataError(f"{what}[{k}]: non-finite {name} value at sample {r}, column {c} "
                                f"({int(bad.sum())} in all)")
        X.append(xi)
        U.append(ui)
    return X, U


def _stack(X, U):
    Zs, Ys, nxt = [], [], []
    off = 0
    for xi, ui in zip(X, U):
        T = xi.shape[0] - 1
        Zs.append(np.hstack([xi[:-1], ui[:T]]))
        Ys.append(xi[1:])
        nx = np.arange(off + 1, off + T + 1)
        nx[-1] = -1
        nxt.append(nx)
        off += T
    return _Data(np.vstack(Zs), np.vstack(Ys), np.concatenate(nxt), len(X))


def _batch(data, idx):
    """Rows for a mini-batch: the samples ``idx`` (prediction error) plus the successors needed for the
    Jacobian pairs (t, t+1) with t in idx.  Returns Z, Y, pred_w, pairs (local row indices)."""
    nx = data.nxt[idx]
    has = nx >= 0
    rows = np.unique(np.concatenate([idx, nx[has]]))
    pos = np.full(data.Z.shape[0], -1)
    pos[rows] = np.arange(rows.size)
    pred_w = np.zeros(rows.size)
    pred_w[pos[idx]] = 1.0 / idx.size
    pairs = np.stack([pos[idx[has]], pos[nx[has]]], axis=1) if has.any() else np.zeros((0, 2), int)
    return data.Z[rows], data.Y[rows], pred_w, pairs


class Adam:
    """Adam optimizer state [Kingma and Ba, 2014] for a parameter list [(W, b), ...]."""

    def __init__(self, params, lr=1e-3, b1=0.9, b2=0.999, eps=1e-8):
        self.lr, self.b1, self.b2, self.eps = lr, b1, b2, eps
        self.m = [(np.zeros_like(W), np.zeros_like(b)) for W, b in params]
        self.v = [(np.zeros_like(W), np.zeros_like(b)) for W, b in params]
        self.step = 0

    def update(self, params, grads):
        self.step += 1
        b1, b2, lr, eps = self.b1, self.b2, self.lr, self.eps
        c1, c2 = 1 - b1 ** self.step, 1 - b2 ** self.step
        new = []
        for k, ((W, b), (gW, gb)) in enumerate(zip(params, grads)):
            mW, mb = self.m[k]
            vW, vb = self.v[k]
            mW = b1 * mW + (1 - b1) * gW
            mb = b1 * mb + (1 - b1) * gb
            vW = b2 * vW + (1 - b2) * gW * gW
            vb = b2 * vb + (1 - b2) * gb * gb
            self.m[k], self.v[k] = (mW, mb), (vW, vb)
            new.append((W - lr * (mW / c1) / (np.sqrt(vW / c2) + eps),
                        b - lr * (mb / c1) / (np.sqrt(vb / c2) + eps)))
        return new


def train_epoch(params, data, order, batch_size, adam, jacprop=0.0, weight_decay=0.0):
    """One pass over the training samples in ``order``: a mini-batch gradient step (exact gradient of the
    cost of :func:`loss_and_grad`) and Adam update per batch of ``batch_size`` samples.

    Returns (params, (cost, prediction cost, Jacprop cost) averaged over the epoch, bad) where ``bad`` is
    True when a non-finite cost or gradient stopped the epoch (``params`` are then those before that step)."""
    Ns = order.size
    tot = totp = totj = 0.0
    for s0 in range(0, Ns, batch_size):
        idx = np.sort(order[s0:s0 + batch_size])
        Zb, Yb, pw, pairs = _batch(data, idx)
        cost, pc, jc, grads = loss_and_grad(params, Zb, Yb, pw, pairs, jacprop, weight_decay)
        if not np.isfinite(cost) or not all(np.all(np.isfinite(g)) for gw in grads for g in gw):
            return params, (tot, totp, totj), True
        frac = idx.size / Ns
        tot, totp, totj = tot + cost * frac, totp + pc * frac, totj + jc * frac
        params = adam.update(params, grads)
    return params, (tot, totp, totj), False


# =============================================================================================
# the estimator
# =============================================================================================
class NeuralDynamicsModel:
    """Discrete-time neural dynamics model x+ = f^(x, u) trained by Adam (thesis Ch. 8).

    Parameters
    ----------
    hidden : sizes of the tanh hidden layers, e.g. (20,) for the linear task, (30, 30, 30) for the
        pendulum on a cart (Sec. 8.6).
    form : ``"f"`` (x+ = net), ``"g"`` (x+ = net + x, Eq. (8.8)) or ``"nominal"`` (x+ = net + A0 x + B0 u,
        Sec. 8.4; give ``A0``, ``B0``).
    jacprop : weight of the tangent-space penalty (8.9) (0 = off).
    weight_decay : L2 penalty on the weight matrices (Sec. 8.4) (0 = off).
    epochs, batch_size, learning_rate : Adam settings (batch_size None = full batch).
    patience : stop when the validation prediction error has not improved for this many epochs
        (None = train all epochs; the best validation parameters are kept either way).
    validation_every : epochs between validation evaluations.
    seed : seeds the initialization and the mini-batch order.
    init_scale : scale of the initial output-layer weights.
    normalize : train on standardized inputs z and targets x+ - N z (mean 0, standard deviation 1 per
        column of the training data); the scaling is folded into the first and last layers after training,
        so :attr:`params_` act on original units.  The Jacprop penalty then acts on the Jacobian in the
        standardized coordinates, diag(1/s_t) (J - N) diag(s_z).

    Attributes after :meth:`fit`: ``params_`` (list of (W, b)), ``history_`` (dict of per-epoch training
    cost, and validation error at the evaluated epochs), ``best_epoch_``, ``diverged_`` (message or None).
    """

    def __init__(self, hidden=(30, 30, 30), form="g", jacprop=0.0, weight_decay=0.0, epochs=500,
                 batch_size=None, learning_rate=1e-3, patience=None, validation_every=10, seed=0,
                 init_scale=0.1, A0=None, B0=None, normalize=True, progress_bar=True):
        if form not in FORMS:
            raise DataError(f"form must be one of {FORMS}, got {form!r}")
        hidden = tuple(int(h) for h in hidden)
        if any(h < 1 for h in hidden):
            raise DataError(f"hidden: layer sizes must be positive, got {hidden}")
        for name, v in (("jacprop", jacprop), ("weight_decay", weight_decay)):
            if not (np.isfinite(v) and v >= 0):
                raise DataError(f"{name} must be a finite number >= 0, got {v}")
        if not (np.isfinite(learning_rate) and learning_rate > 0):
            raise DataError(f"learning_rate must be > 0, got {learning_rate}")
        if int(epochs) < 1:
            raise DataError(f"epochs must be >= 1, got {epochs}")
        if form == "nominal" and A0 is None:
            raise DataError("form='nominal' needs the nominal model A0 (and B0 when there are inputs)")
        self.hidden = hidden
        self.form = form
        self.jacprop = float(jacprop)
        self.weight_decay = float(weight_decay)
        self.epochs = int(epochs)
        self.batch_size = batch_size
        self.learning_rate = float(learning_rate)
        self.patience = patience
        self.validation_every = max(1, int(validation_every))
        self.seed = seed
        self.init_scale = float(init_scale)
        self.A0 = None if A0 is None else np.atleast_2d(np.asarray(A0, float))
        self.B0 = None if B0 is None else np.asarray(B0, float)
        self.normalize = bool(normalize)
        self.progress_bar = progress_bar
        self.params_ = None

    # ---------------------------------------------------------------- structure
    def _nominal(self, n, m):
        if self.form == "f":
            return None
        if self.form == "g":
            return np.hstack([np.eye(n), np.zeros((n, m))])
        A0 = self.A0
        B0 = np.zeros((n, m)) if self.B0 is None else np.asarray(self.B0, float).reshape(n, m)
        if A0.shape != (n, n):
            raise DataError(f"A0 has shape {A0.shape}, the data have {n} states")
        if not (np.all(np.isfinite(A0)) and np.all(np.isfinite(B0))):
            raise DataError("A0/B0 contain non-finite values")
        return np.hstack([A0, B0])

    @property
    def n_states(self):
        self._check_fitted()
        return self.n_x_

    @property
    def n_inputs(self):
        self._check_fitted()
        return self.n_u_

    def _check_fitted(self):
        if self.params_ is None:
            raise DataError("model is not fitted; call fit() or set_params() first")

    def set_params(self, params, n_states, n_inputs):
        """Use given network weights [(W, b), ...] (e.g. from another trainer) for an n_states/n_inputs model."""
        params = [(np.array(W, float), np.array(b, float)) for W, b in params]
        sizes = [n_states + n_inputs] + list(self.hidden) + [n_states]
        for i, (W, b) in enumerate(params):
            if i >= len(sizes) - 1 or W.shape != (sizes[i + 1], sizes[i]) or b.shape != (sizes[i + 1],):
                raise DataError(f"params layer {i}: shape {W.shape}/{b.shape} does not fit layer sizes {sizes}")
        if len(params) != len(sizes) - 1:
            raise DataError(f"params: {len(params)} layers given, {len(sizes) - 1} expected")
        self.params_ = params
        self.n_x_, self.n_u_ = int(n_states), int(n_inputs)
        self.N_ = self._nominal(self.n_x_, self.n_u_)
        return self

    # ---------------------------------------------------------------- training
    def fit(self, x, u=None, x_val=None, u_val=None):
        """Train on trajectories.  ``x`` (T, n) state trajectory or a list of them, ``u`` (T, m) or (T-1, m)
        inputs or a list (None = autonomous; a last input row after the last state is ignored); sample t's
        target is x_{t+1} of the same trajectory.  ``x_val``/``u_val``:
        validation trajectories for early stopping (the parameters with the lowest validation prediction
        error are kept; without them, those with the lowest training cost)."""
        X, U = _as_trajectories(x, u, what="x")
        n, m = X[0].shape[1], U[0].shape[1]
        data = _stack(X, U)
        val = None
        if x_val is not None:
            Xv, Uv = _as_trajectories(x_val, u_val, n_x=n, n_u=m, what="x_val")
            val = _stack(Xv, Uv)
        self.n_x_, self.n_u_ = n, m
        self.N_ = self._nominal(n, m)
        # train the network on standardized inputs z_s = (z - mu_z) / s_z and targets
        # t_s = (x+ - N z - mu_t) / s_t; the scalings are folded into the first/last layer afterwards
        scal = _Scaling.from_data(data, self.N_, self.normalize)
        data = scal.apply(data, self.N_)
        if val is not None:
            val = scal.apply(val, self.N_)
        rng = np.random.default_rng(self.seed)
        sizes = [n + m] + list(self.hidden) + [n]
        params = init_params(sizes, rng, self.init_scale)
        Ns = data.Z.shape[0]
        bs = Ns if self.batch_size is None else max(1, min(int(self.batch_size), Ns))
        adam = Adam(params, self.learning_rate)
        hist = {"epoch": [], "train_cost": [], "train_pred": [], "train_jac": [], "val_epoch": [], "val_mse": []}
        best = (np.inf, copy.deepcopy(params), 0)
        last_good = copy.deepcopy(params)
        self.diverged_ = None
        since_best = 0
        epochs = progress(range(self.epochs), desc=f"train {self.form}", total=self.epochs) \
            if self.progress_bar else range(self.epochs)
        for ep in epochs:
            params, (tot, totp, totj), bad = train_epoch(params, data, rng.permutation(Ns), bs, adam,
                                                         self.jacprop, self.weight_decay)
            if bad or not all(np.all(np.isfinite(a)) for W, b in params for a in (W, b)):
                self.diverged_ = (f"training diverged (non-finite loss) in epoch {ep + 1}; "
                                  f"returning the last good parameters (epoch {ep})")
                warnings.warn(self.diverged_, RuntimeWarning, stacklevel=2)
                params = last_good
                if best[0] == np.inf:
                    best = (np.inf, copy.deepcopy(last_good), ep)
                break
            last_good = params
            hist["epoch"].append(ep + 1)
            hist["train_cost"].append(tot)
            hist["train_pred"].append(totp)
            hist["train_jac"].append(totj)
            if (ep + 1) % self.validation_every == 0 or ep + 1 == self.epochs:
                if val is not None:
                    score = _mse(params, val, None, scal.s_t)
                    hist["val_epoch"].append(ep + 1)
                    hist["val_mse"].append(score)
                else:
                    score = tot
                if score < best[0]:
                    best = (score, params, ep + 1)
                    since_best = 0
                else:
                    since_best += self.validation_every
                if self.patience is not None and since_best >= self.patience:
                    break
        self.params_ = scal.fold(best[1] if best[0] < np.inf else last_good)
        self.scaling_ = scal
        self.best_epoch_ = int(best[2])
        self.history_ = hist
        return self

    # ---------------------------------------------------------------- use
    def _z(self, x, u):
        self._check_fitted()
        x = np.asarray(x, float)
        single = x.ndim == 1
        X = np.atleast_2d(x)
        if X.shape[1] != self.n_x_:
            raise DataError(f"x has {X.shape[1]} columns, the model has {self.n_x_} states")
        if u is None:
            if self.n_u_:
                raise DataError(f"u missing: the model has {self.n_u_} inputs")
            Uu = np.zeros((X.shape[0], 0))
        else:
            Uu = np.asarray(u, float)
            Uu = Uu.reshape(1, -1) if (single and Uu.ndim <= 1) else (Uu[:, None] if Uu.ndim == 1 else Uu)
            if Uu.shape != (X.shape[0], self.n_u_):
                raise DataError(f"u has shape {Uu.shape}, expected ({X.shape[0]}, {self.n_u_})")
        return np.hstack([X, Uu]), single

    def predict(self, x, u=None):
        """One-step prediction x+ for states ``x`` (n,) or (T, n) and inputs ``u`` (m,) or (T, m)."""
        Z, single = self._z(x, u)
        out = forward(self.params_, Z)
        if self.N_ is not None:
            out = out + Z @ self.N_.T
        return out[0] if single else out

    def jacobian(self, x, u=None):
        """Input-output Jacobian [A B] (8.6) at each point: (n, n+m) or (T, n, n+m)."""
        Z, single = self._z(x, u)
        _, J = forward_jac(self.params_, Z)
        if self.N_ is not None:
            J = J + self.N_
        return J[0] if single else J

    def linearize(self, x, u=None):
        """(A_t, B_t) along a trajectory: arrays (T, n, n), (T, n, m) (or (n, n), (n, m) at one point)."""
        J = self.jacobian(x, u)
        n = self.n_x_
        return J[..., :n], J[..., n:]

    def ltv_prior(self, cov):
        """Dynamics prior (7.15) for ``drake_est.identification.ltv.ltv_smoother(prior=...)``: a callable
        ``prior(t, x_t, u_t) -> ([A B] at (x_t, u_t), cov)`` with ``cov`` (n+m, n+m) the prior covariance of
        each row of [A B] (Sec. 7.5, a learned model as prior)."""
        self._check_fitted()
        cov = np.asarray(cov, float)
        p = self.n_x_ + self.n_u_
        cov = cov * np.eye(p) if cov.ndim == 0 else (np.diag(cov) if cov.ndim == 1 else cov)
        if cov.shape != (p, p) or not np.all(np.isfinite(cov)):
            raise DataError(f"cov must be a finite ({p}, {p}) matrix, a length-{p} vector or a scalar")

        def prior(t, x_t, u_t):
            return self.jacobian(np.asarray(x_t, float), None if self.n_u_ == 0 else np.asarray(u_t, float)), cov
        return prior

    def ltv_prior_mean(self, x, u=None):
        """k_t = [A_t B_t]^T (T, n+m, n) along a trajectory: the prior mean in the layout of
        ``drake_est.identification.ltv.tv_regression_smoother(prior_mean=...)``."""
        J = np.atleast_3d(self.jacobian(np.atleast_2d(x), None if u is None else np.atleast_2d(u)))
        return np.swapaxes(J, 1, 2)

    def simulate(self, x0, u):
        """Free simulation x_{t+1} = f^(x_t, u_t) from x0 over inputs u (T, m); returns (T+1, n)."""
        self._check_fitted()
        U = np.asarray(u, float)
        U = U[:, None] if U.ndim == 1 else U
        x = np.asarray(x0, float).reshape(-1)
        out = [x]
        for t in range(U.shape[0]):
            x = self.predict(x, U[t])
            out.append(x)
        return np.array(out)

    def score(self, x, u=None):
        """Mean squared one-step prediction error (mean over samples of ||x+ - x^+||^2) on trajectories."""
        X, U = _as_trajectories(x, u, n_x=self.n_states, n_u=self.n_inputs, what="x")
        return _mse(self.params_, _stack(X, U), self.N_)

    # ---------------------------------------------------------------- Drake and files
    def to_drake(self):
        """The network part as a Drake ``MultilayerPerceptron`` (tanh hidden layers, identity output) and a
        Context holding the weights.  The full model adds the fixed linear part: x+ = mlp(z) + N z, with
        N = :attr:`nominal_matrix` (0 for form 'f')."""
        from pydrake.systems.primitives import MultilayerPerceptron, PerceptronActivationType as Act
        self._check_fitted()
        sizes = [self.n_x_ + self.n_u_] + list(self.hidden) + [self.n_x_]
        mlp = MultilayerPerceptron(sizes, [Act.kTanh] * len(self.hidden) + [Act.kIdentity])
        ctx = mlp.CreateDefaultContext()
        for i, (W, b) in enumerate(self.params_):
            mlp.SetWeights(ctx, i, W)
            mlp.SetBiases(ctx, i, b)
        return mlp, ctx

    @property
    def nominal_matrix(self):
        """N (n, n+m) with x+ = net(z) + N z."""
        self._check_fitted()
        return np.zeros((self.n_x_, self.n_x_ + self.n_u_)) if self.N_ is None else self.N_.copy()

    @classmethod
    def from_drake(cls, mlp, context, n_states, form="g", A0=None, B0=None):
        """A model from a Drake ``MultilayerPerceptron`` with tanh hidden layers and an identity output."""
        layers = list(mlp.layers())
        hidden = layers[1:-1]
        params = [(np.array(mlp.GetWeights(context, i)), np.array(mlp.GetBiases(context, i)))
                  for i in range(len(layers) - 1)]
        model = cls(hidden=hidden, form=form, A0=A0, B0=B0)
        return model.set_params(params, int(n_states), layers[0] - int(n_states))

    def to_dict(self):
        """JSON-able description (form, sizes, weights, nominal model)."""
        self._check_fitted()
        return {"form": self.form, "hidden": list(self.hidden), "n_states": self.n_x_, "n_inputs": self.n_u_,
                "weights": [W.tolist() for W, _ in self.params_], "biases": [b.tolist() for _, b in self.params_],
                "A0": None if self.A0 is None else self.A0.tolist(),
                "B0": None if self.B0 is None else np.asarray(self.B0).tolist()}

    @classmethod
    def from_dict(cls, d):
        try:
            model = cls(hidden=d["hidden"], form=d["form"], A0=d.get("A0"), B0=d.get("B0"))
            return model.set_params(list(zip(d["weights"], d["biases"])), d["n_states"], d["n_inputs"])
        except KeyError as err:
            raise DataError(f"neural dynamics model file: missing key {err}") from None

    def save(self, path):
        from drake_est.jsonutil import dump_json
        dump_json(self.to_dict(), path)

    @classmethod
    def load(cls, path):
        with open(path) as fh:
            return cls.from_dict(json.load(fh))


def _mse(params, data, N, s_t=None):
    out = forward(params, data.Z)
    if N is not None:
        out = out + data.Z @ N.T
    E = out - data.Y
    if s_t is not None:
        E = E * s_t
    return float(np.mean(np.sum(E * E, axis=1)))


@dataclass
class _Scaling:
    """Affine standardization of network inputs and targets (identity when ``normalize=False``)."""
    mu_z: np.ndarray
    s_z: np.ndarray
    mu_t: np.ndarray
    s_t: np.ndarray

    @classmethod
    def from_data(cls, data, N, normalize):
        T = data.Y if N is None else data.Y - data.Z @ N.T
        d, n = data.Z.shape[1], data.Y.shape[1]
        if not normalize:
            return cls(np.zeros(d), np.ones(d), np.zeros(n), np.ones(n))

        def sd(a):
            s = a.std(axis=0)
            return np.where(s > 1e-12 * max(1.0, float(np.abs(a).max(initial=0.0))), s, 1.0)
        return cls(data.Z.mean(0), sd(data.Z), T.mean(0), sd(T))

    def apply(self, data, N):
        T = data.Y if N is None else data.Y - data.Z @ N.T
        return _Data((data.Z - self.mu_z) / self.s_z, (T - self.mu_t) / self.s_t, data.nxt, data.n_traj)

    def fold(self, params):
        """Network weights in the original units: net(z) = s_t * net_s((z - mu_z) / s_z) + mu_t."""
        params = [(W.copy(), b.copy()) for W, b in params]
        W1, b1 = params[0]
        W1 = W1 / self.s_z
        params[0] = (W1, b1 - W1 @ self.mu_z)
        WL, bL = params[-1]
        params[-1] = (self.s_t[:, None] * WL, self.s_t * bL + self.mu_t)
        return params


# =============================================================================================
# regularization chosen on validation data
# =============================================================================================
def select_regularization(x, u, x_val, u_val, param="jacprop", values=(0.0, 1e-3, 1e-2, 1e-1, 1.0), **kw):
    """Train one model per value of ``param`` (``"jacprop"`` or ``"weight_decay"``) and keep the one with the
    lowest validation prediction error (Sec. 8.6: "regularization parameters ... tuned such that prediction
    error on the test data is minimized").  Returns (best_model, {value: validation mse})."""
    if param not in ("jacprop", "weight_decay"):
        raise DataError(f"param must be 'jacprop' or 'weight_decay', got {param!r}")
    scores, best = {}, None
    for v in values:
        model = NeuralDynamicsModel(**{**kw, param: float(v)}).fit(x, u, x_val, u_val)
        s = model.score(x_val, u_val)
        scores[float(v)] = s
        if best is None or s < best[0]:
            best = (s, model)
    return best[1], scores
