"""drake_est.systems"""
