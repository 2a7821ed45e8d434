"""drake_est: machine learning and system identification for estimation in
physical systems (F. Bagge Carlson, Lund 2018) as Drake systems.

Subpackages
-----------
estimation      state estimators (Kalman filter/smoother, particle filter)
identification  friction, LTV and (later) black-box model identification
spectral        LPV spectral decomposition (Ch. 10)
calibration     F/T-sensor and laser-scanner calibration (Ch. 13)
diagnose        model-discrepancy diagnosis (the headline workflow)
control         iLQR/DDP and model-based RL (Ch. 5, 11; roadmap)
seam            particle-filter seam tracking (Ch. 14; roadmap)
systems         Drake LeafSystem wrappers shared by the above
"""
__version__ = "0.1.0"

from drake_est.errors import DrakeEstError, DataError, IdentifiabilityError  # noqa: F401
