"""drake_est.spectral"""
