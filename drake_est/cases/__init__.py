"""Case studies on real measured data (EMPS, KUKA KR300, ODrive cogging): plain functions that load
a data set with :mod:`drake_est.datasets`, fit on one recording, validate on another and return the
numbers (and optionally write figures).  The ``real-*`` reproductions call them."""
