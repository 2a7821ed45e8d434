"""Basis-function expansions (thesis Sec. 6.3) and ridge regression (Sec. 6.4).

A :class:`BasisFunctionExpansion` maps inputs ``X`` of shape ``(N, d)`` to a
feature matrix ``Phi`` of shape ``(N, K)`` with kernels of local support placed
on a grid of centres (1-D or a product grid, Eqs. (9.13)-(9.14) and
(9.17)-(9.18)).  Options:

* ``kernel``: ``"gaussian"`` (Eq. (9.13)), ``"triangular"`` (piecewise affine fit)
  or ``"rectangular"`` (piecewise constant fit);
* ``normalize``: normalized expansion (Sec. 6.3 "Normalization"), which keeps
  its trend outside the data instead of falling to zero;
* ``period``: per input dimension, a period for wrapped distances (motor
  position on the circle, Sec. 9.6);
* ``sign_split``: the Coulomb discontinuity of Sec. 9.3 -- the features are
  duplicated, one copy active only for positive velocity, one only for negative.

:func:`ridge_fit` solves the L2-regularized least-squares problem (6.8) by a QR
factorization of the data followed by an SVD of the small augmented system
(never an explicit inverse).  :func:`select_ridge` chooses the penalty by
K-fold cross-validation or by evidence (marginal-likelihood) maximization, and
:func:`select_bfe` chooses the number of kernels and the width as well.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drake_est.errors import DataError, DrakeEstError, IdentifiabilityError

KERNELS = ("gaussian", "triangular", "rectangular")


def _as_2d(X) -> np.ndarray:
    X = np.asarray(X, dtype=float)
    if X.ndim == 1:
        X = X[:, None]
    if X.ndim != 2:
        raise DrakeEstError(f"basis-function input must be (N,) or (N, d), got shape {X.shape}")
    return X


def uniform_centers(lo: float, hi: float, n: int, periodic: bool = False) -> np.ndarray:
    """``n`` evenly spaced centres on [lo, hi] (on [lo, hi) when periodic)."""
    if n < 1:
        raise DrakeEstError(f"number of basis functions must be >= 1, got {n}")
    if periodic:
        return lo + (hi - lo) * np.arange(n) / n
    if n == 1:
        return np.array([(lo + hi) / 2.0])
    return np.linspace(lo, hi, n)


@dataclass
class BasisFunctionExpansion:
    """Kernels on a (product) grid of centres.

    Parameters
    ----------
    centers : list of 1-D arrays, one per input dimension; the product grid is used.
    widths : kernel width per dimension (standard deviation for the Gaussian,
        half-support for triangular/rectangular).  Default: the centre spacing.
    kernel : "gaussian" | "triangular" | "rectangular".
    normalize : divide each row by the sum of its kernel activations.
    period : per-dimension period (None for non-periodic), e.g. 2*pi for motor angle.
    """

    centers: list
    widths: object = None
    kernel: str = "gaussian"
    normalize: bool = False
    period: object = None
    _grid: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        if self.kernel not in KERNELS:
            raise DrakeEstError(f"unknown kernel '{self.kernel}'; choose one of {KERNELS}")
        if isinstance(self.centers, np.ndarray) and self.centers.ndim == 1:
            self.centers = [self.centers]
        self.centers = [np.asarray(c, dtype=float).ravel() for c in self.centers]
        d = len(self.centers)
        per = self.period if isinstance(self.period, (list, tuple, np.ndarray)) else [self.period] * d
        if len(per) != d:
            raise DrakeEstError(f"period has {len(per)} entries for {d} input dimensions")
        self.period = list(per)
        if self.widths is None:
            w = []
            for c, p in zip(self.centers, self.period):
                if len(c) > 1:
                    w.append(float(np.min(np.diff(np.sort(c)))))
                elif p is not None:
                    w.append(float(p))
                else:
                    w.append(1.0)
            self.widths = w
        widths = np.broadcast_to(np.asarray(self.widths, dtype=float), (d,)).copy()
        if np.any(widths <= 0):
            raise DrakeEstError(f"basis-function widths must be positive, got {widths}")
        self.widths = widths
        mesh = np.meshgrid(*self.centers, indexing="ij")
        self._grid = np.stack([m.ravel() for m in mesh], axis=1)

    @property
    def n_inputs(self) -> int:
        return len(self.centers)

    @property
    def n_basis(self) -> int:
        return self._grid.shape[0]

    @property
    def grid(self) -> np.ndarray:
        """Centres as an array (K, d)."""
        return self._grid

    @classmethod
    def uniform(cls, lo, hi, n, width_factor: float = 1.0, kernel="gaussian", normalize=False, period=None):
        """Uniform (product) grid: ``lo``, ``hi``, ``n`` scalars or per-dimension lists.
        The width is ``width_factor`` times the centre spacing."""
        lo, hi, n = np.atleast_1d(lo), np.atleast_1d(hi), np.atleast_1d(n).astype(int)
        d = max(len(lo), len(hi), len(n))
        lo, hi, n = (np.broadcast_to(a, (d,)) for a in (lo, hi, n))
        per = period if isinstance(period, (list, tuple)) else [period] * d
        centers, widths = [], []
        for i in range(d):
            periodic = per[i] is not None
            c = uniform_centers(lo[i], hi[i], n[i], periodic=periodic)
            spacing = (hi[i] - lo[i]) / (n[i] if periodic else max(n[i] - 1, 1))
            centers.append(c)
            widths.append(width_factor * (spacing if spacing > 0 else 1.0))
        return cls(centers=centers, widths=widths, kernel=kernel, normalize=normalize, period=per)

    @classmethod
    def from_data(cls, X, n, width_factor: float = 1.0, kernel="gaussian", normalize=True, period=None,
                  quantile: float = 0.0):
        """Grid spanning the data range of ``X`` (optionally trimmed by ``quantile``).

        Refuses (``DataError``) non-finite inputs and a non-periodic input whose values are all equal while
        more than one kernel is asked for: every kernel would sit at the same place (identical columns)."""
        X = _as_2d(X)
        if X.shape[0] == 0:
            raise DataError("X is empty; from_data needs samples to span")
        if not np.all(np.isfinite(X)):
            raise DataError(f"X contains NaN/inf ({int(np.sum(~np.isfinite(X)))} entries)")
        n_arr = np.broadcast_to(np.atleast_1d(np.asarray(n)), (X.shape[1],))
        if np.any(n_arr < 1):
            raise DataError(f"n must be >= 1 kernel per input, got {n}")
        if quantile > 0:
            lo, hi = np.quantile(X, quantile, axis=0), np.quantile(X, 1 - quantile, axis=0)
        else:
            lo, hi = X.min(axis=0), X.max(axis=0)
        per = period if isinstance(period, (list, tuple)) else [period] * X.shape[1]
        for i in range(X.shape[1]):
            if per[i] is None and n_arr[i] > 1 and not hi[i] > lo[i]:
                raise DataError(f"X column {i}: all values equal {float(lo[i]):.6g} (within quantile {quantile:g}); "
                                f"{int(n_arr[i])} kernels over it would be identical, the data do not span the input")
        lo = np.array([0.0 if p is not None else l for l, p in zip(lo, per)])
        hi = np.array([p if p is not None else h for h, p in zip(hi, per)])
        return cls.uniform(lo, hi, n, width_factor=width_factor, kernel=kernel, normalize=normalize, period=per)

    def _distances(self, X) -> np.ndarray:
        """Scaled distances (N, K, d) divided by the widths."""
        X = _as_2d(X)
        if X.shape[1] != self.n_inputs:
            raise DrakeEstError(f"expansion has {self.n_inputs} input dimensions, data has {X.shape[1]}")
        diff = X[:, None, :] - self._grid[None, :, :]
        for i, p in enumerate(self.period):
            if p is not None:
                diff[..., i] = (diff[..., i] + p / 2.0) % p - p / 2.0
        return diff / self.widths

    def features(self, X, velocity=None, sign_split: bool = False) -> np.ndarray:
        """Feature matrix Phi (N, K), or (N, 2K) with ``sign_split`` (Sec. 9.3):
        first K columns active for velocity > 0, last K for velocity < 0."""
        X = _as_2d(X)
        N = X.shape[0]
        K = self.n_basis
        out = np.empty((N, K))
        chunk = max(1, int(2e6 // max(K * self.n_inputs, 1)))
        for s in range(0, N, chunk):
            z = self._distances(X[s:s + chunk])
            if self.kernel == "gaussian":
                phi = np.exp(-0.5 * np.sum(z * z, axis=2))
            elif self.kernel == "triangular":
                phi = np.prod(np.clip(1.0 - np.abs(z), 0.0, None), axis=2)
            else:
                phi = np.all(np.abs(z) < 0.5 + 1e-12, axis=2).astype(float)
            if self.normalize:
                tot = phi.sum(axis=1, keepdims=True)
                tot[tot <= 1e-300] = 1.0
                phi = phi / tot
            out[s:s + chunk] = phi
        if sign_split:
            if velocity is None:
                raise DrakeEstError("sign_split features need the velocity")
            v = np.asarray(velocity, dtype=float).ravel()
            if v.shape[0] != N:
                raise DrakeEstError(f"velocity has {v.shape[0]} samples, positions have {N}")
            pos = (v > 0).astype(float)[:, None]
            neg = (v < 0).astype(float)[:, None]
            out = np.hstack([out * pos, out * neg])
        return out

    __call__ = features


# --------------------------------------------------------------------------- ridge


# The ridge solvers live in the one regression core; re-exported here (public names kept).
from drake_est.regression import (RidgeFit, check_excitation, cv_error, log_evidence,  # noqa: E402,F401
                                  penalty_weights as _penalty_matrix, ridge_fit, select_ridge)
from drake_est.regression import kfold_indices as _kfold_indices  # noqa: E402,F401


def select_bfe(X, y, n_grid=(5, 10, 20, 40), width_factors=(0.5, 1.0, 2.0), lams=None, kernel="gaussian",
               normalize=True, period=None, base=None, folds: int = 5, velocity=None, sign_split=False,
               contiguous: bool = True, seed: int = 0):
    """Choose the number of kernels, their width and the ridge penalty by K-fold CV.

    ``base`` (N, b) are extra unpenalized regressors (e.g. the nominal friction
    model's columns) fitted together with the expansion.  Returns a dict with
    the chosen ``bfe``, ``lam``, ``cv_mse`` and the table of all candidates."""
    X = _as_2d(X)
    y = np.asarray(y, dtype=float)
    if lams is None:
        lams = np.logspace(-5, 2, 8)
    table = []
    best = None
    for n in n_grid:
        for wf in width_factors:
            bfe = BasisFunctionExpansion.from_data(X, n, width_factor=wf, kernel=kernel, normalize=normalize,
                                                   period=period)
            Phi = bfe.features(X, velocity=velocity, sign_split=sign_split)
            if base is not None:
                A = np.hstack([np.asarray(base, dtype=float), Phi])
                pen = np.r_[np.zeros(base.shape[1]), np.ones(Phi.shape[1])]
            else:
                A, pen = Phi, None
            if A.shape[0] < 2 * A.shape[1]:
                continue
            for lam in lams:
                err = cv_error(A, y, lam, pen, folds, contiguous, seed)
                table.append({"n": int(n), "width_factor": float(wf), "lam": float(lam), "cv_mse": err})
                if best is None or err < best["cv_mse"]:
                    best = {"bfe": bfe, "lam": float(lam), "cv_mse": err, "n": int(n), "width_factor": float(wf)}
    if best is None:
        raise IdentifiabilityError(
            f"too few samples ({X.shape[0]}) for any candidate basis (smallest needs "
            f"{2 * (min(n_grid) ** X.shape[1])} samples)")
    best["table"] = table
    return best
