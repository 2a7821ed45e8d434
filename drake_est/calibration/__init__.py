"""drake_est.calibration"""
