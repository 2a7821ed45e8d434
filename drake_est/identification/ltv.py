"""Identification of linear time-varying (LTV) models, thesis Ch. 7.

Two layers:

* **Time-varying linear regression** ``y_t = Phi_t k_t + e_t`` with ``Phi_t`` (m x p) per time step
  (``tv_regression_*``): the general form of (7.2), also used for e.g. friction
  ``Phi_t = [v_t, sign(v_t)]``.
* **State-space LTV models** ``x_{t+1} = A_t x_t + B_t u_t + v_t`` with
  ``k_t = vec([A_t B_t]^T)`` (Eq. (7.1), ``ltv_*``).  Every row of ``[A B]`` shares the regressor
  ``phi_t = [x_t; u_t]``, so the rows are solved together with one shared (p x p) covariance,
  p = n + m (the Kronecker structure of (7.2)).

Problems (Table 7.1):

===========================  ======================================  ======================================
problem                      regression                              state space
===========================  ======================================  ======================================
(7.3)/(7.5)/(7.13) squared   :func:`tv_regression_smoother`          :func:`ltv_smoother`
(7.6)/(7.9) group lasso      :func:`tv_regression_group_lasso`       :func:`ltv_group_lasso`
(7.8) known # of switches    :func:`tv_regression_segments`          :func:`ltv_segments`
(7.10) two-step refinement   :func:`refine_with_knots`               :func:`ltv_refine_with_knots`
lambda by max. likelihood    :func:`tv_select_lambda_ml`             :func:`ltv_select_lambda_ml`
===========================  ======================================  ======================================

The squared problems are the negative log-likelihood of the parameter random walk (7.2)
(or (7.11) for (7.5)), so the solution is the Kalman-smoother posterior mean, with the
posterior covariance.  ``method="banded"`` (default) computes that posterior from the
block-banded information form by block cyclic reduction (vectorized, O(T) work,
see :mod:`drake_est.identification.ltv_banded`); ``method="rts"`` runs the textbook
Kalman filter + RTS smoother of :mod:`drake_est.estimation.kalman` on the
parameter-state model (a per-step Python loop; identical results up to the
approximately diffuse initial covariance).  The convex nonsmooth problems are solved by a
working-set primal-dual Newton method with a duality-gap certificate (first differences, (7.6))
or by ADMM (:func:`tv_regression_group_lasso`); :func:`tv_regression_qp_reference` /
:func:`tv_regression_group_lasso_reference` write the same problems as Drake
``MathematicalProgram`` s (the reference the tests compare against).
"""
from __future__ import annotations

# The implementation is split by idea; this module re-exports every name (public and private) so that
# ``from drake_est.identification.ltv import X`` and ``ltv.X`` keep working.
from drake_est.identification.ltv_common import (  # noqa: F401
    LtvResult, TVRegressionResult, _Lambda, _apply_D, _apply_DT, _as_regression, _as_state_space, _check_lam,
    _cluster_times, _finite, _gram, _nullspace_basis, _poly, _reg_bands, _to_ltv, change_points,
    check_identifiable,
)
from drake_est.identification.ltv_smoother import (  # noqa: F401
    _LOG2PI, _Raw, _prior_arrays, _smooth_core, _smooth_rts, _tv_smooth, ltv_smoother,
    tv_regression_smoother,
)
from drake_est.identification.ltv_lambda import (  # noqa: F401
    _select, ltv_select_lambda_ml, tv_select_lambda_ml,
)
from drake_est.identification.ltv_lasso import (  # noqa: F401
    GroupLassoResult, _admm, _gl_active_set, _gl_band_pattern, _gl_gap, _gl_reduced_newton, _gl_rel_gap,
    _gl_solve, _group_lasso_cost, _nrm, ltv_group_lasso, tv_regression_group_lasso,
)
from drake_est.identification.ltv_segments import (  # noqa: F401
    SegmentsResult, _SegmentCost, _dp, _refine, _segment_bounds, _segments, ltv_refine_with_knots,
    ltv_segments, refine_with_knots, segments_brute_force, tv_regression_segments,
)
from drake_est.identification.ltv_reference import (  # noqa: F401
    _mp_program, _mp_solve, ltv_group_lasso_reference, ltv_qp_reference, tv_regression_group_lasso_reference,
    tv_regression_qp_reference,
)
from drake_est.identification.ltv_examples import (  # noqa: F401
    drift_system, jump_system, simulate_ltv,
)
from drake_est.identification.ltv_online import (  # noqa: F401
    ltv_filter, ltv_filter_init, ltv_filter_step,
)

import numpy as _np  # noqa: E402

_LOG2PI = _np.log(2.0 * _np.pi)
