"""Choice of the regularization weight lambda by maximum likelihood of the parameter random walk
(thesis Fig. 7.4).

Split out of :mod:`drake_est.identification.ltv`, which re-exports every name."""
from __future__ import annotations

import numpy as np

from drake_est.errors import DataError, IdentifiabilityError
from drake_est.identification.ltv_common import _as_regression, _as_state_space, _poly, check_identifiable
from drake_est.identification.ltv_smoother import _tv_smooth


# lambda by maximum likelihood (Fig. 7.4)
# ---------------------------------------------------------------------------------------------
def _select(Phi, Y, lams, order, P, Lambda, sigma_e, refine):
    from scipy.optimize import minimize_scalar

    lams = np.asarray(lams if lams is not None else np.logspace(-2, 4, 25), dtype=float)
    if lams.ndim != 1 or len(lams) == 0 or not np.all(np.isfinite(lams)) or np.any(lams <= 0):
        raise DataError("lams: candidate lambdas must be a non-empty 1-D array of finite numbers > 0")

    def ll(lam):
        return _tv_smooth(Phi, Y, lam, order, P, Lambda, None, None, sigma_e, "banded", False, None,
                          want_cov=False).loglik

    T, m, p = Phi.shape
    r = Y.shape[2]
    d = len(_poly(order, P)) - 1
    if sigma_e is None and T * m * r - d * p * r < 1:
        raise IdentifiabilityError(
            f"too few samples to choose lambda by maximum likelihood: {T} time steps leave no degree of freedom "
            f"for the noise variance after the {d * p * r} diffuse initial parameters; give more data or choose "
            "lambda yourself")
    check_identifiable(Phi, _poly(order, P))
    with np.errstate(invalid="ignore", divide="ignore"):
        lls = np.array([ll(l) for l in lams])
    if not np.all(np.isfinite(lls)):
        raise IdentifiabilityError(
            f"the log-likelihood of lambda is undefined for these data ({len(Y)} samples, "
            f"{int(np.sum(~np.isfinite(lls)))} of {len(lls)} candidates not finite): too few samples for the "
            "number of parameters; give more data or choose lambda yourself")
    i = int(np.argmax(lls))
    best = float(lams[i])
    if refine and 0 < i < len(lams) - 1:
        r = minimize_scalar(lambda s: -ll(np.exp(s)), bounds=(np.log(lams[i - 1]), np.log(lams[i + 1])),
                            method="bounded", options={"xatol": 1e-3})
        if -r.fun >= lls[i]:
            best = float(np.exp(r.x))
    return best, lams, lls


def tv_select_lambda_ml(Phi, y, lams=None, order=1, P=None, Lambda=None, sigma_e=None, refine=True):
    """Maximum-likelihood lambda for :func:`tv_regression_smoother` (Fig. 7.4).

    Evaluates the diffuse log-likelihood of the random-walk model on the grid ``lams`` (default
    logspace(-2, 4, 25)) and refines the best point by a bounded 1-D search in log(lambda).
    Returns (lam_best, lams, logliks)."""
    Phi, Y = _as_regression(Phi, y)
    return _select(Phi, Y, lams, order, P, Lambda, sigma_e, refine)


def ltv_select_lambda_ml(x, u, lams=None, order=1, P=None, Lambda=None, sigma_e=None, y=None, refine=True):
    """Maximum-likelihood lambda for :func:`ltv_smoother` (Fig. 7.4); returns (lam, lams, logliks)."""
    phi, Yn, n, m, names = _as_state_space(x, u, y)
    return _select(phi[:, None, :], Yn[:, None, :], lams, order, P, Lambda, sigma_e, refine)
