"""drake_est.identification"""
