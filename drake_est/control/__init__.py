"""Controllers: iLQR/DDP trajectory optimization with control bounds and a KL trust region, and model-based
reinforcement learning with LTV models (thesis Ch. 5 and 11).

* :mod:`drake_est.control.ilqr` — :func:`ilqr`, :func:`ilqr_kl`, models and costs;
* :mod:`drake_est.control.boxqp` — the box-QP of Tassa et al. (2014);
* :mod:`drake_est.control.cartpole` — the cart-pole of Eqs. (8.11)-(8.12) (compiled);
* :mod:`drake_est.control.drake_model` — derivatives of any Drake system by AutoDiffXd;
* :mod:`drake_est.control.mbrl` — Algorithm 7 (rollout, fit LTI/LTV model, KL-constrained iLQR).
"""
from drake_est.control.boxqp import BoxQPResult, boxqp
from drake_est.control.ilqr import (FunctionCost, FunctionModel, IlqrOptions, IlqrResult, KLResult,
                                    LinearGaussianController, LtvModel, Model, QuadraticCost, ilqr, ilqr_kl,
                                    trajectory_kl)

__all__ = ["BoxQPResult", "boxqp", "FunctionCost", "FunctionModel", "IlqrOptions", "IlqrResult", "KLResult",
           "LinearGaussianController", "LtvModel", "Model", "QuadraticCost", "ilqr", "ilqr_kl", "trajectory_kl"]
