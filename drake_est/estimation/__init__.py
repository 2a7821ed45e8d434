"""drake_est.estimation: state estimation (thesis Ch. 4).

:mod:`drake_est.estimation.kalman` (Kalman filter / RTS smoother on numpy arrays) and
:mod:`drake_est.estimation.kalman_system` (the filter as a Drake ``LeafSystem``)."""

# particle filters (Sec. 4.2), FFBSi smoothing and parameter estimation
from drake_est.estimation.pf import GaussianParticleFilter, ParticleFilter, ParticleSmoothResult  # noqa: E402,F401
from drake_est.estimation.params import MLResult, PMMHResult, loglik_function, maximize_loglik, pmmh  # noqa: E402,F401
