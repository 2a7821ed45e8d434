"""drake_est.estimation"""
