"""Basis over the scheduling variable for the LPV spectral method (thesis Sec. 10.2).

:class:`ScheduleBasis` evaluates the *normalized* Gaussian activations
``phi_bar(v)`` of Eq. (10.6) (each row sums to one, so the spectral content of a
frequency is a convex combination of the per-kernel coefficients), built on
:class:`drake_est.bfe.BasisFunctionExpansion`.

``sign_split=True`` is the Coulomb-style variant of Sec. 10.3: half of the
kernels live on positive velocities, half on negative ones, each half normalized
on its own side, so the amplitude function may jump at zero velocity.  Samples with
``v == 0`` exactly are assigned to the positive side.
"""
from __future__ import annotations

import numpy as np

from drake_est.bfe import BasisFunctionExpansion
from drake_est.errors import DataError, IdentifiabilityError


class ScheduleBasis:
    """Normalized Gaussian basis ``phi_bar(v)`` over a scalar scheduling variable.

    Parameters
    ----------
    n_basis : number J of kernels (J = 1 gives the constant basis, i.e. a plain
        least-squares spectrum (10.5)).
    lo, hi : range of the centres.
    sign_split : Coulomb-style split, ``n_basis // 2`` kernels on v >= 0 and the
        rest on v < 0 (``lo < 0 < hi`` required).
    width_factor : kernel standard deviation in units of the centre spacing.
    """

    def __init__(self, n_basis: int = 1, lo: float = 0.0, hi: float = 1.0, sign_split: bool = False,
                 width_factor: float = 1.0):
        n_basis = int(n_basis)
        if n_basis < 1:
            raise DataError(f"number of schedule basis functions must be >= 1, got {n_basis}")
        if sign_split and n_basis < 2:
            raise DataError("sign_split needs at least 2 schedule basis functions (one per velocity sign)")
        self.n_basis = n_basis
        self.lo, self.hi = float(lo), float(hi)
        self.sign_split = bool(sign_split)
        self.width_factor = float(width_factor)
        if n_basis == 1:
            self._pos = self._neg = None
        elif sign_split:
            if not (self.lo < 0.0 < self.hi):
                raise IdentifiabilityError(
                    f"sign_split schedule basis needs both signs of the schedule, range is [{lo:.3g}, {hi:.3g}]")
            n_pos = n_basis - n_basis // 2
            n_neg = n_basis // 2
            self._pos = BasisFunctionExpansion.uniform(0.0, self.hi, n_pos, width_factor=width_factor,
                                                       normalize=True) if n_pos > 1 else None
            self._neg = BasisFunctionExpansion.uniform(self.lo, 0.0, n_neg, width_factor=width_factor,
                                                       normalize=True) if n_neg > 1 else None
            self._n_pos, self._n_neg = n_pos, n_neg
        else:
            self._pos = BasisFunctionExpansion.uniform(self.lo, self.hi, n_basis, width_factor=width_factor,
                                                       normalize=True)

    @classmethod
    def from_data(cls, v, n_basis: int = 10, sign_split: bool = False, width_factor: float = 1.0,
                  quantile: float = 0.0):
        """Centres spanning the data range of ``v`` (trimmed by ``quantile`` on each side).

        Raises :class:`DataError` when ``v`` is constant but more than one kernel is asked for."""
        v = np.asarray(v, dtype=float).ravel()
        if v.size == 0:
            raise DataError("scheduling variable is empty")
        if not np.all(np.isfinite(v)):
            raise DataError(f"scheduling variable contains {int(np.sum(~np.isfinite(v)))} NaN/inf values")
        if quantile > 0:
            lo, hi = np.quantile(v, quantile), np.quantile(v, 1 - quantile)
        else:
            lo, hi = float(v.min()), float(v.max())
        if n_basis > 1 and not hi - lo > 1e-12 * max(1.0, abs(lo), abs(hi)):
            raise DataError(f"scheduling variable is constant ({lo:.6g}); use n_basis=1 (no scheduling) "
                            "or a schedule that varies")
        return cls(n_basis, lo, hi, sign_split=sign_split, width_factor=width_factor)

    def __call__(self, v) -> np.ndarray:
        """Activations (N, J); rows sum to one (to one per side with ``sign_split``)."""
        v = np.asarray(v, dtype=float).ravel()
        N = v.size
        if self.n_basis == 1:
            return np.ones((N, 1))
        if not self.sign_split:
            return self._pos.features(v[:, None])
        out = np.zeros((N, self.n_basis))
        pos = v >= 0
        neg = ~pos
        if self._pos is None:
            out[pos, 0] = 1.0
        else:
            out[pos, :self._n_pos] = self._pos.features(v[pos][:, None])
        if self._neg is None:
            out[neg, self._n_pos] = 1.0
        else:
            out[neg, self._n_pos:] = self._neg.features(v[neg][:, None])
        return out

    features = __call__

    @property
    def centers(self) -> np.ndarray:
        if self.n_basis == 1:
            return np.array([(self.lo + self.hi) / 2])
        if not self.sign_split:
            return self._pos.centers[0]
        cp = self._pos.centers[0] if self._pos is not None else np.array([self.hi / 2])
        cn = self._neg.centers[0] if self._neg is not None else np.array([self.lo / 2])
        return np.r_[cp, cn]

    def __repr__(self):
        return (f"ScheduleBasis(n_basis={self.n_basis}, lo={self.lo:.4g}, hi={self.hi:.4g}, "
                f"sign_split={self.sign_split})")
