"""drake_est.diagnose"""
