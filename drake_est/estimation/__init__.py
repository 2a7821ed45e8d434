"""drake_est.estimation: state estimation (thesis Ch. 4).

:mod:`drake_est.estimation.kalman` (Kalman filter / RTS smoother on numpy arrays) and
:mod:`drake_est.estimation.kalman_system` (the filter as a Drake ``LeafSystem``)."""
