"""Moved: the Kalman filter system now lives in :mod:`drake_est.systems.estimators` (ports ``measurement``,
``control``, outputs ``estimate``, ``covariance``, ``log_likelihood``).  This alias keeps
``from drake_est.estimation.kalman_system import KalmanFilterSystem`` working."""
from drake_est.systems.estimators import KalmanFilterSystem  # noqa: F401
