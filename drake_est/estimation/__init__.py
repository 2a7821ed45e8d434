"""drake_est.estimation: state estimation (thesis Ch. 4).

:mod:`~drake_est.estimation.kalman` (Kalman filter / RTS smoother), :mod:`~drake_est.estimation.ekf`,
:mod:`~drake_est.estimation.ukf`, all on the :mod:`~drake_est.estimation.protocol`; their Drake
``LeafSystem`` wrappers live in :mod:`drake_est.systems.estimators`."""

# Gaussian filters (Sec. 4.3): Kalman filter / RTS smoother, EKF, UKF
from drake_est.estimation.protocol import Filter, FilterResult, check_inputs  # noqa: E402,F401
from drake_est.estimation.gaussian import GaussianFilter, SmoothResult  # noqa: E402,F401
from drake_est.estimation.kalman import KalmanFilter, rts_smooth  # noqa: E402,F401
from drake_est.estimation.ekf import ExtendedKalmanFilter  # noqa: E402,F401
from drake_est.estimation.ukf import UnscentedKalmanFilter  # noqa: E402,F401

# particle filters (Sec. 4.2), FFBSi smoothing and parameter estimation
from drake_est.estimation.pf import GaussianParticleFilter, ParticleFilter, ParticleSmoothResult  # noqa: E402,F401
from drake_est.estimation.params import MLResult, PMMHResult, loglik_function, maximize_loglik, pmmh  # noqa: E402,F401
